// kalibr_imu_chain.yaml: reading with validation, and writing in the same format.
#include <set>
#include <sstream>

#include "mvis/rig/rig_io.h"
#include "yaml_reader.h"

namespace mvis {
namespace {

using rig_io::EntryReader;
using rig_io::formatMatrix;
using rig_io::formatNumber;
using rig_io::formatRow;

const std::set<std::string> kImuKeys = {"T_i_b",
                                        "time_offset",
                                        "rostopic",
                                        "update_rate",
                                        "sensor_type",
                                        "model",
                                        "Tw",
                                        "R_IMUtoGYRO",
                                        "Ta",
                                        "R_IMUtoACC",
                                        "Tg",
                                        "accelerometer_noise_density",
                                        "accelerometer_random_walk",
                                        "gyroscope_noise_density",
                                        "gyroscope_random_walk"};

constexpr double kExactTolerance = 1e-9;  // for "must be identity" / "upper triangular"

void requireUpperTriangular(const EntryReader& entry, const std::string& key,
                            const Eigen::Matrix3d& T) {
  for (int r = 1; r < 3; ++r) {
    for (int c = 0; c < r; ++c) {
      if (std::abs(T(r, c)) > kExactTolerance) {
        entry.fail(key, "must be upper triangular (row " + std::to_string(r) + ", column " +
                            std::to_string(c) + " is " + formatNumber(T(r, c)) + ")");
      }
    }
  }
  if (T.diagonal().minCoeff() <= 0.0) entry.fail(key, "diagonal must be positive");
}

ImuIntrinsics readIntrinsics(const EntryReader& entry, ImuModel model) {
  ImuIntrinsics in;
  if (entry.has("Tw")) in.Tw = entry.matrix("Tw", 3, 3);
  if (entry.has("Ta")) in.Ta = entry.matrix("Ta", 3, 3);
  if (entry.has("Tg")) in.Tg = entry.matrix("Tg", 3, 3);
  if (entry.has("R_IMUtoGYRO")) in.R_IMUtoGYRO = entry.rotation("R_IMUtoGYRO");
  if (entry.has("R_IMUtoACC")) in.R_IMUtoACC = entry.rotation("R_IMUtoACC");
  requireUpperTriangular(entry, "Tw", in.Tw);
  requireUpperTriangular(entry, "Ta", in.Ta);
  if (!in.R_IMUtoGYRO.isIdentity(kExactTolerance)) {
    entry.fail("R_IMUtoGYRO", "must be identity (mvis puts the inertial frame on the gyroscope)");
  }
  if (model == ImuModel::kCalibrated) {
    const ImuIntrinsics identity;
    const auto check = [&](const char* key, const Eigen::Matrix3d& value,
                           const Eigen::Matrix3d& expected) {
      if (!(value - expected).isZero(kExactTolerance)) {
        entry.fail(key,
                   "model is calibrated, which fixes it at its default; set model: rpng "
                   "to use it");
      }
    };
    check("Tw", in.Tw, identity.Tw);
    check("Ta", in.Ta, identity.Ta);
    check("Tg", in.Tg, identity.Tg);
    check("R_IMUtoACC", in.R_IMUtoACC, identity.R_IMUtoACC);
  }
  return in;
}

std::optional<InertialCalibrationStd> readStd(const EntryReader& entry) {
  const std::vector<std::string> keys = {"T_i_b_std", "time_offset_std", "Tw_std",
                                         "Ta_std",    "Tg_std",          "R_IMUtoACC_std"};
  bool any = false;
  for (const auto& key : keys) any = any || entry.has(key);
  if (!any) return std::nullopt;
  InertialCalibrationStd std;
  if (entry.has("T_i_b_std")) {
    const EntryReader t = entry.child("T_i_b_std");
    std.rotation = t.nonNegativeVector("rotation", 3);
    std.translation = t.nonNegativeVector("translation", 3);
  }
  if (entry.has("time_offset_std")) {
    std.time_offset = entry.nonNegativeNumber("time_offset_std");
  }
  if (entry.has("Tw_std")) std.Tw = entry.nonNegativeMatrix("Tw_std", 3, 3);
  if (entry.has("Ta_std")) std.Ta = entry.nonNegativeMatrix("Ta_std", 3, 3);
  if (entry.has("Tg_std")) std.Tg = entry.nonNegativeMatrix("Tg_std", 3, 3);
  if (entry.has("R_IMUtoACC_std")) {
    std.R_IMUtoACC = entry.nonNegativeVector("R_IMUtoACC_std", 3);
  }
  return std;
}

InertialSensor readInertial(const EntryReader& entry, const std::string& name, bool is_base) {
  entry.rejectUnknownKeys(kImuKeys);
  InertialSensor s;
  s.name = name;
  const std::string type = entry.text("sensor_type", "imu");
  if (type == "imu") {
    s.type = InertialType::kImu;
  } else if (type == "gyroscope") {
    s.type = InertialType::kGyroscope;
  } else {
    entry.fail("sensor_type", "unknown sensor type '" + type + "' (expected imu or gyroscope)");
  }
  if (is_base && s.type != InertialType::kImu) {
    entry.fail("sensor_type", "imu0 is the base IMU and must be an imu, not a gyroscope");
  }

  if (entry.has("T_i_b") || !is_base) s.T_i_b = entry.transform("T_i_b");
  s.time_offset = entry.number("time_offset", 0.0);
  if (is_base && !s.T_i_b.matrix().isIdentity(kExactTolerance)) {
    entry.fail("T_i_b", "must be identity for imu0, the base IMU");
  }
  if (is_base && s.time_offset != 0.0) {
    entry.fail("time_offset", "must be 0 for imu0, the base IMU (it defines the base clock)");
  }
  s.rostopic = entry.text("rostopic");
  s.update_rate = entry.positiveNumber("update_rate");

  s.noise.gyroscope_noise_density = entry.positiveNumber("gyroscope_noise_density");
  s.noise.gyroscope_random_walk = entry.positiveNumber("gyroscope_random_walk");
  // A gyroscope has no accelerometer; its accelerometer keys are optional and unused.
  if (s.type == InertialType::kImu || entry.has("accelerometer_noise_density")) {
    s.noise.accelerometer_noise_density = entry.positiveNumber("accelerometer_noise_density");
  }
  if (s.type == InertialType::kImu || entry.has("accelerometer_random_walk")) {
    s.noise.accelerometer_random_walk = entry.positiveNumber("accelerometer_random_walk");
  }

  const std::string model = entry.text("model", "calibrated");
  if (model == "calibrated") {
    s.model = ImuModel::kCalibrated;
  } else if (model == "rpng") {
    s.model = ImuModel::kRpng;
  } else {
    entry.fail("model", "unknown model '" + model + "' (expected calibrated or rpng)");
  }
  s.intrinsics = readIntrinsics(entry, s.model);
  s.std = readStd(entry);
  return s;
}

void writeStd(std::ostream& out, const InertialCalibrationStd& std) {
  out << "  T_i_b_std:\n    rotation: " << formatRow(std.rotation)
      << "\n    translation: " << formatRow(std.translation) << "\n";
  out << "  time_offset_std: " << formatNumber(std.time_offset) << "\n";
  out << "  Tw_std:\n" << formatMatrix(std.Tw, 4);
  out << "  Ta_std:\n" << formatMatrix(std.Ta, 4);
  out << "  Tg_std:\n" << formatMatrix(std.Tg, 4);
  out << "  R_IMUtoACC_std: " << formatRow(std.R_IMUtoACC) << "\n";
}

}  // namespace

StatusOr<std::vector<InertialSensor>> parseImuChain(const std::string& yaml_text,
                                                    const std::string& path) {
  return rig_io::guardedParse(path, [&] {
    const YAML::Node root = rig_io::parseYamlText(yaml_text, path);
    std::vector<InertialSensor> sensors;
    for (const auto& name : rig_io::numberedEntries(root, "imu", path)) {
      sensors.push_back(readInertial(EntryReader(root[name], path, name), name, sensors.empty()));
    }
    rig_io::requireUniqueTopics(sensors, path);
    return sensors;
  });
}

std::string imuChainToYaml(const Rig& rig) {
  std::ostringstream out;
  out << "# Inertial sensors of the rig (imu0 = base IMU). Format: doc/conventions.md\n";
  for (const auto& s : rig.inertial) {
    out << s.name << ":\n";
    out << "  sensor_type: " << toString(s.type) << "\n";
    out << "  T_i_b:\n" << formatMatrix(s.T_i_b.matrix(), 4);
    out << "  time_offset: " << formatNumber(s.time_offset) << "\n";
    out << "  rostopic: " << s.rostopic << "\n";
    out << "  update_rate: " << formatNumber(s.update_rate) << "\n";
    out << "  gyroscope_noise_density: " << formatNumber(s.noise.gyroscope_noise_density) << "\n";
    out << "  gyroscope_random_walk: " << formatNumber(s.noise.gyroscope_random_walk) << "\n";
    if (s.type == InertialType::kImu) {
      out << "  accelerometer_noise_density: " << formatNumber(s.noise.accelerometer_noise_density)
          << "\n";
      out << "  accelerometer_random_walk: " << formatNumber(s.noise.accelerometer_random_walk)
          << "\n";
    }
    out << "  model: " << toString(s.model) << "\n";
    out << "  Tw:\n" << formatMatrix(s.intrinsics.Tw, 4);
    out << "  R_IMUtoGYRO:\n" << formatMatrix(s.intrinsics.R_IMUtoGYRO, 4);
    out << "  Ta:\n" << formatMatrix(s.intrinsics.Ta, 4);
    out << "  R_IMUtoACC:\n" << formatMatrix(s.intrinsics.R_IMUtoACC, 4);
    out << "  Tg:\n" << formatMatrix(s.intrinsics.Tg, 4);
    if (s.std) writeStd(out, *s.std);
  }
  return out.str();
}

}  // namespace mvis
