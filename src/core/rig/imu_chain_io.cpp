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

const std::set<std::string> kImuKeys = {
    "T_i_b", "time_offset", "rostopic", "update_rate", "sensor_type", "model", "Tw", "R_IMUtoGYRO",
    "Ta", "R_IMUtoACC", "Tg", "accelerometer_noise_density", "accelerometer_random_walk",
    "gyroscope_noise_density", "gyroscope_random_walk",
    // Kalibr's IMU result files (kalibr_calibrate_imu_camera)
    "gyroscopes", "accelerometers"};

constexpr double kExactTolerance = 1e-9;  // for "must be identity" / "upper triangular"

// Tw or Ta of the rpng (upper triangular) or kalibr (lower triangular) model, with a positive
// diagonal.
void requireTriangular(const EntryReader& entry, const std::string& key, const Eigen::Matrix3d& T,
                       bool upper) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if ((upper ? r <= c : r >= c) || std::abs(T(r, c)) <= kExactTolerance) continue;
      entry.fail(key, std::string("must be ") + (upper ? "upper" : "lower") +
                          " triangular for model " + (upper ? "rpng" : "kalibr") + " (row " +
                          std::to_string(r) + ", column " + std::to_string(c) + " is " +
                          formatNumber(T(r, c)) + ")");
    }
  }
  if (T.diagonal().minCoeff() <= 0.0) entry.fail(key, "diagonal must be positive");
}

// Kalibr's IMU model names (kalibr_calibrate_imu_camera's imu.yaml) onto mvis's.
ImuModel kalibrResultModel(const EntryReader& entry, const std::string& model) {
  if (model == "scale-misalignment") return ImuModel::kKalibr;
  if (model == "scale-misalignment-size-effect") {
    entry.fail("model",
               "Kalibr's scale-misalignment-size-effect is not supported (mvis does not model "
               "the accelerometers' size effect); calibrate with Kalibr's scale-misalignment "
               "model, or use model: calibrated to take the readings as they are");
  }
  entry.fail("model", "unknown model '" + model +
                          "' (expected calibrated, rpng or kalibr, or Kalibr's "
                          "scale-misalignment)");
}

ImuIntrinsics readIntrinsics(const EntryReader& entry, ImuModel model) {
  ImuIntrinsics in;
  if (entry.has("gyroscopes") || entry.has("accelerometers")) {
    // A Kalibr IMU result file: gyroscopes {M: Tw, C_gyro_i: R_IMUtoGYRO, A: Tg},
    // accelerometers {M: Ta} (the mapping OpenVINS documents for its kalibr model).
    for (const char* key : {"Tw", "Ta", "Tg", "R_IMUtoGYRO", "R_IMUtoACC"}) {
      if (entry.has(key)) {
        entry.fail(key,
                   "give the intrinsics either as Kalibr's gyroscopes/accelerometers or as "
                   "Tw, Ta, Tg, R_IMUtoGYRO, R_IMUtoACC, not both");
      }
    }
    if (entry.has("gyroscopes")) {
      const EntryReader g = entry.child("gyroscopes");
      g.rejectUnknownKeys({"M", "A", "C_gyro_i"});
      if (g.has("M")) in.Tw = g.matrix("M", 3, 3);
      if (g.has("A")) in.Tg = g.matrix("A", 3, 3);
      if (g.has("C_gyro_i")) in.R_IMUtoGYRO = g.rotation("C_gyro_i");
    }
    if (entry.has("accelerometers")) {
      const EntryReader a = entry.child("accelerometers");
      a.rejectUnknownKeys({"M"});
      if (a.has("M")) in.Ta = a.matrix("M", 3, 3);
    }
  } else {
    if (entry.has("Tw")) in.Tw = entry.matrix("Tw", 3, 3);
    if (entry.has("Ta")) in.Ta = entry.matrix("Ta", 3, 3);
    if (entry.has("Tg")) in.Tg = entry.matrix("Tg", 3, 3);
    if (entry.has("R_IMUtoGYRO")) in.R_IMUtoGYRO = entry.rotation("R_IMUtoGYRO");
    if (entry.has("R_IMUtoACC")) in.R_IMUtoACC = entry.rotation("R_IMUtoACC");
  }
  const bool kalibr = model == ImuModel::kKalibr;
  requireTriangular(entry, "Tw", in.Tw, !kalibr);
  requireTriangular(entry, "Ta", in.Ta, !kalibr);
  if (model == ImuModel::kRpng && !in.R_IMUtoGYRO.isIdentity(kExactTolerance)) {
    entry.fail("R_IMUtoGYRO",
               "must be identity for model rpng (its inertial frame is the gyroscope's; "
               "model kalibr has R_IMUtoGYRO and an identity R_IMUtoACC instead)");
  }
  if (kalibr && !in.R_IMUtoACC.isIdentity(kExactTolerance)) {
    entry.fail("R_IMUtoACC",
               "must be identity for model kalibr (its inertial frame is the accelerometer's; "
               "model rpng has R_IMUtoACC and an identity R_IMUtoGYRO instead)");
  }
  if (model == ImuModel::kCalibrated) {
    const ImuIntrinsics identity;
    const auto check = [&](const char* key, const Eigen::Matrix3d& value,
                           const Eigen::Matrix3d& expected) {
      if (!(value - expected).isZero(kExactTolerance)) {
        entry.fail(key,
                   "model is calibrated, which fixes it at its default; set model: rpng or "
                   "kalibr to use it");
      }
    };
    check("Tw", in.Tw, identity.Tw);
    check("Ta", in.Ta, identity.Ta);
    check("Tg", in.Tg, identity.Tg);
    check("R_IMUtoGYRO", in.R_IMUtoGYRO, identity.R_IMUtoGYRO);
    check("R_IMUtoACC", in.R_IMUtoACC, identity.R_IMUtoACC);
  }
  return in;
}

std::optional<InertialCalibrationStd> readStd(const EntryReader& entry) {
  const std::vector<std::string> keys = {"T_i_b_std", "time_offset_std", "Tw_std",         "Ta_std",
                                         "Tg_std",    "R_IMUtoACC_std",  "R_IMUtoGYRO_std"};
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
  if (entry.has("R_IMUtoGYRO_std")) {
    std.R_IMUtoGYRO = entry.nonNegativeVector("R_IMUtoGYRO_std", 3);
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
  } else if (model == "kalibr") {
    s.model = ImuModel::kKalibr;
  } else {
    s.model = kalibrResultModel(entry, model);
  }
  s.intrinsics = readIntrinsics(entry, s.model);
  s.std = readStd(entry);
  return s;
}

void writeStd(std::ostream& out, const InertialCalibrationStd& std, ImuModel model) {
  out << "  T_i_b_std:\n    rotation: " << formatRow(std.rotation)
      << "\n    translation: " << formatRow(std.translation) << "\n";
  out << "  time_offset_std: " << formatNumber(std.time_offset) << "\n";
  out << "  Tw_std:\n" << formatMatrix(std.Tw, 4);
  out << "  Ta_std:\n" << formatMatrix(std.Ta, 4);
  out << "  Tg_std:\n" << formatMatrix(std.Tg, 4);
  // The rotation the model estimates: R_IMUtoACC (rpng) or R_IMUtoGYRO (kalibr).
  if (model == ImuModel::kKalibr) {
    out << "  R_IMUtoGYRO_std: " << formatRow(std.R_IMUtoGYRO) << "\n";
  } else {
    out << "  R_IMUtoACC_std: " << formatRow(std.R_IMUtoACC) << "\n";
  }
}

}  // namespace

StatusOr<std::vector<InertialSensor>> parseImuChain(const std::string& yaml_text,
                                                    const std::string& path,
                                                    std::vector<std::string>* warnings) {
  return rig_io::guardedParse(path, [&] {
    const YAML::Node root = rig_io::parseYamlText(yaml_text, path);
    std::vector<InertialSensor> sensors;
    for (const auto& name : rig_io::numberedEntries(root, "imu", path)) {
      sensors.push_back(
          readInertial(EntryReader(root[name], path, name, warnings), name, sensors.empty()));
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
    if (s.std) writeStd(out, *s.std, s.model);
  }
  return out.str();
}

}  // namespace mvis
