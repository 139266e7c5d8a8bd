#include "yaml_reader.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <regex>
#include <sstream>

namespace mvis::rig_io {

namespace {
constexpr double kRotationTolerance = 1e-6;  // max |R^T R - I| taken as printing precision
constexpr double kRotationRepair = 1e-3;     // max |R^T R - I| repaired with a warning

std::string formatG(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3g", value);
  return buffer;
}
}  // namespace

YAML::Node parseYamlText(const std::string& text, const std::string& path) {
  // OpenVINS writes OpenCV's "%YAML:1.0" header, which is not a YAML directive.
  std::string cleaned = text;
  if (cleaned.rfind("%YAML:", 0) == 0) cleaned.erase(0, cleaned.find('\n'));
  try {
    YAML::Node root = YAML::Load(cleaned);
    if (!root.IsMap()) throw ConfigError(path + ": expected a mapping of sensors at the top level");
    return root;
  } catch (const YAML::Exception& e) {
    std::ostringstream out;
    out << path << ": line " << e.mark.line + 1 << ", column " << e.mark.column + 1 << ": "
        << e.msg;
    throw ConfigError(out.str());
  }
}

EntryReader::EntryReader(YAML::Node node, std::string path, std::string sensor,
                         std::vector<std::string>* warnings)
    : node_(std::move(node)),
      path_(std::move(path)),
      sensor_(std::move(sensor)),
      warnings_(warnings) {
  if (!node_.IsMap()) {
    throw ConfigError(path_ + (sensor_.empty() ? "" : ": " + sensor_) + ": expected a mapping");
  }
}

std::string EntryReader::prefix(const std::string& key) const {
  return path_ + ": " + (sensor_.empty() ? "" : sensor_ + ": ") + key + ": ";
}

void EntryReader::fail(const std::string& key, const std::string& problem) const {
  throw ConfigError(prefix(key) + problem);
}

void EntryReader::warn(const std::string& key, const std::string& what) const {
  if (warnings_ != nullptr) warnings_->push_back(prefix(key) + what);
}

bool EntryReader::has(const std::string& key) const { return static_cast<bool>(node_[key]); }

double EntryReader::toNumber(const YAML::Node& node, const std::string& key) const {
  double value = 0.0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, value)) {
    fail(key, "expected a number");
  }
  if (!std::isfinite(value)) fail(key, "is not a finite number");
  return value;
}

double EntryReader::number(const std::string& key) const {
  if (!has(key)) fail(key, "missing");
  return toNumber(node_[key], key);
}

double EntryReader::number(const std::string& key, double fallback) const {
  return has(key) ? number(key) : fallback;
}

double EntryReader::positiveNumber(const std::string& key) const {
  const double value = number(key);
  if (value <= 0.0) fail(key, "must be positive, got " + formatNumber(value));
  return value;
}

int EntryReader::positiveInteger(const std::string& key) const {
  const double value = number(key);
  if (value != std::floor(value) || value < 1.0 || value > 1e9) {
    fail(key, "must be a positive whole number, got " + formatNumber(value));
  }
  return static_cast<int>(value);
}

std::string EntryReader::text(const std::string& key) const {
  if (!has(key)) fail(key, "missing");
  const YAML::Node node = node_[key];
  if (!node.IsScalar() || node.Scalar().empty()) fail(key, "expected a non-empty string");
  return node.Scalar();
}

std::string EntryReader::text(const std::string& key, const std::string& fallback) const {
  return has(key) ? text(key) : fallback;
}

Eigen::VectorXd EntryReader::vector(const std::string& key, int size) const {
  if (!has(key)) fail(key, "missing");
  const YAML::Node node = node_[key];
  if (!node.IsSequence() || static_cast<int>(node.size()) != size) {
    fail(key, "expected a list of " + std::to_string(size) + " numbers");
  }
  Eigen::VectorXd v(size);
  for (int i = 0; i < size; ++i) v[i] = toNumber(node[i], key);
  return v;
}

Eigen::MatrixXd EntryReader::matrix(const std::string& key, int rows, int cols) const {
  if (!has(key)) fail(key, "missing");
  const YAML::Node node = node_[key];
  const std::string shape =
      "expected " + std::to_string(rows) + " rows of " + std::to_string(cols) + " numbers";
  if (!node.IsSequence() || static_cast<int>(node.size()) != rows) fail(key, shape);
  Eigen::MatrixXd M(rows, cols);
  for (int r = 0; r < rows; ++r) {
    const YAML::Node row = node[r];
    if (!row.IsSequence() || static_cast<int>(row.size()) != cols) fail(key, shape);
    for (int c = 0; c < cols; ++c) M(r, c) = toNumber(row[c], key);
  }
  return M;
}

Eigen::Matrix3d EntryReader::checkedRotation(const Eigen::Matrix3d& R, const std::string& key,
                                             const std::string& what) const {
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(error <= kRotationRepair)) {
    fail(key, what + " is not orthonormal (max |R^T R - I| = " + formatG(error) + "; up to " +
                  formatG(kRotationRepair) + " is taken as rounding)");
  }
  if (R.determinant() < 0.0) fail(key, what + " is a reflection (determinant -1)");
  const Eigen::Matrix3d nearest = lie::nearestRotation(R);
  if (error > kRotationTolerance) {
    warn(key, what + " is not orthonormal (max |R^T R - I| = " + formatG(error) +
                  "): using the nearest rotation, which changes its entries by up to " +
                  formatG((nearest - R).cwiseAbs().maxCoeff()));
  }
  return nearest;
}

Eigen::Matrix3d EntryReader::rotation(const std::string& key) const {
  return checkedRotation(matrix(key, 3, 3), key, "matrix");
}

SE3 EntryReader::transform(const std::string& key) const {
  const Eigen::Matrix4d T = matrix(key, 4, 4);
  if (T.row(3) != Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0)) {
    fail(key, "bottom row must be [0, 0, 0, 1]");
  }
  const Eigen::Matrix3d R = checkedRotation(T.topLeftCorner<3, 3>(), key, "rotation part");
  return SE3(R, Eigen::Vector3d(T.topRightCorner<3, 1>()));
}

EntryReader EntryReader::child(const std::string& key) const {
  if (!has(key)) fail(key, "missing");
  if (!node_[key].IsMap()) fail(key, "expected a mapping");
  return EntryReader(node_[key], path_, sensor_.empty() ? key : sensor_ + ": " + key, warnings_);
}

double EntryReader::nonNegativeNumber(const std::string& key) const {
  const double value = number(key);
  if (value < 0.0) fail(key, "must not be negative");
  return value;
}

Eigen::VectorXd EntryReader::nonNegativeVector(const std::string& key, int size) const {
  const Eigen::VectorXd v = vector(key, size);
  if (v.minCoeff() < 0.0) fail(key, "must not be negative");
  return v;
}

Eigen::MatrixXd EntryReader::nonNegativeMatrix(const std::string& key, int rows, int cols) const {
  const Eigen::MatrixXd M = matrix(key, rows, cols);
  if (M.minCoeff() < 0.0) fail(key, "must not be negative");
  return M;
}

void EntryReader::rejectUnknownKeys(const std::set<std::string>& known,
                                    const std::set<std::string>& ignored) const {
  for (const auto& entry : node_) {
    const std::string key = entry.first.as<std::string>();
    if (known.count(key) || ignored.count(key)) continue;
    const std::string suffix = "_std";
    if (key.size() > suffix.size() &&
        key.compare(key.size() - suffix.size(), suffix.size(), suffix) == 0 &&
        known.count(key.substr(0, key.size() - suffix.size()))) {
      continue;
    }
    fail(key, "unknown key (a typo? see doc/conventions.md for the keys of this file)");
  }
}

std::vector<std::string> numberedEntries(const YAML::Node& root, const std::string& stem,
                                         const std::string& path) {
  const std::regex pattern(stem + "([0-9]+)");
  std::map<int, std::string> found;
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    std::smatch match;
    if (!std::regex_match(key, match, pattern) || match[1].str().size() > 6) {
      throw ConfigError(path + ": " + key + ": unexpected top-level key (expected " + stem + "0, " +
                        stem + "1, ...)");
    }
    found[std::stoi(match[1].str())] = key;
  }
  if (found.empty()) throw ConfigError(path + ": no sensors (expected " + stem + "0, ...)");
  std::vector<std::string> names;
  for (const auto& [index, key] : found) {
    const std::string expected = stem + std::to_string(names.size());
    if (index != static_cast<int>(names.size())) {
      throw ConfigError(path + ": " + expected + ": missing (sensors are numbered " + stem + "0, " +
                        stem + "1, ... without gaps)");
    }
    if (key != expected) {
      throw ConfigError(path + ": " + key + ": write it as " + expected + " (no leading zeros)");
    }
    names.push_back(key);
  }
  return names;
}

std::string formatNumber(double value) {
  // YAML 1.1 (PyYAML, and through it Kalibr's and ROS's Python tools) reads a float only with a
  // dot and a signed exponent ("4.0e+02", not "4e+02"), and NaN and infinity as .nan and .inf;
  // yaml-cpp reads these too.
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0.0 ? ".inf" : "-.inf";
  char buffer[40];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof(buffer), "%.*g", precision, value);
    if (std::strtod(buffer, nullptr) == value) break;
  }
  std::string text = buffer;
  // Keep it visibly a floating-point number: a dot in the mantissa ("%g" signs the exponent).
  if (text.find('.') == std::string::npos) {
    const std::size_t e = text.find('e');
    text.insert(e == std::string::npos ? text.size() : e, ".0");
  }
  return text;
}

std::string formatRow(const Eigen::VectorXd& values) {
  std::string out = "[";
  for (int i = 0; i < values.size(); ++i) {
    out += (i ? ", " : "") + formatNumber(values[i]);
  }
  return out + "]";
}

std::string formatMatrix(const Eigen::MatrixXd& M, int indent) {
  std::string out;
  for (int r = 0; r < M.rows(); ++r) {
    out += std::string(indent, ' ') + "- " + formatRow(M.row(r).transpose()) + "\n";
  }
  return out;
}

}  // namespace mvis::rig_io
