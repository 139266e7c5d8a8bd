// Reading and writing the rig's configuration files (see doc/conventions.md and README):
//   kalibr_imu_chain.yaml     every inertial sensor (imu0 = base IMU)
//   kalibr_imucam_chain.yaml  every camera
//   aprilgrid.yaml            the tag board (optional)
//
// A bad file is refused with one message "FILE: SENSOR: KEY: problem" (SENSOR and KEY left out
// where they do not apply). Nothing here throws, exits or logs.
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
                                                    const std::string& path);
StatusOr<std::vector<Camera>> parseCamChain(const std::string& yaml_text, const std::string& path);
StatusOr<AprilGrid> parseAprilGrid(const std::string& yaml_text, const std::string& path);

// Loads a configuration directory: the two chain files are required, aprilgrid.yaml is
// optional. Also checks what spans files (a topic used twice).
StatusOr<Rig> loadRig(const std::string& directory);

// Text of each file in exactly the input format; *_std keys are added where the sensor has std.
std::string imuChainToYaml(const Rig& rig);
std::string camChainToYaml(const Rig& rig);
std::string aprilGridToYaml(const AprilGrid& grid);

// Writes the chain files (and aprilgrid.yaml if the rig has a target) into `directory`,
// creating it if needed.
Status saveRig(const Rig& rig, const std::string& directory);

}  // namespace mvis
