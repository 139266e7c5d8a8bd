#include "estimator_impl.h"

namespace mvis {

void Estimator::Impl::addRecord(State* owner, ceres::CostFunction* cost, ceres::LossFunction* loss,
                                std::vector<double*> blocks) {
  ResidualRecord r;
  r.id = problem->AddResidualBlock(cost, loss, blocks);
  r.cost = cost;
  r.loss = loss;
  r.blocks = std::move(blocks);
  owner->residuals.push_back(std::move(r));
}

void Estimator::Impl::addStateBlocks(State* s) {
  problem->AddParameterBlock(s->pose, kPoseSize, &pose_manifold);
  problem->AddParameterBlock(s->speed_bias, kSpeedBiasSize);
}

void Estimator::Impl::addCalibrationBlocks() {
  problem->AddParameterBlock(gravity, kGravitySize, &sphere_manifold);
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    CameraBlocks& b = *cameras[c];
    problem->AddParameterBlock(b.extrinsic, kPoseSize, &pose_manifold);
    problem->AddParameterBlock(b.time_offset, 1);
    problem->AddParameterBlock(b.intrinsics, kIntrinsicsSize);
    const std::string& name = rig.cameras[c].name;
    const bool intrinsics = options.estimate_intrinsics && !heldByOption(name, "intrinsics");
    if (!options.estimate_extrinsics || heldByOption(name, "extrinsic")) {
      problem->SetParameterBlockConstant(b.extrinsic);
    }
    if (!options.estimate_time_offsets || heldByOption(name, "time_offset")) {
      problem->SetParameterBlockConstant(b.time_offset);
    }
    if (!intrinsics) problem->SetParameterBlockConstant(b.intrinsics);
    // Priors from the configuration's *_std keys, or the options' defaults.
    const auto& sd = rig.cameras[c].std;
    b.prior = estimator_internal::calibrationPrior(
        options.extrinsic_rotation_prior_rad, options.extrinsic_translation_prior_m,
        options.time_offset_prior_s, sd ? &sd->rotation : nullptr, sd ? &sd->translation : nullptr,
        sd ? sd->timeshift_cam_imu : 0.0);
    const estimator_internal::CalibrationPrior& prior = b.prior;
    problem->AddResidualBlock(
        PosePriorFactor::fromStd(poseToSE3(b.extrinsic), prior.rotation, prior.translation),
        nullptr, b.extrinsic);
    problem->AddResidualBlock(
        new ceres::NormalPrior(Eigen::Matrix<double, 1, 1>(1.0 / prior.time_offset),
                               Eigen::Matrix<double, 1, 1>(b.time_offset[0])),
        nullptr, b.time_offset);
    // Intrinsics: the configuration's *_std keys where they are positive, else the defaults.
    for (int i = 0; i < kIntrinsicsSize; ++i) {
      const double fallback = i < 2   ? options.intrinsics_focal_prior_px
                              : i < 4 ? options.intrinsics_centre_prior_px
                                      : options.distortion_prior;
      const double given = !sd ? 0.0 : i < 4 ? sd->intrinsics[i] : sd->distortion_coeffs[i - 4];
      b.intrinsics_prior[i] = given > 0.0 ? given : fallback;
    }
    if (intrinsics) {
      using Vector8d = Eigen::Matrix<double, kIntrinsicsSize, 1>;
      problem->AddResidualBlock(
          new ceres::NormalPrior(Eigen::MatrixXd(b.intrinsics_prior.cwiseInverse().asDiagonal()),
                                 Vector8d(Eigen::Map<const Vector8d>(b.intrinsics))),
          nullptr, b.intrinsics);
    }
  }
  addAuxCalibrationBlocks();
  addImuIntrinsicsBlocks();
}

std::vector<Estimator::Impl::FramePiece> Estimator::Impl::frameFactors(const TagFrame& frame,
                                                                       std::size_t k, State** owner,
                                                                       int* corners) {
  const std::size_t c = frame.camera;
  CameraBlocks& cb = *cameras[c];
  // The frame's pose comes from the readings around it: inside a gap they are made up.
  if (insideImuGap(frame.stamp_ns + timeOffsetNs(c))) {
    ++counters.frames_in_imu_gap;
    return {};
  }
  // The corners in groups of one factor each, with their landmark block (null: board points).
  std::vector<std::pair<std::vector<CornerObservation>, double*>> groups;
  *corners = 0;
  if (landmarkMode()) {
    for (const auto& tag : frame.tags) {
      double* landmark = landmarkFor(frame, tag, k);
      if (landmark == nullptr) continue;
      std::vector<CornerObservation> obs;
      for (int i = 0; i < 4; ++i) obs.push_back({Eigen::Vector3d::Zero(), tag.corners_px[i], i});
      groups.emplace_back(std::move(obs), landmark);
      *corners += 4;
    }
  } else {
    auto obs = boardCorners(frame, *rig.target);
    *corners = static_cast<int>(obs.size());
    if (!obs.empty()) groups.emplace_back(std::move(obs), nullptr);
  }
  if (groups.empty()) return {};
  const DistortionModel model = rig.cameras[c].distortion_model;
  State* sk = states[k].get();
  *owner = sk;
  std::vector<double*> blocks;
  std::function<TagReprojectionFactor*(std::vector<CornerObservation>)> make;
  double* noise = nullptr;  // the frame's propagation-noise block, shared by its tags' factors
  ceres::CostFunction* noise_prior = nullptr;
  if (options.interpolation == FrameInterpolation::kImu) {
    const TimeNs t_a = std::max(sk->t, frame.stamp_ns + timeOffsetNs(c));
    // The readings at t_a for the last few milliseconds (the time offset's change): corrected by
    // the current intrinsics estimate when they are estimated (the raw bias states are then
    // subtracted from corrected readings: a few parts per thousand of a bias over milliseconds).
    const ImuMeasurement at = propagationReading(readingAt(t_a));
    const Eigen::Vector3d alpha = angularAcceleration(t_a);
    const double dt_nominal = toSeconds(frame.stamp_ns - t_a);
    TagReprojectionFactor::ImuAnchor anchor;
    blocks = {sk->pose, sk->speed_bias, gravity, cb.extrinsic, cb.time_offset, cb.intrinsics};
    // The readings' covariance over [t_k, t_a], [dtheta, dp, dv] (imu_preintegration.h).
    Eigen::Matrix<double, 9, 9> propagation_cov = Eigen::Matrix<double, 9, 9>::Zero();
    double* imu_in = imuIntrinsics(0);
    if (imu_in != nullptr && t_a - sk->t > kIntrinsicsAnchorSpanNs) {
      // Raw readings re-integrated at the state's biases and the current intrinsics, with the
      // intrinsics' Jacobian (tag_reprojection_factor.h).
      const ImuDeltas d =
          reintegrate(imuToIntegrate(sk->t, t_a),
                      deltaVariables(sk->speed_bias + 3, sk->speed_bias + 6, imu_in),
                      imu_intrinsics[0]->frame, true);
      anchor = TagReprojectionFactor::makeAnchor(d, true, dt_nominal, at.gyro, at.accel, alpha);
      blocks.push_back(imu_in);
      if (options.propagation_noise) {
        const Eigen::Vector3d bg(sk->speed_bias + 3), ba(sk->speed_bias + 6);
        propagation_cov =
            preintegrate(sk->t, t_a, bg, ba, true)->covariance().topLeftCorner<9, 9>();
      }
    } else {
      // Without intrinsics, or over so short a span (cam0's frames, at their state's time) that
      // they cannot matter: readings corrected by the current estimate, no intrinsics block
      // (the biases in corrected form, imu_correction.h; both identity without intrinsics).
      Eigen::Vector3d bg, ba;
      propagationBiases(Eigen::Vector3d(sk->speed_bias + 3), Eigen::Vector3d(sk->speed_bias + 6),
                        &bg, &ba);
      auto pre = preintegrate(sk->t, t_a, bg, ba, true);
      anchor = TagReprojectionFactor::makeAnchor(*pre, dt_nominal, at.gyro, at.accel, alpha);
      propagation_cov = pre->covariance().topLeftCorner<9, 9>();
    }
    if (options.propagation_noise && t_a - sk->t >= kPropagationNoiseSpanNs) {
      noise_prior = propagationNoisePrior(propagation_cov);
    }
    if (noise_prior != nullptr) {
      sk->propagation_noise.push_back(std::make_unique<double[]>(kPropagationNoiseSize));
      noise = sk->propagation_noise.back().get();
      std::fill(noise, noise + kPropagationNoiseSize, 0.0);
      blocks.push_back(noise);
    }
    make = [&, anchor](std::vector<CornerObservation> obs) {
      auto* f = TagReprojectionFactor::imuPropagated(model, std::move(obs), options.pixel_sigma_px,
                                                     anchor);
      if (noise != nullptr) f->usePropagationNoise();
      return f;
    };
  } else if (c == 0) {
    const double dt_nominal = toSeconds(frame.stamp_ns - sk->t);
    blocks = {sk->pose, sk->speed_bias, cb.extrinsic, cb.time_offset, cb.intrinsics};
    make = [&, dt_nominal](std::vector<CornerObservation> obs) {
      return TagReprojectionFactor::kinematic(model, std::move(obs), options.pixel_sigma_px,
                                              dt_nominal, sk->motion.gyro);
    };
  } else {
    State* sk1 = states[k + 1].get();
    blocks = {sk->pose, sk1->pose, cb.extrinsic, cb.time_offset, cb.intrinsics};
    make = [&, sk1](std::vector<CornerObservation> obs) {
      return TagReprojectionFactor::poseBased(model, std::move(obs), options.pixel_sigma_px,
                                              toSeconds(frame.stamp_ns - sk->t),
                                              toSeconds(sk1->t - sk->t));
    };
  }
  std::vector<FramePiece> out;
  // A frame's tag factors share its camera pose (without a board; with one it has one factor).
  const auto shared = landmarkMode() ? TagReprojectionFactor::makeSharedCameraPose() : nullptr;
  for (auto& [obs, landmark] : groups) {
    TagReprojectionFactor* factor = make(std::move(obs));
    ceres::LossFunction* loss = nullptr;
    // The first batch (before `initialized`) always has the loss per frame: its residuals are
    // mostly the rough initial calibration's, which a per-corner loss would take for outliers
    // (it left the batch's states tens of millimetres off), and plain squares would let a
    // wrong detection in it bias everything that follows.
    if (options.robust_loss == RobustLoss::kFrame || !initialized) {
      loss = landmark != nullptr ? tagLoss(static_cast<int>(groups.size())) : huber.get();
    } else if (options.huber_sigma > 0.0) {
      factor->useCornerLoss(options.huber_sigma);
    }
    FramePiece piece{factor, loss, blocks};
    if (landmark != nullptr) {
      factor->useLandmarkBlock();
      factor->shareCameraPose(shared);
      piece.blocks.push_back(landmark);
    }
    out.push_back(std::move(piece));
  }
  if (noise != nullptr) out.push_back({noise_prior, nullptr, {noise}});
  return out;
}

ceres::CostFunction* Estimator::Impl::propagationNoisePrior(
    const Eigen::Matrix<double, 9, 9>& covariance) {
  // A with A^T A = Sigma^-1, through the Jacobi-scaled S = D Sigma D (D = diag(Sigma)^-1/2: the
  // rotation's and position's variances differ by orders of magnitude): A = L^-1 D, S = L L^T.
  const Eigen::Matrix<double, 9, 1> d = covariance.diagonal();
  if (!(d.minCoeff() > 0.0) || !d.allFinite()) return nullptr;
  const Eigen::Matrix<double, 9, 1> D = d.cwiseSqrt().cwiseInverse();
  const Eigen::Matrix<double, 9, 9> S = D.asDiagonal() * covariance * D.asDiagonal();
  const Eigen::LLT<Eigen::Matrix<double, 9, 9>> llt(S);
  if (llt.info() != Eigen::Success) return nullptr;
  Eigen::Matrix<double, 9, 9> A = D.asDiagonal();
  llt.matrixL().solveInPlace(A);
  return new ceres::NormalPrior(A, Eigen::VectorXd::Zero(kPropagationNoiseSize));
}

Eigen::Vector3d Estimator::Impl::angularAcceleration(TimeNs t) const {
  const TimeNs half = fromSeconds(0.01);
  double st = 0.0, stt = 0.0;
  Eigen::Vector3d sw = Eigen::Vector3d::Zero(), stw = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& m : imu) {
    if (m.stamp_ns < t - half) continue;
    if (m.stamp_ns > t + half) break;
    const double x = toSeconds(m.stamp_ns - t);
    st += x;
    stt += x * x;
    sw += m.gyro;
    stw += x * m.gyro;
    ++n;
  }
  const double denominator = n * stt - st * st;
  if (n < 3 || denominator <= 0.0) return Eigen::Vector3d::Zero();
  return (n * stw - st * sw) / denominator;
}

void Estimator::Impl::addFrame(const TagFrame& frame, std::size_t k) {
  State* owner = nullptr;
  int corners = 0;
  auto pieces = frameFactors(frame, k, &owner, &corners);
  if (pieces.empty()) return;
  for (auto& piece : pieces) {
    addRecord(owner, piece.cost, piece.loss, std::move(piece.blocks));
  }
  owner->frames += 1;
  owner->corners += corners;
}

void Estimator::Impl::addImuFactor(std::size_t k, std::shared_ptr<const ImuPreintegration> pre) {
  State* a = states[k].get();
  State* b = states[k + 1].get();
  addReadingMoments(0, b->t, pre->samples());
  double* intrinsics = imuIntrinsics(0);
  if (intrinsics == nullptr) {
    addRecord(a, new ImuFactor(std::move(pre)), nullptr,
              {a->pose, a->speed_bias, b->pose, b->speed_bias, gravity});
    return;
  }
  addRecord(a,
            new ImuFactor(std::move(pre), imu_intrinsics[0]->frame,
                          options.imu_intrinsics_linearization, imu_intrinsics[0]->initial),
            nullptr, {a->pose, a->speed_bias, b->pose, b->speed_bias, gravity, intrinsics});
}

std::unique_ptr<State> Estimator::Impl::makeState(TimeNs t) const {
  auto s = std::make_unique<State>();
  s->t = t;
  const ImuMeasurement at = readingAt(t);
  s->motion.gyro = at.gyro;
  s->motion.accel = at.accel;
  s->motion.angular_acceleration = angularAcceleration(t);
  s->aux.resize(aux.size());
  return s;
}

void Estimator::Impl::addState(const TagFrame& frame, TimeNs t) {
  const State& last = *states.back();
  const Eigen::Vector3d bg(last.speed_bias + 3), ba(last.speed_bias + 6);
  auto pre = preintegrate(last.t, t, bg, ba);
  auto s = makeState(t);
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
  pre->predict(poseRotation(last.pose), posePosition(last.pose), Eigen::Vector3d(last.speed_bias),
               Eigen::Vector3d(gravity), &q, &p, &v);
  se3ToPose(SE3(q, p), s->pose);
  Eigen::Map<Eigen::Vector3d>(s->speed_bias) = v;
  std::copy(last.speed_bias + 3, last.speed_bias + 9, s->speed_bias + 3);
  states.push_back(std::move(s));
  addStateBlocks(states.back().get());
  addImuFactor(states.size() - 2, pre);
  addFrame(frame, states.size() - 1);
  addMotionInformation(last.t, t, bg);
}

void Estimator::Impl::attachOtherFrames() {
  if (states.size() < 2) return;
  for (std::size_t c = 1; c < other_frames.size(); ++c) {
    auto& q = other_frames[c];
    const TimeNs offset = timeOffsetNs(c);
    while (!q.empty()) {
      const TimeNs t = q.front().stamp_ns + offset;
      if (t < states.front()->t) {
        ++counters.frames_too_old;
        q.pop_front();
        continue;
      }
      if (t > states.back()->t) break;
      std::size_t k = 0;
      while (k + 2 < states.size() && states[k + 1]->t <= t) ++k;
      addFrame(q.front(), k);
      q.pop_front();
    }
  }
}

void Estimator::Impl::propagate(const ImuMeasurement& m) {
  if (!propagation_callback || !initialized || states.empty()) return;
  const State& newest = *states.back();
  if (m.stamp_ns <= newest.t) return;
  const Eigen::Vector3d bg(newest.speed_bias + 3), ba(newest.speed_bias + 6);
  if (!propagation || propagation_from != newest.t) {
    // With estimated intrinsics the readings are raw: corrected here by the current estimate.
    Eigen::Vector3d bg_c, ba_c;
    propagationBiases(bg, ba, &bg_c, &ba_c);
    propagation = preintegrate(newest.t, m.stamp_ns, bg_c, ba_c, true);
    propagation_from = newest.t;
  } else {
    propagation->add(propagationReading(m));
  }
  EstimatorState out;
  out.stamp_ns = m.stamp_ns;
  Eigen::Quaterniond q;
  Eigen::Vector3d p, v;
  propagation->predict(poseRotation(newest.pose), posePosition(newest.pose),
                       Eigen::Vector3d(newest.speed_bias), Eigen::Vector3d(gravity), &q, &p, &v);
  out.T_G_I = SE3(q, p);
  out.v_G = v;
  out.bias_gyro = bg;
  out.bias_accel = ba;
  propagation_callback(out);
}

SolveSummary Estimator::Impl::solve(int iterations, double max_time_s) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  o.max_num_iterations = iterations;
  o.max_solver_time_in_seconds = max_time_s > 0 ? max_time_s : options.max_solve_time_s;
  o.num_threads = options.threads;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary s;
  ceres::Solve(o, problem.get(), &s);
  refreshBaseCorrection();
  ++counters.solves;
  SolveSummary out = windowSummary();
  out.iterations = static_cast<int>(s.iterations.size());
  out.solve_s = s.total_time_in_seconds;
  out.cost = s.final_cost;
  out.usable = s.IsSolutionUsable();
  return out;
}

SolveSummary Estimator::Impl::windowSummary() const {
  SolveSummary out;
  out.states = static_cast<int>(states.size());
  for (const auto& st : states) {
    out.frames += st->frames;
    out.corners += st->corners;
  }
  return out;
}

void Estimator::Impl::marginalizeOldest() {
  State* oldest = states.front().get();
  Marginalizer m;
  for (const auto& r : oldest->residuals) {
    for (double* block : r.blocks) m.setManifold(block, baseManifold(block));
    // The measurements leaving add nothing along what they cannot observe; the old prior
    // keeps what earlier motion told.
    m.addResidual(r.cost, r.loss, r.blocks, true);
  }
  if (prior_whole) {
    for (double* block : prior_whole->parameterBlocks()) m.setManifold(block, baseManifold(block));
    m.addPrior(prior_whole.get());
  }
  for (const auto& [block, directions] : uninformative) m.setUninformative(block, directions);
  std::vector<double*> leaving = {oldest->pose, oldest->speed_bias};
  for (const auto& noise : oldest->propagation_noise) leaving.push_back(noise.get());
  const std::vector<double*> leaving_landmarks = leavingLandmarks(*oldest);
  leaving.insert(leaving.end(), leaving_landmarks.begin(), leaving_landmarks.end());
  for (std::size_t i = 0; i < aux.size(); ++i) {
    AuxState* as = oldest->aux[i].get();
    if (as == nullptr) continue;
    leaving.push_back(as->x);
    // The last estimate of the sensor's biases, for a chain that starts later.
    aux[i]->bias_gyro = Eigen::Vector3d(aux[i]->biasGyro(as));
    if (!aux[i]->gyro) aux[i]->bias_accel = Eigen::Vector3d(aux[i]->biasAccel(as));
  }
  auto made = m.marginalize(std::set<const double*>(leaving.begin(), leaving.end()));
  // Remove the old prior and the state (with every residual on it).
  for (const auto& r : prior) problem->RemoveResidualBlock(r.id);
  prior.clear();
  prior_whole.reset();
  // Residual blocks one by one in their recorded order: Ceres's own removal of a parameter
  // block's dependents walks a hash set, whose order (pointer values) would make results
  // differ from run to run in the last digits, and the window amplifies that.
  for (const auto& r : oldest->residuals) problem->RemoveResidualBlock(r.id);
  for (double* block : leaving) problem->RemoveParameterBlock(block);
  for (double* block : leaving_landmarks) removeLandmark(block);
  past.push_back(oldest->toEstimate());
  states.pop_front();
  if (!made.ok()) {
    status_text = "marginalization failed (" + made.status().message() + "); prior dropped";
    return;
  }
  // One residual block per row group: Ceres's J^T J of the dense prior is its largest cost
  // with many auxiliary sensors.
  for (auto& rows : made.value()->splitRows()) {
    ResidualRecord r;
    r.blocks = rows->parameterBlocks();
    r.cost = rows.get();
    r.id = problem->AddResidualBlock(rows.release(), nullptr, r.blocks);
    prior.push_back(std::move(r));
  }
  prior_whole = std::move(made).value();
}

void Estimator::Impl::publish(const SolveSummary& summary, Clock::time_point start) {
  ++solves_since_covariance;
  EstimatorUpdate u;
  u.solve = summary;
  u.state = states.back()->toEstimate();
  u.gravity_G = Eigen::Vector3d(gravity);
  u.unobservable = unobservable;
  u.pose_covariance.setConstant(std::numeric_limits<double>::quiet_NaN());
  if (options.covariance_every > 0 && solves_since_covariance >= options.covariance_every) {
    Eigen::Matrix<double, 6, 6> pose_cov;
    if (covariance(&pose_cov).ok()) {
      u.pose_covariance = pose_cov;
      u.calibration_covariance_updated = true;
    }
  }
  u.solve.total_s = seconds(start, Clock::now());
  if (callback) callback(u);
}

Status Estimator::Impl::covariance(Eigen::Matrix<double, 6, 6>* pose_cov) {
  solves_since_covariance = 0;
  if (states.empty()) return Status::Error("no state yet");
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::SPARSE_QR;
  co.num_threads = options.threads;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> blocks;
  double* newest = states.back()->pose;
  blocks.emplace_back(newest, newest);
  for (const auto& cb : cameras) {
    for (const double* b : {cb->extrinsic, cb->time_offset, cb->intrinsics}) {
      if (!problem->IsParameterBlockConstant(b)) blocks.emplace_back(b, b);
    }
  }
  for (auto& a : aux) {
    for (const double* b : {static_cast<const double*>(a->extrinsicBlock()),
                            static_cast<const double*>(a->time_offset)}) {
      if (!problem->IsParameterBlockConstant(b)) blocks.emplace_back(b, b);
    }
  }
  for (std::size_t i = 0; i < imu_intrinsics.size(); ++i) {
    const double* b = imuIntrinsics(i);
    if (b != nullptr && !problem->IsParameterBlockConstant(b)) blocks.emplace_back(b, b);
  }
  if (!cov.Compute(blocks, problem.get())) return Status::Error("covariance computation failed");
  imuIntrinsicsCovariance(cov);
  if (pose_cov != nullptr) {
    cov.GetCovarianceBlockInTangentSpace(newest, newest, pose_cov->data());
    if (!holds.empty()) {
      const Status s = poseCovarianceWithHeld(pose_cov);
      if (!s.ok()) return s;
    }
  }
  // Blocks held whole (constant) keep the standard deviations they had.
  std::vector<CameraCalibrationStd> out =
      camera_std ? *camera_std : std::vector<CameraCalibrationStd>(cameras.size());
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const CameraBlocks& cb = *cameras[c];
    if (!problem->IsParameterBlockConstant(cb.extrinsic)) {
      const Vector6d sd = tangentCovariance(cov, cb.extrinsic).diagonal().cwiseMax(0.0).cwiseSqrt();
      out[c].rotation = sd.head<3>();
      out[c].translation = sd.tail<3>();
    }
    if (!problem->IsParameterBlockConstant(cb.time_offset)) {
      double v = 0.0;
      cov.GetCovarianceBlock(cb.time_offset, cb.time_offset, &v);
      out[c].timeshift_cam_imu = std::sqrt(std::max(v, 0.0));
    }
    if (!problem->IsParameterBlockConstant(cb.intrinsics)) {
      Eigen::Matrix<double, 8, 8, Eigen::RowMajor> C;
      cov.GetCovarianceBlock(cb.intrinsics, cb.intrinsics, C.data());
      const Eigen::Matrix<double, 8, 1> sd = C.diagonal().cwiseMax(0.0).cwiseSqrt();
      out[c].intrinsics = sd.head<4>();
      out[c].distortion_coeffs = sd.tail<4>();
    }
  }
  camera_std = out;
  for (auto& a : aux) {
    // A block held whole (constant) keeps the standard deviations it had.
    InertialCalibrationStd sd = a->std ? *a->std : InertialCalibrationStd{};
    double* e = a->extrinsicBlock();
    if (!problem->IsParameterBlockConstant(e)) {
      const Eigen::VectorXd v = tangentCovariance(cov, e).diagonal().cwiseMax(0.0).cwiseSqrt();
      sd.rotation = v.head<3>();
      if (!a->gyro) sd.translation = v.tail<3>();
    }
    if (!problem->IsParameterBlockConstant(a->time_offset)) {
      double v = 0.0;
      cov.GetCovarianceBlock(a->time_offset, a->time_offset, &v);
      sd.time_offset = std::sqrt(std::max(v, 0.0));
    }
    a->std = sd;
  }
  return Status::Ok();
}

Status Estimator::Impl::poseCovarianceWithHeld(Eigen::Matrix<double, 6, 6>* pose_cov) {
  // The pose depends on what is held (a camera's translation along the only rotation axis
  // moves imu0's position in the board frame along it): with the held directions constant its
  // covariance would be as if they were known. Released for this computation, with a prior of
  // the uncertainty they kept, they carry it into the pose. The window may still know a little
  // along them (the marginalization prior keeps what earlier motion told, which is part of the
  // kept variance too), so the pose's variance along them is at worst about half what it is.
  std::vector<ceres::ResidualBlockId> added;
  for (auto& [const_block, hold] : holds) {
    double* block = const_cast<double*>(const_block);
    if (hold.subspace) {
      problem->SetManifold(block, hold.base);
    } else {
      problem->SetParameterBlockVariable(block);
    }
    const int ambient = problem->ParameterBlockSize(block);
    added.push_back(problem->AddResidualBlock(
        new TangentPriorFactor(hold.base, std::vector<double>(block, block + ambient),
                               hold.directions, hold.variance.cwiseMax(1e-30).cwiseSqrt()),
        nullptr, block));
  }
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::SPARSE_QR;
  co.num_threads = options.threads;
  ceres::Covariance cov(co);
  double* newest = states.back()->pose;
  const std::vector<std::pair<const double*, const double*>> pose_block = {{newest, newest}};
  const bool ok = cov.Compute(pose_block, problem.get());
  if (ok) cov.GetCovarianceBlockInTangentSpace(newest, newest, pose_cov->data());
  for (ceres::ResidualBlockId id : added) problem->RemoveResidualBlock(id);
  for (auto& [const_block, hold] : holds) {
    double* block = const_cast<double*>(const_block);
    if (hold.subspace) {
      problem->SetManifold(block, hold.subspace.get());
    } else {
      problem->SetParameterBlockConstant(block);
    }
  }
  return ok ? Status::Ok() : Status::Error("pose covariance with the held directions failed");
}

}  // namespace mvis
