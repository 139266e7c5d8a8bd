#include "mvis/sim/simulation_config.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "../rig/yaml_reader.h"

namespace mvis {
namespace {

using rig_io::EntryReader;

constexpr double kDegree = M_PI / 180.0;

double nonNegative(const EntryReader& entry, const std::string& key, double fallback) {
  return entry.has(key) ? entry.nonNegativeNumber(key) : fallback;
}

PerturbationSizes readPerturbation(const EntryReader& entry) {
  entry.rejectUnknownKeys({"camera_rotation_deg", "camera_translation_m", "camera_time_offset_s",
                           "camera_focal_px", "camera_centre_px", "camera_distortion",
                           "aux_rotation_deg", "aux_translation_m", "aux_time_offset_s",
                           "imu_scale_misalignment", "imu_gravity_sensitivity",
                           "imu_acc_rotation_deg"});
  PerturbationSizes p;
  p.camera_rotation_rad =
      nonNegative(entry, "camera_rotation_deg", p.camera_rotation_rad / kDegree) * kDegree;
  p.camera_translation_m = nonNegative(entry, "camera_translation_m", p.camera_translation_m);
  p.camera_time_offset_s = nonNegative(entry, "camera_time_offset_s", p.camera_time_offset_s);
  p.camera_focal_px = nonNegative(entry, "camera_focal_px", p.camera_focal_px);
  p.camera_centre_px = nonNegative(entry, "camera_centre_px", p.camera_centre_px);
  p.camera_distortion = nonNegative(entry, "camera_distortion", p.camera_distortion);
  p.aux_rotation_rad =
      nonNegative(entry, "aux_rotation_deg", p.aux_rotation_rad / kDegree) * kDegree;
  p.aux_translation_m = nonNegative(entry, "aux_translation_m", p.aux_translation_m);
  p.aux_time_offset_s = nonNegative(entry, "aux_time_offset_s", p.aux_time_offset_s);
  p.imu_scale_misalignment = nonNegative(entry, "imu_scale_misalignment", p.imu_scale_misalignment);
  p.imu_gravity_sensitivity =
      nonNegative(entry, "imu_gravity_sensitivity", p.imu_gravity_sensitivity);
  p.imu_acc_rotation_rad =
      nonNegative(entry, "imu_acc_rotation_deg", p.imu_acc_rotation_rad / kDegree) * kDegree;
  return p;
}

}  // namespace

StatusOr<SimulationConfig> parseSimulationConfig(const std::string& yaml_text,
                                                 const std::string& path, std::size_t num_cameras) {
  return rig_io::guardedParse(path, [&] {
    const EntryReader entry(rig_io::parseYamlText(yaml_text, path), path, "");
    entry.rejectUnknownKeys(
        {"duration_s",  "seed",           "start_time_s",     "motion",         "height_m",
         "amplitude",   "camera_rate_hz", "camera_output",    "pixel_noise_px", "image_noise_sigma",
         "supersample", "threads",        "imu_noise",        "board",          "image_blur_px",
         "renderer",    "image_gamma",    "image_vignetting", "perturbation",   "moves"});
    SimulationConfig c;
    if (entry.has("duration_s")) c.duration_s = entry.positiveNumber("duration_s");
    if (entry.has("seed")) {
      const double seed = entry.number("seed");
      if (seed < 0.0 || seed != std::floor(seed) || seed > 9e15) {
        entry.fail("seed", "must be a whole number >= 0");
      }
      c.seed = static_cast<std::uint64_t>(seed);
    }
    if (entry.has("start_time_s")) {
      const double start = entry.positiveNumber("start_time_s");
      // Whole and fractional parts apart, so the nanoseconds survive the double.
      const double whole = std::floor(start);
      c.start_ns = static_cast<TimeNs>(whole) * kNsPerSecond + fromSeconds(start - whole);
    }
    const std::string motion = entry.text("motion", "handheld");
    if (!parseMotionKind(motion, &c.motion.kind)) {
      entry.fail("motion", "unknown motion '" + motion +
                               "' (expected handheld, yaw_only or translation_only)");
    }
    c.motion.height_m =
        entry.has("height_m") ? entry.positiveNumber("height_m") : c.motion.height_m;
    c.motion.amplitude = nonNegative(entry, "amplitude", c.motion.amplitude);
    const Eigen::VectorXd rates = entry.vector("camera_rate_hz", static_cast<int>(num_cameras));
    for (int i = 0; i < rates.size(); ++i) {
      if (!(rates[i] > 0.0)) entry.fail("camera_rate_hz", "every rate must be positive");
      c.camera_rate_hz.push_back(rates[i]);
    }
    const std::string output = entry.text("camera_output", "images");
    if (output == "images") {
      c.camera_output = CameraOutput::kImages;
    } else if (output == "detections") {
      c.camera_output = CameraOutput::kDetections;
    } else {
      entry.fail("camera_output",
                 "unknown camera output '" + output + "' (expected images or detections)");
    }
    c.pixel_noise_px = nonNegative(entry, "pixel_noise_px", c.pixel_noise_px);
    c.image_noise_sigma = nonNegative(entry, "image_noise_sigma", c.image_noise_sigma);
    if (entry.has("supersample")) c.supersample = entry.positiveInteger("supersample");
    const std::string board = entry.text("board", "kalibr");
    if (board == "kalibr") {
      c.board = BoardKind::kKalibrGrid;
    } else if (board == "plain") {
      c.board = BoardKind::kPlain;
    } else {
      entry.fail("board", "unknown board '" + board + "' (expected kalibr or plain)");
    }
    c.image_blur_px = nonNegative(entry, "image_blur_px", c.image_blur_px);
    const std::string renderer = entry.text("renderer", "sampled");
    if (renderer != "sampled" && renderer != "coverage") {
      entry.fail("renderer", "unknown renderer '" + renderer + "' (expected sampled or coverage)");
    }
    c.coverage_renderer = renderer == "coverage";
    if (entry.has("image_gamma")) {
      c.image_gamma = entry.positiveNumber("image_gamma");
      if (!c.coverage_renderer && c.image_gamma != 1.0) {
        entry.fail("image_gamma", "needs renderer: coverage");
      }
    }
    c.image_vignetting = nonNegative(entry, "image_vignetting", c.image_vignetting);
    if (c.image_vignetting >= 1.0) entry.fail("image_vignetting", "must be under 1");
    if (!c.coverage_renderer && c.image_vignetting != 0.0) {
      entry.fail("image_vignetting", "needs renderer: coverage");
    }
    if (entry.has("threads")) c.threads = entry.positiveInteger("threads");
    if (entry.has("imu_noise")) {
      const std::string flag = entry.text("imu_noise");
      if (flag != "true" && flag != "false") entry.fail("imu_noise", "expected true or false");
      c.imu_noise = flag == "true";
    }
    if (entry.has("perturbation")) c.perturbation = readPerturbation(entry.child("perturbation"));
    if (entry.has("moves")) {
      const YAML::Node moves = rig_io::parseYamlText(yaml_text, path)["moves"];
      if (!moves.IsMap()) entry.fail("moves", "expected a mapping of sensor names");
      for (const auto& item : moves) {
        SensorMove m;
        m.sensor = item.first.as<std::string>();
        const EntryReader move(item.second, path, "moves: " + m.sensor);
        move.rejectUnknownKeys({"at_s", "rotation_deg", "translation_m", "time_offset_s"});
        m.at_s = nonNegative(move, "at_s", 0.0);
        if (move.has("rotation_deg")) m.rotation_rad = move.vector("rotation_deg", 3) * kDegree;
        if (move.has("translation_m")) m.translation_m = move.vector("translation_m", 3);
        m.time_offset_s = move.number("time_offset_s", 0.0);
        c.moves.push_back(m);
      }
    }
    return c;
  });
}

StatusOr<Rig> movedRig(const Rig& truth, const std::vector<SensorMove>& moves) {
  Rig out = truth;
  for (const SensorMove& m : moves) {
    const SE3 delta(Eigen::Quaterniond(Eigen::AngleAxisd(
                        m.rotation_rad.norm(), m.rotation_rad.norm() > 0.0
                                                   ? Eigen::Vector3d(m.rotation_rad.normalized())
                                                   : Eigen::Vector3d::UnitX())),
                    m.translation_m);
    bool found = false;
    for (auto& cam : out.cameras) {
      if (cam.name != m.sensor) continue;
      cam.T_cam_imu = delta * cam.T_cam_imu;
      cam.timeshift_cam_imu += m.time_offset_s;
      found = true;
    }
    for (std::size_t i = 1; i < out.inertial.size(); ++i) {
      if (out.inertial[i].name != m.sensor) continue;
      out.inertial[i].T_i_b = delta * out.inertial[i].T_i_b;
      out.inertial[i].time_offset += m.time_offset_s;
      found = true;
    }
    if (!found) {
      return Status::Error("moves: " + m.sensor +
                           ": no camera or auxiliary inertial sensor of that name in the rig");
    }
  }
  return out;
}

StatusOr<SimulationConfig> loadSimulationConfig(const std::string& path, std::size_t num_cameras) {
  std::ifstream in(path);
  if (!in) return Status::Error(path + ": cannot read the file");
  std::ostringstream text;
  text << in.rdbuf();
  return parseSimulationConfig(text.str(), path, num_cameras);
}

}  // namespace mvis
