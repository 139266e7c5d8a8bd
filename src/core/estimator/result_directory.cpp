#include "mvis/estimator/result_directory.h"

#include <cstdio>
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

Status writeBatchResiduals(const std::string& dir, const Rig& rig, const BatchSummary& batch,
                           TimeNs stamp_ns) {
  if (batch.model_calibration) {
    EstimateLog model;
    model.addCalibration(stamp_ns, *batch.model_calibration);
    const Status s = model.writeCalibration(dir + "/calibration_model.csv");
    if (!s.ok()) return s;
  }
  const std::string corners_path = dir + "/corner_residuals.csv";
  std::FILE* f = std::fopen(corners_path.c_str(), "w");
  if (f == nullptr) return Status::Error(corners_path + ": cannot write");
  std::fputs("stamp,camera,x,y,z,corner,u,v,du,dv,sigma\n", f);
  for (const CornerResidual& c : batch.corners) {
    writeStamp(f, c.stamp_ns);
    std::fprintf(f, ",%s,%.6g,%.6g,%.6g,%d,%.4f,%.4f,%.5f,%.5f,%.4g\n",
                 rig.cameras[static_cast<std::size_t>(c.camera)].name.c_str(), c.p_G.x(), c.p_G.y(),
                 c.p_G.z(), c.corner, c.uv.x(), c.uv.y(), c.residual.x(), c.residual.y(),
                 batch.pixel_sigma_px);
  }
  if (std::fclose(f) != 0) return Status::Error(corners_path + ": cannot write");
  const std::string inertial_path = dir + "/inertial_residuals.csv";
  f = std::fopen(inertial_path.c_str(), "w");
  if (f == nullptr) return Status::Error(inertial_path + ": cannot write");
  std::fputs("stamp,sensor,residuals,chi_square\n", f);
  for (const InertialResidual& r : batch.inertial) {
    writeStamp(f, r.stamp_ns);
    std::fprintf(f, ",%s,%d,%.6g\n", rig.inertial[static_cast<std::size_t>(r.sensor)].name.c_str(),
                 r.residuals, r.chi_square);
  }
  if (std::fclose(f) != 0) return Status::Error(inertial_path + ": cannot write");
  return Status::Ok();
}

}  // namespace mvis
