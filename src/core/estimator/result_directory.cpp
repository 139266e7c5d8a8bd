#include "mvis/estimator/result_directory.h"

#include <filesystem>
#include <system_error>

#include "mvis/rig/rig_io.h"
#include "mvis/rig/trajectory_io.h"

namespace mvis {

Status writeResultDirectory(const std::string& dir, const Rig& calibration,
                            const std::vector<EstimatorState>& trajectory, const EstimateLog& log) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);  // if that fails, the first file says so
  Status status = saveRig(calibration, dir);
  if (!status.ok()) return status;
  std::vector<StampedPose> poses;
  for (const auto& s : trajectory) poses.emplace_back(s.stamp_ns, s.T_G_I);
  status = writeTumTrajectory(dir + "/trajectory.tum", poses);
  if (!status.ok()) return status;
  return log.write(dir);
}

}  // namespace mvis
