#include "mvis/estimator/evaluation.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

namespace mvis {

double positionRmse(const std::vector<EstimatorState>& estimate,
                    const std::vector<StampedPose>& truth) {
  std::map<TimeNs, SE3> by_stamp(truth.begin(), truth.end());
  double sum = 0.0;
  int n = 0;
  for (const auto& s : estimate) {
    auto after = by_stamp.lower_bound(s.stamp_ns);
    if (after == by_stamp.end()) continue;
    Eigen::Vector3d p = after->second.p;
    if (after->first != s.stamp_ns) {
      if (after == by_stamp.begin()) continue;
      const auto before = std::prev(after);
      const double lambda = static_cast<double>(s.stamp_ns - before->first) /
                            static_cast<double>(after->first - before->first);
      p = lie::interpolatePose(before->second, after->second, lambda).p;
    }
    sum += (p - s.T_G_I.p).squaredNorm();
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : std::numeric_limits<double>::quiet_NaN();
}

CameraCalibrationError cameraError(const Camera& truth, const Camera& estimate) {
  CameraCalibrationError e;
  e.rotation = lie::logQuat(estimate.T_cam_imu.q.conjugate() * truth.T_cam_imu.q);
  e.translation = truth.T_cam_imu.p - estimate.T_cam_imu.p;
  e.time_offset = truth.timeshift_cam_imu - estimate.timeshift_cam_imu;
  return e;
}

namespace {

std::string row(const char* camera, const char* quantity, double a, double b, double c,
                const char* last) {
  char line[160];
  std::snprintf(line, sizeof(line), "%-6s %-18s %14.4f %14.4f %12.4f  %s\n", camera, quantity, a, b,
                c, last);
  return line;
}

}  // namespace

std::string calibrationTable(const Rig& initial, const Rig& estimate, const Rig* truth) {
  constexpr double kDeg = 180.0 / M_PI;
  std::string out;
  char header[160];
  if (truth != nullptr) {
    std::snprintf(header, sizeof(header), "%-6s %-18s %14s %14s %12s  %s\n", "camera", "quantity",
                  "initial error", "final error", "3 sigma", "inside 3 sigma");
  } else {
    std::snprintf(header, sizeof(header), "%-6s %-18s %14s %14s %12s\n", "camera", "quantity",
                  "initial", "estimate", "3 sigma");
  }
  out += header;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t c = 0; c < estimate.cameras.size(); ++c) {
    const Camera& est = estimate.cameras[c];
    const char* name = est.name.c_str();
    const bool has_std = est.std.has_value();
    const double rot3 = has_std ? 3.0 * est.std->rotation.norm() * kDeg : nan;
    const double pos3 = has_std ? 3.0 * est.std->translation.norm() * 1e3 : nan;
    const double td3 = has_std ? 3.0 * est.std->timeshift_cam_imu * 1e3 : nan;
    if (truth != nullptr) {
      const CameraCalibrationError e0 = cameraError(truth->cameras[c], initial.cameras[c]);
      const CameraCalibrationError e1 = cameraError(truth->cameras[c], est);
      auto inside = [&](const Eigen::Vector3d& err, const Eigen::Vector3d& sd) {
        if (!has_std) return "-";
        for (int i = 0; i < 3; ++i) {
          if (std::abs(err[i]) > 3.0 * sd[i]) return "no";
        }
        return "yes";
      };
      out += row(name, "rotation [deg]", e0.rotation.norm() * kDeg, e1.rotation.norm() * kDeg, rot3,
                 has_std ? inside(e1.rotation, est.std->rotation) : "-");
      out += row(name, "translation [mm]", e0.translation.norm() * 1e3, e1.translation.norm() * 1e3,
                 pos3, has_std ? inside(e1.translation, est.std->translation) : "-");
      const bool td_inside =
          has_std && std::abs(e1.time_offset) <= 3.0 * est.std->timeshift_cam_imu;
      out += row(name, "time offset [ms]", std::abs(e0.time_offset) * 1e3,
                 std::abs(e1.time_offset) * 1e3, td3, has_std ? (td_inside ? "yes" : "no") : "-");
    } else {
      const Camera& ini = initial.cameras[c];
      const double angle =
          lie::logQuat(ini.T_cam_imu.q.conjugate() * est.T_cam_imu.q).norm() * kDeg;
      out += row(name, "rotation [deg]", 0.0, angle, rot3, "(change from initial)");
      out += row(name, "translation [mm]", 0.0, (est.T_cam_imu.p - ini.T_cam_imu.p).norm() * 1e3,
                 pos3, "(change from initial)");
      out += row(name, "time offset [ms]", ini.timeshift_cam_imu * 1e3, est.timeshift_cam_imu * 1e3,
                 td3, "");
    }
  }
  return out;
}

}  // namespace mvis
