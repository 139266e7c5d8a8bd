// Degenerate-motion awareness (report Sec. 5.1, Table 2; observability.h): which calibration
// directions the recent motion leaves unobservable, checked before every solve, and holding them.
#include <Eigen/QR>
#include <cstdio>

#include "estimator_impl.h"
#include "mvis/estimator/observability.h"

namespace mvis {

std::string UnobservableCalibration::text() const {
  std::ostringstream s;
  s << sensor << ' ' << quantity;
  if (directions_I.empty()) {
    s << ": vary the rig's rate of rotation";  // only gyroscope time offsets are checked
  } else if (directions_I.size() == 1) {
    char d[64];
    std::snprintf(d, sizeof d, "(%.2f, %.2f, %.2f)", directions_I[0].x(), directions_I[0].y(),
                  directions_I[0].z());
    s << (quantity == "rotation" ? " about " : " along ") << d << " in " << base
      << ": rotate about another axis too";
  } else {
    s << ": rotate the rig about more than one axis";
  }
  return s.str();
}

namespace {

// One calibrated quantity: rows [offset, offset + size) of its block's tangent, and the
// information the recent motion gives it (tangent coordinates).
struct Quantity {
  std::string sensor, name;
  double* block;
  int offset, size;
  Eigen::VectorXd prior_std;
  Eigen::Matrix3d to_I;  // tangent coordinates to the base IMU frame
  Eigen::MatrixXd information;
};

}  // namespace

void Estimator::Impl::addMotionInformation(TimeNs a, TimeNs b, const Eigen::Vector3d& bias_gyro) {
  // Chunks of about 25 ms: their mean rates, and angular accelerations between them. The
  // gyroscope's noise makes each alpha noisy (variance s2 per axis), which would add 2 s2 I to
  // hat(alpha)^T hat(alpha) on average: it is taken out again, or noise alone would look like
  // rotation about every axis.
  const std::vector<ImuMeasurement> readings = imuBetween(a, b);
  constexpr double kChunk = 0.025;
  const double density = rig.inertial[0].noise.gyroscope_noise_density;
  std::vector<std::pair<double, Eigen::Vector3d>> chunks;  // (mid time [s], mean rate)
  double t0 = toSeconds(readings.front().stamp_ns - a), sum_t = 0.0;
  Eigen::Vector3d sum_w = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& m : readings) {
    const double t = toSeconds(m.stamp_ns - a);
    if (n > 0 && t - t0 > kChunk) {
      chunks.emplace_back(sum_t / n, sum_w / n);
      t0 = t;
      sum_t = 0.0;
      sum_w.setZero();
      n = 0;
    }
    sum_t += t;
    sum_w += m.gyro - bias_gyro;
    ++n;
  }
  if (n > 0) chunks.emplace_back(sum_t / n, sum_w / n);
  MotionInformation info;
  info.t = b;
  for (std::size_t i = 0; i + 1 < chunks.size(); ++i) {
    const double dt = chunks[i + 1].first - chunks[i].first;
    if (!(dt > 0.0)) continue;
    const Eigen::Vector3d w = 0.5 * (chunks[i].second + chunks[i + 1].second);
    const Eigen::Vector3d alpha = (chunks[i + 1].second - chunks[i].second) / dt;
    const double s2 = 2.0 * density * density / (kChunk * dt * dt);
    const Eigen::Matrix3d Jp = lie::hat(alpha) + lie::hat(w) * lie::hat(w);
    info.translation += dt * (Jp.transpose() * Jp - 2.0 * s2 * Eigen::Matrix3d::Identity());
    info.rotation += dt * lie::hat(w).transpose() * lie::hat(w);
    info.time_offset += dt * std::max(alpha.squaredNorm() - 3.0 * s2, 0.0);
  }
  motion_information.push_back(info);
  const TimeNs horizon = fromSeconds(options.observability_horizon_s);
  while (!motion_information.empty() && motion_information.front().t < b - horizon) {
    motion_information.pop_front();
  }
}

void Estimator::Impl::checkObservability() {
  unobservable.clear();
  uninformative.clear();
  if (options.observability_ratio <= 0.0 || motion_information.empty()) {
    applyHolds();
    return;
  }
  // The recent motion's information (report Sec. 5.1, Table 2), per unit noise density.
  MotionInformation sum;
  for (const auto& m : motion_information) {
    sum.translation += m.translation;
    sum.rotation += m.rotation;
    sum.time_offset += m.time_offset;
  }
  std::vector<Quantity> quantities;
  // Translations (cameras and aux IMUs): the relative acceleration of two rigidly attached
  // points is (hat(alpha) + hat(w)^2) p, measured with the accelerometer's noise. Extrinsic
  // translations are p_X_I in {X}; the sensor's position in {I} is -R^T p.
  auto translation = [&](const std::string& name, double* block,
                         const estimator_internal::CalibrationPrior& prior, double density) {
    if (!estimated(block) || !(density > 0.0)) return;
    const Eigen::Matrix3d R_X_I = poseRotation(block).toRotationMatrix();
    quantities.push_back({name, "translation", block, 3, 3, prior.translation, R_X_I.transpose(),
                          R_X_I * sum.translation * R_X_I.transpose() / (density * density)});
  };
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    translation(rig.cameras[c].name, cameras[c]->extrinsic, cameras[c]->prior,
                rig.inertial[0].noise.accelerometer_noise_density);
  }
  for (auto& a : aux) {
    const std::string& name = rig.inertial[a->sensor].name;
    const ImuNoise& noise = rig.inertial[a->sensor].noise;
    if (!a->gyro) {
      translation(name, a->extrinsic, a->prior, noise.accelerometer_noise_density);
      continue;
    }
    // A gyroscope's rotation (right perturbation, {I}): w_G = R Exp(dtheta) w_I, so
    // d w_G / d dtheta = -R hat(w); its time offset: d w_G / d t = R alpha.
    const double density = noise.gyroscope_noise_density;
    if (!(density > 0.0)) continue;
    if (estimated(a->rotation)) {
      quantities.push_back({name, "rotation", a->rotation, 0, 3, a->prior.rotation,
                            Eigen::Matrix3d::Identity(), sum.rotation / (density * density)});
    }
    if (estimated(a->time_offset)) {
      quantities.push_back(
          {name, "time offset", a->time_offset, 0, 1,
           Eigen::VectorXd::Constant(1, a->prior.time_offset), Eigen::Matrix3d::Identity(),
           Eigen::MatrixXd::Constant(1, 1, sum.time_offset / (density * density))});
    }
  }

  for (const auto& q : quantities) {
    const Eigen::MatrixXd S = q.prior_std.asDiagonal();
    const WeakDirections weak =
        weakDirections(S * q.information * S, q.prior_std, options.observability_ratio);
    if (weak.directions.cols() == 0) continue;
    UnobservableCalibration u;
    u.sensor = q.sensor;
    u.base = rig.inertial[0].name;
    u.quantity = q.name;
    for (int c = 0; c < weak.directions.cols(); ++c) {
      u.information_ratio.push_back(std::max(weak.gains[c], 0.0));
      if (q.size != 3) continue;
      Eigen::Vector3d d = q.to_I * weak.directions.col(c);
      int largest = 0;
      d.cwiseAbs().maxCoeff(&largest);
      if (d[largest] < 0) d = -d;
      u.directions_I.push_back(d.normalized());
    }
    unobservable.push_back(std::move(u));
    // The block's tangent directions (disjoint rows per quantity, so the columns stay
    // orthonormal).
    const ceres::Manifold* own = baseManifold(q.block);
    const int tangent = own != nullptr ? own->TangentSize() : q.size;
    Eigen::MatrixXd& D = uninformative[q.block];
    const auto old = D.cols();
    D.conservativeResize(tangent, old + weak.directions.cols());
    D.rightCols(weak.directions.cols()).setZero();
    D.block(q.offset, old, q.size, weak.directions.cols()) = weak.directions;
  }
  applyHolds();
}

Eigen::VectorXd Estimator::Impl::latestStd(const double* block) const {
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const CameraBlocks& cb = *cameras[c];
    const bool have = camera_std.has_value();
    if (block == cb.extrinsic) {
      Vector6d sd;
      sd << cb.prior.rotation, cb.prior.translation;
      if (have && (*camera_std)[c].rotation.allFinite() && (*camera_std)[c].rotation.norm() > 0) {
        sd << (*camera_std)[c].rotation, (*camera_std)[c].translation;
      }
      return sd;
    }
    if (block == cb.time_offset) {
      const double v = have ? (*camera_std)[c].timeshift_cam_imu : 0.0;
      return Eigen::VectorXd::Constant(1, v > 0 ? v : cb.prior.time_offset);
    }
  }
  for (const auto& a : aux) {
    const bool have = a->std.has_value();
    if (block == a->time_offset) {
      const double v = have ? a->std->time_offset : 0.0;
      return Eigen::VectorXd::Constant(1, v > 0 ? v : a->prior.time_offset);
    }
    if (block == a->rotation && a->gyro) {
      return have && a->std->rotation.norm() > 0 ? Eigen::VectorXd(a->std->rotation)
                                                 : Eigen::VectorXd(a->prior.rotation);
    }
    if (block == a->extrinsic && !a->gyro) {
      Vector6d sd;
      sd << a->prior.rotation, a->prior.translation;
      if (have && a->std->rotation.norm() > 0) sd << a->std->rotation, a->std->translation;
      return sd;
    }
  }
  return Eigen::VectorXd();
}

void Estimator::Impl::applyHolds() {
  // Release what is observable again.
  for (auto it = holds.begin(); it != holds.end();) {
    double* block = const_cast<double*>(it->first);
    if (uninformative.count(block)) {
      ++it;
      continue;
    }
    if (it->second.subspace) {
      problem->SetManifold(block, it->second.base);
    } else {
      problem->SetParameterBlockVariable(block);
    }
    it = holds.erase(it);
  }
  for (const auto& [const_block, D] : uninformative) {
    double* block = const_cast<double*>(const_block);
    auto existing = holds.find(block);
    if (existing != holds.end() && existing->second.directions.cols() == D.cols() &&
        (existing->second.directions - D).norm() < 1e-9) {
      continue;  // held as it is
    }
    Hold hold;
    hold.base = existing != holds.end() ? existing->second.base
                                        : const_cast<ceres::Manifold*>(problem->GetManifold(block));
    hold.directions = D;
    const Eigen::VectorXd sd = latestStd(block);
    hold.variance.resize(D.cols());
    for (int c = 0; c < D.cols(); ++c) {
      hold.variance[c] = D.col(c).cwiseAbs2().dot(sd.cwiseAbs2());
    }
    const int tangent = static_cast<int>(D.rows());
    const bool was_constant = existing != holds.end() && !existing->second.subspace;
    if (D.cols() >= tangent) {
      if (existing != holds.end() && existing->second.subspace) {
        problem->SetManifold(block, hold.base);
      }
      problem->SetParameterBlockConstant(block);
    } else {
      // The free directions: the orthogonal complement of D.
      const Eigen::HouseholderQR<Eigen::MatrixXd> qr(D);
      const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(tangent, tangent);
      const int ambient = problem->ParameterBlockSize(block);
      hold.subspace =
          std::make_unique<SubspaceManifold>(hold.base, ambient, Q.rightCols(tangent - D.cols()));
      if (was_constant) problem->SetParameterBlockVariable(block);
      problem->SetManifold(block, hold.subspace.get());
    }
    holds[block] = std::move(hold);  // the replaced manifold is no longer in use
  }
}

Eigen::MatrixXd Estimator::Impl::tangentCovariance(const ceres::Covariance& cov,
                                                   const double* block) const {
  const int t = problem->ParameterBlockTangentSize(block);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> C(t, t);
  cov.GetCovarianceBlockInTangentSpace(block, block, C.data());
  const auto h = holds.find(block);
  if (h == holds.end() || !h->second.subspace) return C;
  const Hold& hold = h->second;
  const Eigen::MatrixXd& B = hold.subspace->basis();
  return B * C * B.transpose() +
         hold.directions * hold.variance.asDiagonal() * hold.directions.transpose();
}

}  // namespace mvis
