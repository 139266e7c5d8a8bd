// kalibr_imucam_chain.yaml: reading with validation, and writing in the same format.
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

const std::set<std::string> kCameraKeys = {
    "T_cam_imu",         "T_imu_cam",  "timeshift_cam_imu", "camera_model", "distortion_model",
    "distortion_coeffs", "intrinsics", "resolution",        "rostopic",     "T_cn_cnm1"};
// Keys other tools write that mvis does not use (Kalibr: which cameras see the same target).
const std::set<std::string> kIgnoredCameraKeys = {"cam_overlaps"};
// T_cn_cnm1 against the T_cam_imu chain: a disagreement beyond this is more than printing
// precision [rad, m].
constexpr double kChainTolerance = 1e-4;

std::optional<CameraCalibrationStd> readStd(const EntryReader& entry) {
  const std::vector<std::string> keys = {"T_cam_imu_std", "timeshift_cam_imu_std", "intrinsics_std",
                                         "distortion_coeffs_std"};
  bool any = false;
  for (const auto& key : keys) any = any || entry.has(key);
  if (!any) return std::nullopt;
  CameraCalibrationStd std;
  if (entry.has("T_cam_imu_std")) {
    const EntryReader t = entry.child("T_cam_imu_std");
    std.rotation = t.nonNegativeVector("rotation", 3);
    std.translation = t.nonNegativeVector("translation", 3);
  }
  if (entry.has("timeshift_cam_imu_std")) {
    std.timeshift_cam_imu = entry.nonNegativeNumber("timeshift_cam_imu_std");
  }
  if (entry.has("intrinsics_std")) std.intrinsics = entry.nonNegativeVector("intrinsics_std", 4);
  if (entry.has("distortion_coeffs_std")) {
    std.distortion_coeffs = entry.nonNegativeVector("distortion_coeffs_std", 4);
  }
  return std;
}

// Camera `name`; `previous` is the camera before it (for Kalibr's T_cn_cnm1), null for cam0.
Camera readCamera(const EntryReader& entry, const std::string& name, const Camera* previous) {
  entry.rejectUnknownKeys(kCameraKeys, kIgnoredCameraKeys);
  Camera cam;
  cam.name = name;
  const bool has_cam_imu = entry.has("T_cam_imu");
  const bool has_imu_cam = entry.has("T_imu_cam");
  if (has_cam_imu && has_imu_cam) {
    entry.fail("T_imu_cam", "give T_cam_imu or T_imu_cam, not both");
  }
  if (has_imu_cam) {
    cam.T_cam_imu = entry.transform("T_imu_cam").inverse();
  } else if (has_cam_imu) {
    cam.T_cam_imu = entry.transform("T_cam_imu");
  } else {
    entry.fail("T_cam_imu",
               std::string("missing (the camera's pose relative to imu0") +
                   (entry.has("T_cn_cnm1") ? "; a camchain from kalibr_calibrate_cameras has "
                                             "none: use the camchain-imucam file that "
                                             "kalibr_calibrate_imu_camera writes)"
                                           : ")"));
  }
  if (entry.has("T_cn_cnm1")) {
    // Kalibr's camera n from camera n-1: redundant with the T_cam_imu chain; checked.
    if (previous == nullptr) entry.fail("T_cn_cnm1", "cam0 has no camera before it");
    const SE3 given = entry.transform("T_cn_cnm1");
    const SE3 chain = cam.T_cam_imu * previous->T_cam_imu.inverse();
    const double angle = lie::logQuat(given.q.conjugate() * chain.q).norm();
    const double distance = (given.p - chain.p).norm();
    if (angle > kChainTolerance || distance > kChainTolerance) {
      entry.warn("T_cn_cnm1", "disagrees with " + name + " and " + previous->name +
                                  "'s T_cam_imu by " + formatNumber(angle) + " rad and " +
                                  formatNumber(distance) + " m; mvis uses T_cam_imu");
    }
  }
  cam.timeshift_cam_imu = entry.number("timeshift_cam_imu", 0.0);

  const std::string camera_model = entry.text("camera_model", "pinhole");
  if (camera_model != "pinhole") {
    const bool kalibr = camera_model == "omni" || camera_model == "ds" || camera_model == "eucm";
    entry.fail("camera_model",
               (kalibr ? "Kalibr's camera model '" + camera_model + "' is not supported"
                       : "unknown camera model '" + camera_model + "'") +
                   " (mvis supports pinhole, with radtan or equidistant distortion: calibrate "
                   "with Kalibr's pinhole-radtan or pinhole-equi)");
  }
  const std::string distortion = entry.text("distortion_model");
  if (distortion == "radtan") {
    cam.distortion_model = DistortionModel::kRadtan;
  } else if (distortion == "equidistant") {
    cam.distortion_model = DistortionModel::kEquidistant;
  } else if (distortion == "fov" || distortion == "none") {
    entry.fail("distortion_model",
               "Kalibr's distortion model '" + distortion +
                   "' is not supported (mvis supports radtan and equidistant: calibrate with "
                   "Kalibr's pinhole-radtan or pinhole-equi)");
  } else {
    entry.fail("distortion_model",
               "unknown distortion model '" + distortion + "' (expected radtan or equidistant)");
  }
  cam.distortion_coeffs = entry.vector("distortion_coeffs", 4);
  cam.intrinsics = entry.vector("intrinsics", 4);
  if (cam.intrinsics[0] <= 0.0 || cam.intrinsics[1] <= 0.0) {
    entry.fail("intrinsics", "focal lengths fu, fv must be positive");
  }
  const Eigen::VectorXd resolution = entry.vector("resolution", 2);
  for (int i = 0; i < 2; ++i) {
    if (resolution[i] < 1.0 || resolution[i] != std::floor(resolution[i]) ||
        resolution[i] > 100000.0) {
      entry.fail("resolution", "expected [width, height] as positive whole numbers of pixels");
    }
    cam.resolution[i] = static_cast<int>(resolution[i]);
  }
  cam.rostopic = entry.text("rostopic");
  cam.std = readStd(entry);
  return cam;
}

}  // namespace

StatusOr<std::vector<Camera>> parseCamChain(const std::string& yaml_text, const std::string& path,
                                            std::vector<std::string>* warnings) {
  return rig_io::guardedParse(path, [&] {
    const YAML::Node root = rig_io::parseYamlText(yaml_text, path);
    std::vector<Camera> cameras;
    for (const auto& name : rig_io::numberedEntries(root, "cam", path)) {
      cameras.push_back(readCamera(EntryReader(root[name], path, name, warnings), name,
                                   cameras.empty() ? nullptr : &cameras.back()));
    }
    rig_io::requireUniqueTopics(cameras, path);
    return cameras;
  });
}

std::string camChainToYaml(const Rig& rig) {
  std::ostringstream out;
  out << "# Cameras of the rig. Format: doc/conventions.md\n";
  for (const auto& cam : rig.cameras) {
    out << cam.name << ":\n";
    out << "  T_cam_imu:\n" << formatMatrix(cam.T_cam_imu.matrix(), 4);
    out << "  timeshift_cam_imu: " << formatNumber(cam.timeshift_cam_imu) << "\n";
    out << "  camera_model: pinhole\n";
    out << "  distortion_model: " << toString(cam.distortion_model) << "\n";
    out << "  distortion_coeffs: " << formatRow(cam.distortion_coeffs) << "\n";
    out << "  intrinsics: " << formatRow(cam.intrinsics) << "\n";
    out << "  resolution: [" << cam.resolution[0] << ", " << cam.resolution[1] << "]\n";
    out << "  rostopic: " << cam.rostopic << "\n";
    if (cam.std) {
      out << "  T_cam_imu_std:\n    rotation: " << formatRow(cam.std->rotation)
          << "\n    translation: " << formatRow(cam.std->translation) << "\n";
      out << "  timeshift_cam_imu_std: " << formatNumber(cam.std->timeshift_cam_imu) << "\n";
      out << "  intrinsics_std: " << formatRow(cam.std->intrinsics) << "\n";
      out << "  distortion_coeffs_std: " << formatRow(cam.std->distortion_coeffs) << "\n";
    }
  }
  return out.str();
}

}  // namespace mvis
