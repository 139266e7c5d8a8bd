// Internal to the rig I/O: typed, checked access to one YAML mapping (one sensor's entry or a
// whole file), failing with "FILE: SENSOR: KEY: problem". Failures travel as ConfigError inside
// the parsers and leave them as a Status; no exception crosses the public interface.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/common/status.h"

namespace mvis::rig_io {

struct ConfigError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Parses YAML text; a syntax error becomes "FILE: line L, column C: what".
YAML::Node parseYamlText(const std::string& text, const std::string& path);

class EntryReader {
 public:
  // `sensor` may be empty for a file-level mapping. Warnings (a value used after a correction)
  // go to `warnings` when given, as "FILE: SENSOR: KEY: what".
  EntryReader(YAML::Node node, std::string path, std::string sensor,
              std::vector<std::string>* warnings = nullptr);

  [[noreturn]] void fail(const std::string& key, const std::string& problem) const;
  void warn(const std::string& key, const std::string& what) const;

  bool has(const std::string& key) const;
  double number(const std::string& key) const;  // finite
  double number(const std::string& key, double fallback) const;
  double positiveNumber(const std::string& key) const;  // > 0
  int positiveInteger(const std::string& key) const;    // > 0
  std::string text(const std::string& key) const;       // a non-empty scalar
  std::string text(const std::string& key, const std::string& fallback) const;
  Eigen::VectorXd vector(const std::string& key, int size) const;
  Eigen::MatrixXd matrix(const std::string& key, int rows, int cols) const;
  // A 3x3 rotation matrix, det +1, returned as the nearest rotation: orthonormal within 1e-6
  // silently (printing precision), within 1e-3 with a warning showing the correction (files
  // with rotations printed to five or six digits); further off it is refused.
  Eigen::Matrix3d rotation(const std::string& key) const;
  // A 4x4 rigid transform: rotation block as above, bottom row [0 0 0 1].
  SE3 transform(const std::string& key) const;
  // The mapping under `key`, reporting as "SENSOR: KEY: SUBKEY".
  EntryReader child(const std::string& key) const;
  double nonNegativeNumber(const std::string& key) const;  // >= 0 (a standard deviation)
  // A list of `size` numbers, each >= 0 (standard deviations).
  Eigen::VectorXd nonNegativeVector(const std::string& key, int size) const;
  Eigen::MatrixXd nonNegativeMatrix(const std::string& key, int rows, int cols) const;
  // Every key must be in `known` or end in "_std" with its stem in `known`, or be in `ignored`.
  void rejectUnknownKeys(const std::set<std::string>& known,
                         const std::set<std::string>& ignored = {}) const;

 private:
  std::string prefix(const std::string& key) const;
  double toNumber(const YAML::Node& node, const std::string& key) const;
  Eigen::Matrix3d checkedRotation(const Eigen::Matrix3d& R, const std::string& key,
                                  const std::string& what) const;

  YAML::Node node_;
  std::string path_;
  std::string sensor_;
  std::vector<std::string>* warnings_;
};

// Sensor keys "imu0", "imu1", ... of a chain file in index order; refuses other top-level keys
// and gaps in the numbering.
std::vector<std::string> numberedEntries(const YAML::Node& root, const std::string& stem,
                                         const std::string& path);

// Runs a parser body, turning its ConfigError or a yaml-cpp exception into a Status.
template <typename Parse>
auto guardedParse(const std::string& path, Parse&& parse) -> StatusOr<decltype(parse())> {
  try {
    return parse();
  } catch (const ConfigError& e) {
    return Status::Error(e.what());
  } catch (const YAML::Exception& e) {
    return Status::Error(path + ": " + e.what());
  }
}

// Throws "FILE: SENSOR: rostopic: 'T' is already used by OTHER" for the first sensor (anything
// with .name and .rostopic) whose topic an earlier one uses.
template <typename Sensor>
void requireUniqueTopics(const std::vector<Sensor>& sensors, const std::string& path) {
  for (std::size_t i = 0; i < sensors.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (sensors[i].rostopic == sensors[j].rostopic) {
        throw ConfigError(path + ": " + sensors[i].name + ": rostopic: '" + sensors[i].rostopic +
                          "' is already used by " + sensors[j].name);
      }
    }
  }
}

// Shortest decimal text that reads back as exactly `value`.
std::string formatNumber(double value);
// "[a, b, c]"
std::string formatRow(const Eigen::VectorXd& values);
// A matrix as a YAML block list of rows, each line indented by `indent` spaces.
std::string formatMatrix(const Eigen::MatrixXd& M, int indent);

}  // namespace mvis::rig_io
