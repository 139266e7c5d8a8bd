#include "mvis/estimator/calibration_status.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mvis/common/lie.h"

namespace mvis {
namespace {

constexpr double kDeg = 180.0 / M_PI;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// How far past its target a converged quantity may go before it counts as improving again.
constexpr double kHysteresis = 1.5;

bool holds(const std::vector<std::string>& hold, const std::string& sensor, const char* what) {
  return std::find(hold.begin(), hold.end(), sensor + "." + what) != hold.end();
}

// "x", "y" or "z": the axis of v's largest component.
const char* axisName(int i) { return i == 0 ? "x" : i == 1 ? "y" : "z"; }

// The two axes other than `i`, in words.
std::string otherAxes(int i) {
  return std::string(axisName((i + 1) % 3)) + " and " + axisName((i + 2) % 3);
}

Eigen::VectorXd stack(std::initializer_list<Eigen::VectorXd> parts) {
  Eigen::Index n = 0;
  for (const auto& p : parts) n += p.size();
  Eigen::VectorXd out(n);
  n = 0;
  for (const auto& p : parts) {
    out.segment(n, p.size()) = p;
    n += p.size();
  }
  return out;
}

Eigen::VectorXd flat(const Eigen::Matrix3d& m) {
  return Eigen::Map<const Eigen::VectorXd>(m.data(), 9);
}

// What the quantity is, its value and per-axis sigma in its unit; rotations are kept as
// quaternion coefficients in `value` (`rotation` true) and compared on the manifold.
struct Reading {
  Eigen::VectorXd value, sigma;
  bool rotation = false;
  bool has_sigma = false;
};

Reading readCamera(const Camera& c, const std::string& quantity) {
  Reading r;
  const bool std = c.std.has_value();
  const CameraCalibrationStd s = c.std.value_or(CameraCalibrationStd());
  if (quantity == "rotation") {
    r.value = c.T_cam_imu.q.coeffs();
    r.sigma = kDeg * s.rotation;
    r.rotation = true;
  } else if (quantity == "translation") {
    r.value = 1e3 * c.T_cam_imu.p;
    r.sigma = 1e3 * s.translation;
  } else if (quantity == "time_offset") {
    r.value = Eigen::VectorXd::Constant(1, 1e3 * c.timeshift_cam_imu);
    r.sigma = Eigen::VectorXd::Constant(1, 1e3 * s.timeshift_cam_imu);
  } else if (quantity == "intrinsics") {
    r.value = c.intrinsics;
    r.sigma = s.intrinsics;
  } else {  // distortion
    r.value = c.distortion_coeffs;
    r.sigma = s.distortion_coeffs;
  }
  r.has_sigma = std && r.sigma.allFinite() && r.sigma.maxCoeff() > 0.0;
  return r;
}

Reading readInertial(const InertialSensor& i, const std::string& quantity) {
  Reading r;
  const InertialCalibrationStd s = i.std.value_or(InertialCalibrationStd());
  if (quantity == "rotation") {
    r.value = i.T_i_b.q.coeffs();
    r.sigma = kDeg * s.rotation;
    r.rotation = true;
  } else if (quantity == "translation") {
    r.value = 1e3 * i.T_i_b.p;
    r.sigma = 1e3 * s.translation;
  } else if (quantity == "time_offset") {
    r.value = Eigen::VectorXd::Constant(1, 1e3 * i.time_offset);
    r.sigma = Eigen::VectorXd::Constant(1, 1e3 * s.time_offset);
  } else if (quantity == "intrinsics") {
    const Eigen::Vector3d& rot = i.model == ImuModel::kKalibr ? s.R_IMUtoGYRO : s.R_IMUtoACC;
    r.value = stack({flat(i.intrinsics.Tw), flat(i.intrinsics.Ta), Eigen::Vector3d::Zero()});
    r.sigma = stack({flat(s.Tw), flat(s.Ta), rot});
  } else {  // gravity_sensitivity
    r.value = flat(i.intrinsics.Tg);
    r.sigma = flat(s.Tg);
  }
  r.has_sigma = i.std.has_value() && r.sigma.allFinite() && r.sigma.maxCoeff() > 0.0;
  return r;
}

// The quantity words the observability check uses, as status quantities.
std::string statusQuantity(const std::string& unobservable_quantity) {
  if (unobservable_quantity == "rotation") return "rotation";
  if (unobservable_quantity == "translation") return "translation";
  if (unobservable_quantity == "time offset") return "time_offset";
  if (unobservable_quantity == "gravity sensitivity") return "gravity_sensitivity";
  return "intrinsics";
}

}  // namespace

const char* toString(QuantityStatus status) {
  switch (status) {
    case QuantityStatus::kConverged:
      return "converged";
    case QuantityStatus::kUnobservable:
      return "unobservable";
    case QuantityStatus::kHeld:
      return "held";
    case QuantityStatus::kImproving:
      break;
  }
  return "improving";
}

std::string QuantityState::statusText() const {
  if (sensor == "rig") return ready ? "ready" : "improving";
  return toString(status);
}

bool CameraCoverage::covered(int column, int row) const {
  return corners[static_cast<std::size_t>(row * columns + column)] >=
         CalibrationStatusTracker::kCornersPerCell;
}

double CameraCoverage::share() const {
  int n = 0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) n += covered(c, r) ? 1 : 0;
  }
  return columns * rows > 0 ? static_cast<double>(n) / (columns * rows) : 0.0;
}

std::string CameraCoverage::missing() const {
  const int last_c = columns - 1, last_r = rows - 1;
  // The image's corners first: they decide the distortion.
  const struct {
    int c, r;
    const char* words;
  } corners[] = {{0, 0, "the image's upper-left corner"},
                 {last_c, 0, "the image's upper-right corner"},
                 {0, last_r, "the image's lower-left corner"},
                 {last_c, last_r, "the image's lower-right corner"}};
  for (const auto& k : corners) {
    if (!covered(k.c, k.r)) return k.words;
  }
  // Then the border with the most cells uncovered, then the inside.
  int left = 0, right = 0, top = 0, bottom = 0, inside = 0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      if (covered(c, r)) continue;
      if (c == 0) ++left;
      if (c == last_c) ++right;
      if (r == 0) ++top;
      if (r == last_r) ++bottom;
      if (c > 0 && c < last_c && r > 0 && r < last_r) ++inside;
    }
  }
  const int most = std::max({left, right, top, bottom});
  if (most == 0) return inside > 0 ? "the image's middle" : "";
  if (left == most) return "the image's left border";
  if (right == most) return "the image's right border";
  if (top == most) return "the image's upper border";
  return "the image's lower border";
}

CalibrationStatusTracker::CalibrationStatusTracker(const Rig& rig, const EstimatorOptions& options,
                                                   StatusTargets targets)
    : rig_(rig), options_(options), targets_(targets) {
  const auto& hold = options.hold;
  const auto add = [this](const std::string& sensor, const std::string& quantity, bool held,
                          double target, const char* unit) {
    QuantityState s;
    s.sensor = sensor;
    s.quantity = quantity;
    s.status = held ? QuantityStatus::kHeld : QuantityStatus::kImproving;
    s.sigma = kNaN;
    s.target = target;
    s.unit = unit;
    states_.push_back(s);
  };
  for (const Camera& c : rig.cameras) {
    const bool extrinsic = !options.estimate_extrinsics || holds(hold, c.name, "extrinsic");
    add(c.name, "rotation", extrinsic, targets.rotation_deg, "deg");
    add(c.name, "translation", extrinsic, targets.camera_translation_mm, "mm");
    add(c.name, "time_offset", !options.estimate_time_offsets || holds(hold, c.name, "time_offset"),
        targets.time_offset_ms, "ms");
    if (options.estimate_intrinsics) {
      const bool held = holds(hold, c.name, "intrinsics");
      add(c.name, "intrinsics", held, targets.camera_intrinsics_px, "px");
      add(c.name, "distortion", held, targets.camera_distortion, "");
    }
    CameraCoverage coverage;
    coverage.camera = c.name;
    coverage.columns = kCoverageColumns;
    coverage.rows = kCoverageRows;
    coverage.corners.assign(kCoverageColumns * kCoverageRows, 0);
    coverage_.push_back(coverage);
  }
  for (std::size_t k = 0; k < rig.inertial.size(); ++k) {
    const InertialSensor& s = rig.inertial[k];
    if (k > 0) {
      const bool extrinsic = !options.estimate_aux_extrinsics || holds(hold, s.name, "extrinsic");
      add(s.name, "rotation", extrinsic, targets.rotation_deg, "deg");
      if (s.type != InertialType::kGyroscope) {
        add(s.name, "translation", extrinsic, targets.imu_translation_mm, "mm");
      }
      add(s.name, "time_offset",
          !options.estimate_aux_time_offsets || holds(hold, s.name, "time_offset"),
          targets.time_offset_ms, "ms");
    }
    if (s.model != ImuModel::kCalibrated && options.estimate_imu_intrinsics) {
      add(s.name, "intrinsics", holds(hold, s.name, "intrinsics"), targets.imu_intrinsics, "");
      if (options.estimate_gravity_sensitivity) {
        add(s.name, "gravity_sensitivity", holds(hold, s.name, "gravity_sensitivity"),
            targets.gravity_sensitivity, "rad/s per m/s^2");
      }
    }
  }
}

void CalibrationStatusTracker::addFrame(const TagFrame& frame) {
  if (frame.camera >= rig_.cameras.size()) return;
  const auto& resolution = rig_.cameras[frame.camera].resolution;
  const double width = frame.width > 0 ? frame.width : resolution[0];
  const double height = frame.height > 0 ? frame.height : resolution[1];
  if (!(width > 0.0) || !(height > 0.0)) return;
  CameraCoverage& c = coverage_[frame.camera];
  for (const TagObservation& tag : frame.tags) {
    for (const Eigen::Vector2d& uv : tag.corners_px) {
      const int col = static_cast<int>(std::floor((uv.x() + 0.5) / width * c.columns));
      const int row = static_cast<int>(std::floor((uv.y() + 0.5) / height * c.rows));
      if (col < 0 || col >= c.columns || row < 0 || row >= c.rows) continue;
      ++c.corners[static_cast<std::size_t>(row * c.columns + col)];
    }
  }
}

void CalibrationStatusTracker::evaluate(QuantityState* s, const Rig& calibration, TimeNs t,
                                        const std::vector<UnobservableCalibration>& unobservable) {
  if (s->status == QuantityStatus::kHeld) return;
  int camera = -1;
  Reading r;
  for (std::size_t c = 0; c < calibration.cameras.size(); ++c) {
    if (calibration.cameras[c].name == s->sensor) {
      camera = static_cast<int>(c);
      r = readCamera(calibration.cameras[c], s->quantity);
    }
  }
  for (const InertialSensor& i : calibration.inertial) {
    if (i.name == s->sensor) r = readInertial(i, s->quantity);
  }
  s->sigma = r.has_sigma ? r.sigma.maxCoeff() : kNaN;
  s->advice.clear();
  for (const UnobservableCalibration& d : unobservable) {
    if (d.sensor == s->sensor && statusQuantity(d.quantity) == s->quantity) {
      s->status = QuantityStatus::kUnobservable;
      s->advice = d.text();
      return;
    }
  }
  // The estimate's movement over the last settle_s, in its sigmas.
  History& h = history_[s->sensor + "." + s->quantity];
  h.values.emplace_back(t, r.value);
  const TimeNs span = static_cast<TimeNs>(targets_.settle_s * 1e9);
  while (h.values.size() > 2 && h.values[1].first <= t - span) h.values.pop_front();
  const bool long_enough = h.values.front().first <= t - span;
  double moved = 0.0;
  if (r.has_sigma) {
    for (const auto& [when, value] : h.values) {
      Eigen::VectorXd step;
      if (r.rotation) {
        const Eigen::Quaterniond then(value[3], value[0], value[1], value[2]);
        const Eigen::Quaterniond now(r.value[3], r.value[0], r.value[1], r.value[2]);
        step = kDeg * lie::logQuat(then.conjugate() * now);
      } else {
        step = r.value - value;
      }
      for (Eigen::Index k = 0; k < step.size() && k < r.sigma.size(); ++k) {
        if (r.sigma[k] > 0.0) moved = std::max(moved, std::abs(step[k]) / r.sigma[k]);
      }
    }
  }
  bool coverage_ok = true;
  if (camera >= 0 && (s->quantity == "intrinsics" || s->quantity == "distortion")) {
    const CameraCoverage& c = coverage_[camera];
    coverage_ok = c.share() >= kCoverageShare && c.covered(0, 0) && c.covered(c.columns - 1, 0) &&
                  c.covered(0, c.rows - 1) && c.covered(c.columns - 1, c.rows - 1);
  }
  const bool settled = long_enough && moved <= targets_.settle_sigmas;
  if (r.has_sigma && s->sigma <= s->target && settled && coverage_ok) {
    s->status = QuantityStatus::kConverged;
    return;
  }
  // Once converged it stays so within a margin (hysteresis): the reported sigmas breathe with
  // the measured inflation, and a quantity at its target would otherwise flip with them. A
  // declared change (its prior reset) or a jump leaves the margin at once.
  if (s->status == QuantityStatus::kConverged && r.has_sigma &&
      s->sigma <= kHysteresis * s->target && moved <= kHysteresis * targets_.settle_sigmas &&
      coverage_ok) {
    return;
  }
  s->status = QuantityStatus::kImproving;
  // Advice: what is missing first.
  if (!coverage_ok) {
    s->advice = "bring the board to " + coverage_[camera].missing() + " of " + s->sensor;
    return;
  }
  if (!r.has_sigma) {
    s->advice = "";  // no covariance yet
    return;
  }
  if (s->sigma <= s->target) {
    s->advice = "keep moving as before: the estimate still moves";
    return;
  }
  Eigen::Index weakest = 0;
  r.sigma.maxCoeff(&weakest);
  const std::string base = rig_.inertial[0].name;
  if (s->quantity == "rotation" || s->quantity == "translation") {
    const int axis = static_cast<int>(weakest % 3);
    s->advice = "rotate about " + base + "'s " + otherAxes(axis) + " axes (weakest along " +
                axisName(axis) + ")";
  } else if (s->quantity == "time_offset") {
    s->advice = "turn and stop briskly: vary the rate of rotation";
  } else if (camera >= 0) {
    s->advice = "move closer and farther, and tilt the board towards " + s->sensor;
  } else if (s->quantity == "gravity_sensitivity") {
    s->advice = "rotate " + s->sensor + " while holding it in different orientations to gravity";
  } else {
    s->advice = "vary the rate of rotation about each of " + s->sensor +
                "'s axes and turn it through every orientation to gravity";
  }
}

std::vector<QuantityState> CalibrationStatusTracker::update(
    TimeNs stamp_ns, const Rig& calibration,
    const std::vector<UnobservableCalibration>& unobservable) {
  std::vector<QuantityState> changed;
  bool ready = !states_.empty();
  for (QuantityState& s : states_) {
    const QuantityStatus before = s.status;
    evaluate(&s, calibration, stamp_ns, unobservable);
    if (!any_update_ || s.status != before) changed.push_back(s);
    if (s.status == QuantityStatus::kImproving || s.status == QuantityStatus::kUnobservable) {
      ready = false;
    }
  }
  if (!any_update_ || ready != ready_) {
    QuantityState rig;
    rig.sensor = "rig";
    rig.quantity = "all";
    rig.ready = ready;
    rig.status = ready ? QuantityStatus::kConverged : QuantityStatus::kImproving;
    rig.sigma = kNaN;
    rig.target = kNaN;
    changed.push_back(rig);
    ready_since_ = ready ? stamp_ns : 0;
  }
  ready_ = ready;
  any_update_ = true;
  return changed;
}

}  // namespace mvis
