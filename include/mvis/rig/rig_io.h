// Reading and writing the rig's configuration files (see doc/conventions.md and doc/formats.md):
//   kalibr_imu_chain.yaml     every inertial sensor (imu0 = base IMU)
//   kalibr_imucam_chain.yaml  every camera
//   aprilgrid.yaml            the tag board (optional)
//
// A bad file is refused with one message "FILE: SENSOR: KEY: problem" (SENSOR and KEY left out
// where they do not apply). What is used after a correction (a rotation printed to five digits,
// re-orthonormalized; Kalibr's T_cn_cnm1 disagreeing with the T_cam_imu chain) is accepted with
// a warning in the same form, appended to `warnings` when given. Nothing here throws, exits or
// logs.
//
// Besides mvis's own format (doc/conventions.md) the chain files may be OpenVINS's
// (`%YAML:1.0`, T_imu_cam, model kalibr) or Kalibr's results as they come (camchain-imucam with
// T_cn_cnm1 and cam_overlaps; the IMU file's gyroscopes/accelerometers sections).
#pragma once

#include <string>

#include "mvis/common/status.h"
#include "mvis/rig/rig.h"

namespace mvis {

inline constexpr const char* kImuChainFile = "kalibr_imu_chain.yaml";
inline constexpr const char* kCamChainFile = "kalibr_imucam_chain.yaml";
inline constexpr const char* kAprilGridFile = "aprilgrid.yaml";

// Each parser takes the file's text and the path used in messages.
StatusOr<std::vector<InertialSensor>> parseImuChain(const std::string& yaml_text,
                                                    const std::string& path,
                                                    std::vector<std::string>* warnings = nullptr);
StatusOr<std::vector<Camera>> parseCamChain(const std::string& yaml_text, const std::string& path,
                                            std::vector<std::string>* warnings = nullptr);
StatusOr<AprilGrid> parseAprilGrid(const std::string& yaml_text, const std::string& path);

// The three files of a configuration, by path.
struct RigFiles {
  std::string imu_chain;
  std::string cam_chain;
  std::string target;  // optional: used if the file exists
  // The default names in `directory`; a non-empty name replaces one (relative to `directory`
  // unless absolute), e.g. Kalibr's camchain-imucam-rig.yaml.
  static RigFiles in(const std::string& directory, const std::string& imu_chain = "",
                     const std::string& cam_chain = "", const std::string& target = "");
};

// Loads a configuration: the two chain files are required, the target file is optional. Also
// checks what spans files (a topic used twice).
StatusOr<Rig> loadRig(const RigFiles& files, std::vector<std::string>* warnings = nullptr);
// The default file names in a directory.
StatusOr<Rig> loadRig(const std::string& directory, std::vector<std::string>* warnings = nullptr);

// Text of each file in exactly the input format; *_std keys are added where the sensor has std.
std::string imuChainToYaml(const Rig& rig);
std::string camChainToYaml(const Rig& rig);
std::string aprilGridToYaml(const AprilGrid& grid);

// Writes the chain files (and aprilgrid.yaml if the rig has a target) into `directory`,
// creating it if needed.
Status saveRig(const Rig& rig, const std::string& directory);

}  // namespace mvis
