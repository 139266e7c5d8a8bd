// Writing a simulated run (mvis_simulate) as a ROS bag plus truth and initial-guess files:
//   OUTPUT/sim.bag     sensor_msgs/Imu per inertial sensor on its rostopic; per camera
//                      sensor_msgs/Image (mono8) on its rostopic (with `compressed_images`
//                      sensor_msgs/CompressedImage, PNG, on <rostopic>/compressed instead), or
//                      mvis/TagDetectionArray on <rostopic>/tag_detections; every stamp in the
//                      sensor's own clock
//   OUTPUT/truth/      the true kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml, aprilgrid.yaml,
//                      and trajectory.tum (imu0 in the world at its sample times); with sensors
//                      that move (SimulationConfig::moves), the rig at the end
//   OUTPUT/truth_start/  with sensors that move, the rig before they do
//   OUTPUT/config/     the same files perturbed: a user's rough initial guess
#pragma once

#include <string>

#include "mvis/common/status.h"
#include "mvis/rig/rig.h"
#include "mvis/sim/simulation_config.h"

namespace mvis {

struct SimulationBagSummary {
  std::size_t imu_messages = 0;
  std::size_t camera_messages = 0;
  std::size_t tags = 0;  // in detection messages
  double seconds = 0.0;  // wall time taken
};

StatusOr<SimulationBagSummary> writeSimulationBag(const Rig& truth, const SimulationConfig& config,
                                                  const std::string& output_dir,
                                                  bool compressed_images = false);

}  // namespace mvis
