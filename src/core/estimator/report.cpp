#include "mvis/estimator/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "mvis/common/lie.h"
#include "mvis/common/time.h"
#include "mvis/estimator/evaluation.h"

#ifndef MVIS_VERSION
#define MVIS_VERSION "unknown"
#endif

namespace mvis {
namespace {

constexpr double kDeg = 180.0 / M_PI;

std::string format(const char* fmt, double a) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, a);
  return buf;
}

std::string vec(const Eigen::Vector3d& v, double scale, const char* fmt) {
  return format(fmt, scale * v.x()) + ", " + format(fmt, scale * v.y()) + ", " +
         format(fmt, scale * v.z());
}

std::string vec4(const Eigen::Vector4d& v, const char* fmt) {
  return format(fmt, v[0]) + ", " + format(fmt, v[1]) + ", " + format(fmt, v[2]) + ", " +
         format(fmt, v[3]);
}

// The largest |change| / sigma over the axes with a positive sigma; NaN when none has one.
double inSigmas(const Eigen::VectorXd& change, const Eigen::VectorXd& sigma) {
  double worst = std::numeric_limits<double>::quiet_NaN();
  for (int i = 0; i < change.size(); ++i) {
    if (!(sigma[i] > 0.0) || !std::isfinite(sigma[i])) continue;
    const double r = std::abs(change[i]) / sigma[i];
    worst = std::isnan(worst) ? r : std::max(worst, r);
  }
  return worst;
}

std::string sigmas(double s) { return std::isnan(s) ? "-" : format("%.1f", s); }

struct Row {
  std::string sensor, quantity, estimate, sigma, change;
  double change_sigma;
};

// An extrinsic's rotation and translation (a gyroscope's: rotation only) and a time offset.
struct Extrinsic {
  std::string sensor, transform, offset_key;  // "cam0", "T_cam_imu", "timeshift_cam_imu"
  SE3 estimate;
  CameraCalibrationError change;  // from the initial guess, in the estimate's tangent
  Eigen::Vector3d rotation_std, translation_std;
  bool translation = true;
  double offset = 0.0, offset_initial = 0.0, offset_std = 0.0;  // [s]
};

void extrinsicRows(const Extrinsic& x, std::vector<Row>* rows) {
  const CameraCalibrationError& d = x.change;
  rows->push_back({x.sensor, "rotation of " + x.transform + " [deg]",
                   vec(lie::logQuat(x.estimate.q), kDeg, "%.3f"), vec(x.rotation_std, kDeg, "%.3f"),
                   format("%.3f deg", kDeg * d.rotation.norm()),
                   inSigmas(d.rotation, x.rotation_std)});
  if (x.translation) {
    rows->push_back({x.sensor, "translation of " + x.transform + " [mm]",
                     vec(x.estimate.p, 1e3, "%.2f"), vec(x.translation_std, 1e3, "%.2f"),
                     format("%.2f mm", 1e3 * d.translation.norm()),
                     inSigmas(d.translation, x.translation_std)});
  }
  rows->push_back({x.sensor, x.offset_key + " [ms]", format("%.3f", 1e3 * x.offset),
                   format("%.3f", 1e3 * x.offset_std),
                   format("%+.3f ms", 1e3 * (x.offset - x.offset_initial)),
                   inSigmas(Eigen::VectorXd::Constant(1, d.time_offset),
                            Eigen::VectorXd::Constant(1, x.offset_std))});
}

void cameraRows(const Camera& init, const Camera& est, std::vector<Row>* rows) {
  const CameraCalibrationStd s = est.std.value_or(CameraCalibrationStd());
  extrinsicRows({est.name, "T_cam_imu", "timeshift_cam_imu", est.T_cam_imu, cameraError(init, est),
                 s.rotation, s.translation, true, est.timeshift_cam_imu, init.timeshift_cam_imu,
                 s.timeshift_cam_imu},
                rows);
  if (s.intrinsics.allFinite() && s.intrinsics.maxCoeff() > 0.0) {
    const Eigen::Vector4d di = est.intrinsics - init.intrinsics;
    rows->push_back({est.name, "intrinsics fu, fv, pu, pv [px]", vec4(est.intrinsics, "%.2f"),
                     vec4(s.intrinsics, "%.2f"), format("%.2f px", di.cwiseAbs().maxCoeff()),
                     inSigmas(di, s.intrinsics)});
    const Eigen::Vector4d dd = est.distortion_coeffs - init.distortion_coeffs;
    rows->push_back({est.name, "distortion_coeffs", vec4(est.distortion_coeffs, "%.5f"),
                     vec4(s.distortion_coeffs, "%.5f"), format("%.5f", dd.cwiseAbs().maxCoeff()),
                     inSigmas(dd, s.distortion_coeffs)});
  }
}

void matrixRow(const std::string& sensor, const std::string& name, const Eigen::Matrix3d& init,
               const Eigen::Matrix3d& est, const Eigen::Matrix3d& sigma, std::vector<Row>* rows) {
  if (!sigma.allFinite() || !(sigma.maxCoeff() > 0.0)) return;
  const Eigen::Matrix3d d = est - init;
  Eigen::VectorXd dv = Eigen::Map<const Eigen::VectorXd>(d.data(), 9);
  Eigen::VectorXd sv = Eigen::Map<const Eigen::VectorXd>(sigma.data(), 9);
  std::ostringstream e;
  e << format("diagonal %.5f", est(0, 0)) << ", " << format("%.5f", est(1, 1)) << ", "
    << format("%.5f", est(2, 2));
  rows->push_back({sensor, name + " (largest element)", e.str(), format("%.5f", sigma.maxCoeff()),
                   format("%.5f", d.cwiseAbs().maxCoeff()), inSigmas(dv, sv)});
}

void inertialRows(const InertialSensor& init, const InertialSensor& est, bool base,
                  std::vector<Row>* rows) {
  const InertialCalibrationStd s = est.std.value_or(InertialCalibrationStd());
  if (!base) {
    extrinsicRows({est.name, "T_i_b", "time_offset", est.T_i_b, inertialError(init, est),
                   s.rotation, s.translation, est.type != InertialType::kGyroscope, est.time_offset,
                   init.time_offset, s.time_offset},
                  rows);
  }
  matrixRow(est.name, "Tw", init.intrinsics.Tw, est.intrinsics.Tw, s.Tw, rows);
  matrixRow(est.name, "Ta", init.intrinsics.Ta, est.intrinsics.Ta, s.Ta, rows);
  matrixRow(est.name, "Tg [rad/s per m/s^2]", init.intrinsics.Tg, est.intrinsics.Tg, s.Tg, rows);
}

// What the options hold at the configured value, and why.
std::vector<std::string> heldByConfiguration(const EstimatorOptions& o, const Rig& rig) {
  std::vector<std::string> out;
  if (!o.estimate_extrinsics) out.push_back("every camera's extrinsic: estimate_extrinsics false");
  if (!o.estimate_time_offsets) {
    out.push_back("every camera's time offset: estimate_time_offsets false");
  }
  if (!o.estimate_intrinsics) out.push_back("every camera's intrinsics: estimate_intrinsics false");
  if (rig.inertial.size() > 1 && !o.estimate_aux_extrinsics) {
    out.push_back("auxiliary sensors' extrinsics: estimate_aux_extrinsics false");
  }
  if (rig.inertial.size() > 1 && !o.estimate_aux_time_offsets) {
    out.push_back("auxiliary sensors' time offsets: estimate_aux_time_offsets false");
  }
  bool modelled = false;
  for (const auto& s : rig.inertial) modelled = modelled || s.model != ImuModel::kCalibrated;
  if (!modelled) {
    out.push_back("IMU intrinsics: every sensor's model is calibrated (identity)");
  } else if (!o.estimate_imu_intrinsics) {
    out.push_back("IMU intrinsics: estimate_imu_intrinsics false");
  } else if (!o.estimate_gravity_sensitivity) {
    out.push_back("gravity sensitivity Tg: estimate_gravity_sensitivity false");
  }
  for (const auto& h : o.hold) out.push_back(h + ": held by name (hold)");
  return out;
}

}  // namespace

std::string renderReport(const ReportInputs& in) {
  std::ostringstream md;
  md << std::boolalpha;
  const Rig& est = *in.estimate;
  const Rig& init = *in.initial;
  md << "# mvis calibration report\n\n";
  const double span = toSeconds(in.last_ns - in.first_ns);
  md << "The " << in.pass << " estimate over " << format("%.1f", span) << " s of " << in.source
     << ". Each value's sigma is one standard deviation; \"change / sigma\" is the largest "
        "change from the initial guess along one axis over that axis's sigma.\n\n";
  std::vector<Row> rows;
  for (std::size_t c = 0; c < est.cameras.size() && c < init.cameras.size(); ++c) {
    cameraRows(init.cameras[c], est.cameras[c], &rows);
  }
  for (std::size_t i = 0; i < est.inertial.size() && i < init.inertial.size(); ++i) {
    inertialRows(init.inertial[i], est.inertial[i], i == 0, &rows);
  }
  md << "## Calibration\n\n| sensor | quantity | estimate | sigma | change | change / sigma |\n"
        "| --- | --- | --- | --- | --- | --- |\n";
  for (const Row& r : rows) {
    md << "| " << r.sensor << " | " << r.quantity << " | " << r.estimate << " | " << r.sigma
       << " | " << r.change << " | " << sigmas(r.change_sigma) << " |\n";
  }
  md << "\nA sigma of 0 or nan: the quantity was held (below) or no covariance was computed. The "
        "sigmas are scaled by how much the calibration moved on this data (x"
     << format("%.2f", in.sigma_inflation) << " overall).\n\n";

  md << "## Residuals\n\n";
  md << "Corner errors |projected - detected| at the estimate (online: each window state's at its "
        "last solve), before the robust loss; chi2 per residual is the whitened squares' mean, "
        "about 1 when the noise model (pixel_sigma "
     << format("%.2f", in.options.pixel_sigma_px)
     << " px, the IMUs' noise densities) fits.\n\n"
        "| sensor | kind | factors | corners | RMS [px] | median [px] | max [px] | chi2 / "
        "residual |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const auto& s : in.residuals.sensors) {
    const bool cam = s.kind == "camera";
    md << "| " << s.sensor << " | " << s.kind << " | " << s.factors << " | "
       << (cam ? std::to_string(s.corners) : "-") << " | "
       << (cam ? format("%.3f", s.cornerRms()) : "-") << " | "
       << (cam ? format("%.2f", s.cornerMedian()) : "-") << " | "
       << (cam ? format("%.2f", s.corner_max) : "-") << " | "
       << format("%.2f", s.chiSquarePerResidual()) << " |\n";
  }

  md << "\n## Held\n\n";
  const std::vector<std::string> held = heldByConfiguration(in.options, init);
  for (const auto& h : held) md << "- " << h << "\n";
  for (const auto& u : in.unobservable) md << "- " << u << " (the motion could not tell it)\n";
  if (held.empty() && in.unobservable.empty()) md << "Nothing.\n";

  if (!in.statuses.empty()) {
    md << "\n## Status\n\n";
    double ready_at = -1.0;
    bool ready = false;
    for (const auto& [t, s] : in.status_timeline) {
      if (s.sensor != "rig") continue;
      ready = s.ready;
      if (ready) ready_at = t;
    }
    if (ready) {
      md << "The rig became ready (every estimated quantity converged) at "
         << format("%.1f", ready_at) << " s and stayed so.\n\n";
    } else {
      md << "The rig was not ready at the end: the quantities below marked improving or "
            "unobservable need more data, the advice says what motion.\n\n";
    }
    md << "| sensor | quantity | status | sigma | target | advice |\n"
          "| --- | --- | --- | --- | --- | --- |\n";
    for (const QuantityState& s : in.statuses) {
      const std::string unit = s.unit.empty() ? "" : " " + s.unit;
      md << "| " << s.sensor << " | " << s.quantity << " | " << s.statusText() << " | "
         << (std::isnan(s.sigma) ? "-" : format("%.3g", s.sigma) + unit) << " | "
         << format("%.3g", s.target) << unit << " | " << s.advice << " |\n";
    }
    for (const CameraCoverage& c : in.coverage) {
      md << "\n"
         << c.camera << "'s image coverage (corners per cell, " << c.columns << " x " << c.rows
         << " cells; " << format("%.0f", 100.0 * c.share()) << "% covered"
         << (c.missing().empty() ? "" : "; missing: " + c.missing()) << "):\n\n```\n";
      for (int r = 0; r < c.rows; ++r) {
        for (int k = 0; k < c.columns; ++k) {
          md << format("%6.0f", c.corners[static_cast<std::size_t>(r * c.columns + k)]);
        }
        md << "\n";
      }
      md << "```\n";
    }
    md << "\nTimeline (every change of status; the full table in "
          "[calibration_status.csv](calibration_status.csv)):\n\n";
    int lines = 0;
    for (const auto& [t, s] : in.status_timeline) {
      if (s.sensor != "rig" && ++lines > 40) continue;
      md << "- " << format("%.1f", t) << " s: " << s.sensor << " " << s.quantity << " "
         << s.statusText() << (s.advice.empty() ? "" : " (" + s.advice + ")") << "\n";
    }
    if (lines > 40) md << "- ... " << lines - 40 << " more in calibration_status.csv\n";
  }

  md << "\n## Changes of a sensor's calibration\n\n";
  if (in.changes.empty()) md << "None declared.\n";
  for (std::size_t i = 0; i < in.changes.size(); ++i) {
    if (i > 0 && in.changes[i].text == in.changes[i - 1].text) continue;
    md << "- " << format("%.2f", toSeconds(in.changes[i].stamp_ns - in.first_ns))
       << " s: " << in.changes[i].text << "\n";
  }

  md << "\n## Warnings\n\n";
  const EstimatorCounters& c = in.counters;
  std::vector<std::string> warnings = in.warnings;
  const auto count = [&warnings](long n, const std::string& what) {
    if (n > 0) warnings.push_back(std::to_string(n) + " " + what);
  };
  count(c.restarts, "restarts from the trusted calibration");
  count(c.failures, "failures found by the checks after a solve");
  count(c.frames_rejected, "frames dropped far from where the estimate put them");
  count(c.corners_rejected, "single corners dropped");
  count(c.inconsistencies, "intrinsics inconsistencies (moved beyond their covariance)");
  count(c.held_intrinsics_misfits, "held gravity sensitivities refuted by the data");
  count(c.frames_too_few_tags, "frames with too few tags (min_tags)");
  count(c.imu_gaps, "holes in the base IMU's readings");
  if (warnings.empty()) md << "None.\n";
  for (const auto& w : warnings) md << "- " << w << "\n";

  md << "\n## Provenance\n\n";
  md << "- mvis " << MVIS_VERSION << ", " << in.tool << "\n";
  if (!in.written.empty()) md << "- written " << in.written << "\n";
  md << "- data: " << in.source << "; states from " << format("%.3f", toSeconds(in.first_ns))
     << " to " << format("%.3f", toSeconds(in.last_ns)) << " s (base clock)\n";
  md << "- pass: " << in.pass << "\n";
  const EstimatorOptions& o = in.options;
  md << "- options: window_size " << o.window_size << ", solve_every " << o.solve_every
     << ", pixel_sigma " << format("%g", o.pixel_sigma_px) << ", huber_sigma "
     << format("%g", o.huber_sigma) << ", robust_loss "
     << (o.robust_loss == RobustLoss::kCorner ? "corner" : "frame") << ", min_tags " << o.min_tags
     << ", estimate_extrinsics " << o.estimate_extrinsics << ", estimate_time_offsets "
     << o.estimate_time_offsets << ", estimate_intrinsics " << o.estimate_intrinsics
     << ", estimate_imu_intrinsics " << o.estimate_imu_intrinsics
     << ", estimate_gravity_sensitivity " << o.estimate_gravity_sensitivity
     << ", failure_step_sigma " << format("%g", o.failure_step_sigma) << ", frame_gate_sigma "
     << format("%g", o.frame_gate_sigma) << ", detect_changes " << o.detect_changes
     << ", observability_ratio " << format("%g", o.observability_ratio);
  for (const auto& [k, v] : in.extra_options) md << ", " << k << " " << v;
  md << "\n\n## Files\n\n"
        "- [kalibr_imucam_chain.yaml](kalibr_imucam_chain.yaml), "
        "[kalibr_imu_chain.yaml](kalibr_imu_chain.yaml): the calibration with *_std keys (feed "
        "them back as the next initial guess)\n"
        "- [calibration.csv](calibration.csv): the calibration after every solve; "
        "[pose_covariance.csv](pose_covariance.csv), [trajectory.tum](trajectory.tum)\n"
        "- [calibration_changes.csv](calibration_changes.csv)\n"
        "- Plots: `rosrun mvis evaluate <this directory>` draws the calibration over time with "
        "its 3-sigma bounds (and, after a batch, the residuals) into evaluation/ and links them "
        "below.\n";
  return md.str();
}

Status writeReport(const std::string& dir, const ReportInputs& in) {
  if (in.initial == nullptr || in.estimate == nullptr) {
    return Status::Error("report: no calibration to report");
  }
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);  // if that fails, opening the file says so
  const std::string path = dir + "/report.md";
  std::ofstream out(path);
  out << renderReport(in);
  if (!out) return Status::Error("cannot write " + path);
  return Status::Ok();
}

}  // namespace mvis
