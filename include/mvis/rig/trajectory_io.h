// Trajectories in TUM format: one line per pose, "timestamp tx ty tz qx qy qz qw", timestamp in
// seconds (base clock), the pose T_G_I of imu0 in the world.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "mvis/common/lie.h"
#include "mvis/common/status.h"
#include "mvis/common/time.h"

namespace mvis {

using StampedPose = std::pair<TimeNs, SE3>;

// Stamps are written as whole seconds and nanoseconds ("1700000000.000000001"), exactly.
Status writeTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses);
StatusOr<std::vector<StampedPose>> readTumTrajectory(const std::string& path);

}  // namespace mvis
