// A whole simulated run of a rig: every inertial sensor's samples, every camera's images or
// tag detections, each stamped in its own clock, and the base IMU's true trajectory.
#pragma once

#include <opencv2/core/mat.hpp>
#include <vector>

#include "mvis/rig/trajectory_io.h"
#include "mvis/sim/simulation_config.h"

namespace mvis {

// Receives the simulated data as it is made (images are too many to keep).
class SimulationSink {
 public:
  virtual ~SimulationSink() = default;
  virtual void imu(std::size_t sensor, const ImuSample& sample) = 0;
  virtual void tagFrame(const TagFrame& frame) = 0;                                  // detections
  virtual void image(std::size_t camera, TimeNs stamp_ns, const cv::Mat& gray) = 0;  // images
};

// Runs the simulation of `truth` (which needs an aprilgrid target) as `config` says. Sensor by
// sensor, each in time order. Returns the base IMU's true trajectory at its sample times.
StatusOr<std::vector<StampedPose>> runSimulation(const Rig& truth, const SimulationConfig& config,
                                                 SimulationSink* sink);

}  // namespace mvis
