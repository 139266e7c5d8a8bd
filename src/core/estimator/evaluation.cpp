#include "mvis/estimator/evaluation.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <tuple>

namespace mvis {

double positionRmse(const std::vector<EstimatorState>& estimate,
                    const std::vector<StampedPose>& truth, bool align) {
  std::map<TimeNs, SE3> by_stamp(truth.begin(), truth.end());
  std::vector<Eigen::Vector3d> est, ref;
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
    ref.push_back(p);
    est.push_back(s.T_G_I.p);
  }
  const std::size_t n = est.size();
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  if (align && n >= 3) {
    Eigen::Matrix3Xd a(3, n), b(3, n);
    for (std::size_t i = 0; i < n; ++i) {
      a.col(i) = est[i];
      b.col(i) = ref[i];
    }
    T = Eigen::umeyama(a, b, false);
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sum += (ref[i] - (T.topLeftCorner<3, 3>() * est[i] + T.topRightCorner<3, 1>())).squaredNorm();
  }
  return std::sqrt(sum / n);
}

namespace {

constexpr double kDeg = 180.0 / M_PI;

// A sensor's extrinsic and time offset in a common shape: T (T_cam_imu or T_i_b), the offset
// and their standard deviations.
struct SpatialTemporal {
  std::string name;
  bool has_translation = true;  // a gyroscope's is not calibrated
  SE3 T;
  double time_offset = 0.0;
  bool has_std = false;
  Eigen::Vector3d rotation_std = Eigen::Vector3d::Zero(), translation_std = Eigen::Vector3d::Zero();
  double time_offset_std = 0.0;
};

SpatialTemporal ofCamera(const Camera& c) {
  SpatialTemporal s;
  s.name = c.name;
  s.T = c.T_cam_imu;
  s.time_offset = c.timeshift_cam_imu;
  if (c.std) {
    s.has_std = true;
    s.rotation_std = c.std->rotation;
    s.translation_std = c.std->translation;
    s.time_offset_std = c.std->timeshift_cam_imu;
  }
  return s;
}

SpatialTemporal ofInertial(const InertialSensor& i) {
  SpatialTemporal s;
  s.name = i.name;
  s.has_translation = i.type != InertialType::kGyroscope;
  s.T = i.T_i_b;
  s.time_offset = i.time_offset;
  if (i.std) {
    s.has_std = true;
    s.rotation_std = i.std->rotation;
    s.translation_std = i.std->translation;
    s.time_offset_std = i.std->time_offset;
  }
  return s;
}

CameraCalibrationError errorOf(const SpatialTemporal& truth, const SpatialTemporal& estimate) {
  CameraCalibrationError e;
  e.rotation = lie::logQuat(estimate.T.q.conjugate() * truth.T.q);
  e.translation = truth.T.p - estimate.T.p;
  e.time_offset = truth.time_offset - estimate.time_offset;
  return e;
}

std::string row(const char* sensor, const char* quantity, double a, double b, double c,
                const char* last) {
  char line[160];
  std::snprintf(line, sizeof(line), "%-6s %-18s %14.4f %14.4f %12.4f  %s\n", sensor, quantity, a, b,
                c, last);
  return line;
}

std::string rows(const SpatialTemporal& ini, const SpatialTemporal& est,
                 const SpatialTemporal* truth) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const char* name = est.name.c_str();
  const bool has_std = est.has_std;
  const double rot3 = has_std ? 3.0 * est.rotation_std.norm() * kDeg : nan;
  const double pos3 = has_std ? 3.0 * est.translation_std.norm() * 1e3 : nan;
  const double td3 = has_std ? 3.0 * est.time_offset_std * 1e3 : nan;
  std::string out;
  if (truth != nullptr) {
    const CameraCalibrationError e0 = errorOf(*truth, ini);
    const CameraCalibrationError e1 = errorOf(*truth, est);
    auto inside = [&](const Eigen::Vector3d& err, const Eigen::Vector3d& sd) {
      if (!has_std) return "-";
      for (int i = 0; i < 3; ++i) {
        if (std::abs(err[i]) > 3.0 * sd[i]) return "no";
      }
      return "yes";
    };
    out += row(name, "rotation [deg]", e0.rotation.norm() * kDeg, e1.rotation.norm() * kDeg, rot3,
               inside(e1.rotation, est.rotation_std));
    if (est.has_translation) {
      out += row(name, "translation [mm]", e0.translation.norm() * 1e3, e1.translation.norm() * 1e3,
                 pos3, inside(e1.translation, est.translation_std));
    }
    const bool td_inside = has_std && std::abs(e1.time_offset) <= 3.0 * est.time_offset_std;
    out += row(name, "time offset [ms]", std::abs(e0.time_offset) * 1e3,
               std::abs(e1.time_offset) * 1e3, td3, has_std ? (td_inside ? "yes" : "no") : "-");
  } else {
    const double angle = lie::logQuat(ini.T.q.conjugate() * est.T.q).norm() * kDeg;
    out += row(name, "rotation [deg]", 0.0, angle, rot3, "(change from initial)");
    if (est.has_translation) {
      out += row(name, "translation [mm]", 0.0, (est.T.p - ini.T.p).norm() * 1e3, pos3,
                 "(change from initial)");
    }
    out += row(name, "time offset [ms]", ini.time_offset * 1e3, est.time_offset * 1e3, td3, "");
  }
  return out;
}

// Intrinsics rows of a camera whose intrinsics were estimated (nonzero std): the largest
// |error| (or change) of the focal lengths, of the centre and of the distortion coefficients.
std::string intrinsicRows(const Camera& ini, const Camera& est, const Camera* truth) {
  if (!est.std || (est.std->intrinsics.array() == 0.0).all()) return "";
  Eigen::Matrix<double, 8, 1> x0, x, sd, ref;
  x0 << ini.intrinsics, ini.distortion_coeffs;
  x << est.intrinsics, est.distortion_coeffs;
  sd << est.std->intrinsics, est.std->distortion_coeffs;
  if (truth != nullptr) ref << truth->intrinsics, truth->distortion_coeffs;
  std::string out;
  for (const auto& [label, first, count] :
       {std::tuple<const char*, int, int>{"focal lengths [px]", 0, 2},
        {"centre [px]", 2, 2},
        {"distortion", 4, 4}}) {
    const auto seg = [&](const Eigen::Matrix<double, 8, 1>& v) { return v.segment(first, count); };
    const double three_sigma = 3.0 * seg(sd).maxCoeff();
    if (truth != nullptr) {
      const Eigen::VectorXd e0 = seg(ref) - seg(x0), e1 = seg(ref) - seg(x);
      const bool inside = (e1.array().abs() <= 3.0 * seg(sd).array()).all();
      out += row(est.name.c_str(), label, e0.cwiseAbs().maxCoeff(), e1.cwiseAbs().maxCoeff(),
                 three_sigma, inside ? "yes" : "no");
    } else {
      out += row(est.name.c_str(), label, 0.0, (seg(x) - seg(x0)).cwiseAbs().maxCoeff(),
                 three_sigma, "(change from initial)");
    }
  }
  return out;
}

// IMU intrinsics rows of an inertial sensor whose intrinsics were estimated (nonzero Tw_std):
// the largest |error| (or change) of a Dw or Da element (what the report estimates; their
// standard deviations are Tw's and Ta's to first order), of a Tg element, and the angle of
// R_IMUtoACC.
std::string imuIntrinsicRows(const InertialSensor& ini, const InertialSensor& est,
                             const InertialSensor* truth) {
  if (!est.std || (est.std->Tw.array() == 0.0).all()) return "";
  const bool gyro = est.type == InertialType::kGyroscope;
  const ImuIntrinsics& x = est.intrinsics;
  const ImuIntrinsics& ref = truth != nullptr ? truth->intrinsics : ini.intrinsics;
  const InertialCalibrationStd& sd = *est.std;
  const auto dD = [&](const ImuIntrinsics& a) {
    Eigen::Matrix<double, 3, 6> d;
    d << a.Tw.inverse() - ref.Tw.inverse(),
        (gyro ? Eigen::Matrix3d::Zero() : Eigen::Matrix3d(a.Ta.inverse() - ref.Ta.inverse()));
    return d.cwiseAbs().maxCoeff();
  };
  const auto within = [](const Eigen::Matrix3d& err, const Eigen::Matrix3d& s) {
    return (err.array().abs() <= 3.0 * s.array() + 1e-15).all();
  };
  const char* name = est.name.c_str();
  const bool compare = truth != nullptr;
  const auto status = [&](bool inside) {
    return compare ? (inside ? "yes" : "no") : "(change from initial)";
  };
  std::string out;
  out += row(name, "Dw, Da [1e-3]", compare ? dD(ini.intrinsics) * 1e3 : 0.0, dD(x) * 1e3,
             3e3 * std::max(sd.Tw.maxCoeff(), gyro ? 0.0 : sd.Ta.maxCoeff()),
             status(within(x.Tw - ref.Tw, sd.Tw) && (gyro || within(x.Ta - ref.Ta, sd.Ta))));
  if (gyro) return out;
  if (sd.Tg.maxCoeff() > 0.0) {
    out += row(name, "Tg [1e-3]",
               compare ? (ini.intrinsics.Tg - ref.Tg).cwiseAbs().maxCoeff() * 1e3 : 0.0,
               (x.Tg - ref.Tg).cwiseAbs().maxCoeff() * 1e3, 3e3 * sd.Tg.maxCoeff(),
               status(within(x.Tg - ref.Tg, sd.Tg)));
  }
  const auto angle = [&](const Eigen::Matrix3d& R) {
    return lie::logSO3(ref.R_IMUtoACC.transpose() * R);
  };
  const Eigen::Vector3d e1 = angle(x.R_IMUtoACC);
  out +=
      row(name, "R_IMUtoACC [deg]", compare ? angle(ini.intrinsics.R_IMUtoACC).norm() * kDeg : 0.0,
          e1.norm() * kDeg, 3.0 * sd.R_IMUtoACC.maxCoeff() * kDeg,
          status((e1.array().abs() <= 3.0 * sd.R_IMUtoACC.array()).all()));
  return out;
}

}  // namespace

double timeOffsetFloor(const std::vector<StampedPose>& truth, const ImuNoise& noise,
                       double gravity_m_s2) {
  const std::size_t n = truth.size();
  if (n < 5 || !(noise.gyroscope_noise_density > 0.0) ||
      !(noise.accelerometer_noise_density > 0.0)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const auto time = [&](std::size_t i) { return toSeconds(truth[i].first - truth[0].first); };
  // Rates in {I} between samples i and i+1, at their midpoints.
  std::vector<Eigen::Vector3d> w(n - 1);
  std::vector<double> t_mid(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const double dt = time(i + 1) - time(i);
    w[i] = lie::logQuat(truth[i].second.q.conjugate() * truth[i + 1].second.q) / dt;
    t_mid[i] = 0.5 * (time(i) + time(i + 1));
  }
  // Specific force in {I} at the inner samples (second central difference of the position).
  const Eigen::Vector3d g(0.0, 0.0, -gravity_m_s2);
  std::vector<Eigen::Vector3d> f(n - 2);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    const Eigen::Vector3d v0 =
        (truth[i].second.p - truth[i - 1].second.p) / (time(i) - time(i - 1));
    const Eigen::Vector3d v1 =
        (truth[i + 1].second.p - truth[i].second.p) / (time(i + 1) - time(i));
    const Eigen::Vector3d a = (v1 - v0) / (t_mid[i] - t_mid[i - 1]);
    f[i - 1] = truth[i].second.q.conjugate() * (a - g);
  }
  const double step = (time(n - 1) - time(0)) / static_cast<double>(n - 1);
  double gyro = 0.0, accel = 0.0;
  for (std::size_t i = 0; i + 1 < w.size(); ++i) {
    gyro += ((w[i + 1] - w[i]) / (t_mid[i + 1] - t_mid[i])).squaredNorm();
  }
  for (std::size_t i = 0; i + 1 < f.size(); ++i) {
    accel += ((f[i + 1] - f[i]) / (time(i + 2) - time(i + 1))).squaredNorm();
  }
  const double qg = noise.gyroscope_noise_density, qa = noise.accelerometer_noise_density;
  return 1.0 / std::sqrt((gyro / (qg * qg) + accel / (qa * qa)) * step);
}

CameraCalibrationError cameraError(const Camera& truth, const Camera& estimate) {
  return errorOf(ofCamera(truth), ofCamera(estimate));
}

CameraCalibrationError inertialError(const InertialSensor& truth, const InertialSensor& estimate) {
  return errorOf(ofInertial(truth), ofInertial(estimate));
}

std::string calibrationTable(const Rig& initial, const Rig& estimate, const Rig* truth) {
  std::string out;
  char header[160];
  if (truth != nullptr) {
    std::snprintf(header, sizeof(header), "%-6s %-18s %14s %14s %12s  %s\n", "sensor", "quantity",
                  "initial error", "final error", "3 sigma", "inside 3 sigma");
  } else {
    std::snprintf(header, sizeof(header), "%-6s %-18s %14s %14s %12s\n", "sensor", "quantity",
                  "initial", "estimate", "3 sigma");
  }
  out += header;
  for (std::size_t c = 0; c < estimate.cameras.size(); ++c) {
    const SpatialTemporal t = truth ? ofCamera(truth->cameras[c]) : SpatialTemporal{};
    out += rows(ofCamera(initial.cameras[c]), ofCamera(estimate.cameras[c]), truth ? &t : nullptr);
    out += intrinsicRows(initial.cameras[c], estimate.cameras[c],
                         truth ? &truth->cameras[c] : nullptr);
  }
  for (std::size_t i = 0; i < estimate.inertial.size(); ++i) {
    if (i > 0) {
      const SpatialTemporal t = truth ? ofInertial(truth->inertial[i]) : SpatialTemporal{};
      out += rows(ofInertial(initial.inertial[i]), ofInertial(estimate.inertial[i]),
                  truth ? &t : nullptr);
    }
    out += imuIntrinsicRows(initial.inertial[i], estimate.inertial[i],
                            truth ? &truth->inertial[i] : nullptr);
  }
  return out;
}

}  // namespace mvis
