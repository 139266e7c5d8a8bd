// The estimator's covariances (the calibration's standard deviations and the newest pose's
// online; in a batch every second of the trajectory's too) and the batch over a whole recording
// (EstimatorOptions::batch): the starting calibration, the seed trajectory, the one solve and
// its whitened residuals per sensor. Part of the facade (estimator_impl.h).
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>
#include <tuple>

#include "estimator_impl.h"
#include "mvis/common/lie.h"
#include "mvis/factors/tag_reprojection_factor.h"

namespace mvis {

using estimator_internal::State;

namespace {

// A calibration is offered to be trusted only after the window has run on this much data: the
// first seconds' covariances are taken far from the solution and are overconfident (restarted
// from the calibration trusted after 2.5 s, a clean small-rig run failed the step test at 10
// sigma a second later).
constexpr double kTrustAfterS = 10.0;
// Seed states further apart than this are not interpolated between (the online pass started
// over there, or had a hole).
constexpr TimeNs kMaxSeedGapNs = 200000000;  // 0.2 s
// A batch's pose covariances: one state per this much of the trajectory.
constexpr TimeNs kPoseCovarianceSpacingNs = kNsPerSecond;
// A batch's clustered covariance (block_covariance.h): the corners of the frames within one such
// span of the recording form a cluster, and so do an inertial sensor's factors. Corners of
// nearby frames share errors that a single frame's cluster misses (on the EuRoC bag thirds and
// halves agree within 3.1 and 3.3 combined sigma with one frame per cluster, 2.4 and 2.8 with
// one second; on the simulator's white corners the sigmas stay 1.01-1.17x the model's for the
// cameras either way: doc/results.md).
constexpr TimeNs kClusterSpanNs = kNsPerSecond;

class ProgressCallback : public ceres::IterationCallback {
 public:
  explicit ProgressCallback(const std::function<void(int, double)>& f) : f_(f) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (f_) f_(s.iteration, s.cost);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(int, double)>& f_;
};

}  // namespace

Status Estimator::Impl::covariance(Eigen::Matrix<double, 6, 6>* pose_cov, Clustered* clustered,
                                   Eigen::Matrix<double, 9, 9>* speed_bias_cov) {
  solves_since_covariance = 0;
  if (window.empty()) return Status::Error("no state yet");
  ceres::Problem* problem = window.problem();
  estimator_internal::BlockCovariance cov;
  std::vector<std::pair<const double*, const double*>> blocks;
  double* newest = window.newest().pose;
  // The IMU intrinsics' held directions free for this computation (considered, held again at
  // the end: ObservabilityMonitor::considering).
  const bool consider = clustered == nullptr && monitor.considering();
  if (consider) monitor.liftConsidered(problem);
  struct Restore {
    estimator_internal::ObservabilityMonitor* monitor;
    ceres::Problem* problem;
    ~Restore() {
      if (monitor != nullptr) monitor->restoreConsidered(problem);
    }
  } restore{consider ? &monitor : nullptr, problem};
  blocks.emplace_back(newest, newest);
  double* speed_bias = window.newest().speed_bias;
  if (speed_bias_cov != nullptr) blocks.emplace_back(speed_bias, speed_bias);
  calibration.covarianceBlocks(*problem, &blocks);
  intrinsics.covarianceBlocks(*problem, &blocks);
  if (!cov.compute(blocks, problem, true, clustered ? &clustered->clusters : nullptr)) {
    return Status::Error("covariance computation failed");
  }
  Eigen::MatrixXd considered;
  std::map<const double*, std::pair<int, int>> at;  // first row, size
  if (consider) {
    std::vector<const double*> listed;
    for (const auto& b : blocks) listed.push_back(b.first);
    considered = monitor.considerCovariance(*problem, cov, listed, &at);
    if (considered.size() == 0) return Status::Error("covariance computation failed");
  }
  const auto from_considered = [&](const double* block) {
    const auto a = at.find(block);
    if (a == at.end()) {  // not in the computation: NaN, as tangentCovariance has it
      const ceres::Manifold* own = monitor.baseManifold(*problem, block);
      const int t = own != nullptr ? own->TangentSize() : problem->ParameterBlockSize(block);
      return Eigen::MatrixXd(
          Eigen::MatrixXd::Constant(t, t, std::numeric_limits<double>::quiet_NaN()));
    }
    const auto [first, t] = a->second;
    return Eigen::MatrixXd(considered.block(first, first, t, t));
  };
  const estimator_internal::TangentCovariance tangent = [&](const double* block) {
    return consider ? from_considered(block) : monitor.tangentCovariance(*problem, cov, block);
  };
  if (clustered != nullptr) {
    clustered->ratio_min = std::numeric_limits<double>::infinity();
    clustered->ratio_max = 0.0;
    Eigen::VectorXd ratio;
    for (const auto& [block, same] : blocks) {
      if (block == newest || !cov.sigmaRatio(block, &ratio)) continue;
      clustered->ratio_min = std::min(clustered->ratio_min, ratio.minCoeff());
      clustered->ratio_max = std::max(clustered->ratio_max, ratio.maxCoeff());
    }
    if (clustered->ratio_max == 0.0) clustered->ratio_min = clustered->ratio_max = 1.0;
    // The calibration with the model's standard deviations, then the clustered ones below.
    cov.showModel(true);
    intrinsics.updateCovariance(*problem, tangent);
    calibration.updateStd(*problem, tangent);
    clustered->model = calibrationEstimate();
    cov.showModel(false);
  }
  intrinsics.updateCovariance(*problem, tangent);
  if (pose_cov != nullptr) {
    cov.showModel(true);  // a pose's covariance is the model's (EstimatorOptions)
    cov.GetCovarianceBlockInTangentSpace(newest, newest, pose_cov->data());
    if (speed_bias_cov != nullptr) {
      Eigen::Matrix<double, 9, 9, Eigen::RowMajor> c;
      cov.GetCovarianceBlockInTangentSpace(speed_bias, speed_bias, c.data());
      *speed_bias_cov = c;
    }
    cov.showModel(false);
    if (monitor.holding()) {  // always while considering
      std::vector<Eigen::Matrix<double, 6, 6>> with_held;
      const Status s = monitor.poseCovarianceWithHeld(problem, {newest}, &with_held);
      if (!s.ok()) return s;
      *pose_cov = with_held[0];
    }
  }
  calibration.updateStd(*problem, tangent);
  if (!options.batch) checkTimeOffsetFloor(*problem, tangent);
  const auto joint = [&](const std::vector<const double*>& listed) {
    if (!consider) return monitor.jointTangentCovariance(*problem, cov, listed);
    std::vector<int> first, size;
    int n = 0;
    for (const double* b : listed) {
      const auto a = at.find(b);
      if (a == at.end()) return Eigen::MatrixXd();
      first.push_back(a->second.first);
      size.push_back(a->second.second);
      n += size.back();
    }
    Eigen::MatrixXd out(n, n);
    for (std::size_t i = 0, r = 0; i < listed.size(); r += size[i], ++i) {
      for (std::size_t j = 0, c = 0; j < listed.size(); c += size[j], ++j) {
        out.block(r, c, size[i], size[j]) = considered.block(first[i], first[j], size[i], size[j]);
      }
    }
    return out;
  };
  // A candidate for the trusted calibration (trusted once the next one is offered).
  if (initialized && window_data_s >= kTrustAfterS && failure().empty()) {
    auto offered = trustedBlocks(false);
    std::vector<const double*> estimated;
    for (const auto& b : offered) {
      if (b.estimated) estimated.push_back(b.x);
    }
    const auto verdict = trusted.offer(std::move(offered), joint(estimated), window.newestTime());
    if (!verdict.failure.empty() && options.failure_step_sigma > 0.0) {
      covariance_failure = "estimate failed: " + verdict.failure;
    }
    if (!verdict.inconsistent.empty() && options.failure_step_sigma > 0.0) {
      ++counters.inconsistencies;
      calibration_note = verdict.inconsistent;
    }
    // Said when the inflation first passes 4, 16, 64 (sigma 2x, 4x, 8x too small).
    const double lambda = trusted.inflation();
    if (lambda >= 4.0 * said_inflation) {
      while (lambda >= 4.0 * said_inflation) said_inflation *= 4.0;
      std::ostringstream note;
      note << "the calibration moves " << std::setprecision(2) << std::sqrt(lambda)
           << "x more between covariances than its standard deviations allow (median "
              "chi-square of its steps over their expectation): the model does not fit this "
              "data (e.g. held intrinsics that are off, an unmodelled effect, corners with "
              "correlated errors); the reported sigmas are too small by about that much, and the "
              "failure checks allow for it";
      calibration_note = note.str();
    }
    if (trusted.fromCovariance()) frames.setGate(options.frame_gate_sigma);
  }
  return Status::Ok();
}

void Estimator::Impl::checkTimeOffsetFloor(const ceres::Problem& problem,
                                           const estimator_internal::TangentCovariance& tangent) {
  // No time offset against imu0 can be known better than imu0's white noise along the motion
  // allows (Estimator::timeOffsetFloor, from its readings between the states); a sigma well under
  // it is certainly too small: the model takes something as exact that is not (on translation-only
  // motion with an auxiliary IMU ten times quieter than imu0 and 0.05 px corners the offsets'
  // sigmas were 0.41 of it, their errors 0.1-3.3 ms; doc/results.md, "A quiet auxiliary IMU").
  // 0.9: the floor from the readings is within about 1% of the truth's over a minute, and a
  // consistent estimate stays well above it (at the end of 60 s on the VI-Rig: 1.43x hand-held,
  // 1.17x translation-only, 1.34x yaw-only); 0.89 on translation-only motion with 0.05 px
  // corners, where the frames' propagation noise is not modelled, is said (one run's errors 3.5
  // sigma for the cameras, 7 for imu1).
  // The bound is on what the sensors share against imu0 (every offset moving together shows
  // only in imu0's readings), so it holds for each offset while all of them are estimated; a
  // sensor whose offset is taken as known would be another clock to measure against: then no
  // check. Their priors add to what is known of that shared shift (at most their sum).
  if (window_data_s < kTrustAfterS) return;
  struct Offset {
    const double* block;
    double prior;  // its configured standard deviation [s]
    const std::string& name;
  };
  std::vector<Offset> offsets;
  for (std::size_t c = 0; c < calibration.cameras(); ++c) {
    const auto& cb = calibration.camera(c);
    offsets.push_back({cb.time_offset, cb.prior.time_offset, rig.cameras[c].name});
  }
  for (std::size_t i = 0; i < aux.size(); ++i) {
    const auto& a = calibration.aux(i);
    offsets.push_back({a.time_offset, a.prior.time_offset, rig.inertial[i + 1].name});
  }
  double information = time_offset_information;
  for (const Offset& o : offsets) {
    if (!monitor.estimated(problem, o.block)) return;
    if (o.prior > 0.0) information += 1.0 / (o.prior * o.prior);
  }
  if (!(information > 0.0)) return;
  const double floor = 1.0 / std::sqrt(information);
  std::vector<std::string> under;
  double lowest = std::numeric_limits<double>::infinity();
  for (const Offset& o : offsets) {
    if (monitor.holds(o.block)) continue;
    const Eigen::MatrixXd c = tangent(o.block);
    if (c.size() != 1 || !(c(0, 0) >= 0.0)) continue;
    const double sigma = std::sqrt(c(0, 0));
    if (sigma >= kFloorShare * floor) continue;
    under.push_back(o.name);
    lowest = std::min(lowest, sigma);
  }
  if (under.empty()) return;
  ++counters.time_offsets_under_floor;
  if (said_floor) return;
  said_floor = true;
  std::ostringstream note;
  note << std::setprecision(2) << "time offsets of";
  for (const auto& name : under) note << " " << name;
  note << " have sigmas down to " << lowest * 1e3 << " ms, under the " << floor * 1e3
       << " ms that imu0's noise allows on this motion: they are too small (something taken as "
          "exact is not; with corners of a few hundredths of a pixel try propagation_noise)";
  calibration_note += (calibration_note.empty() ? "" : "; ") + note.str();
}

bool Estimator::Impl::seedAt(TimeNs t, State* s) const {
  if (!options.batch || seed.empty()) return false;
  const auto after =
      std::lower_bound(seed.begin(), seed.end(), t,
                       [](const EstimatorState& e, TimeNs stamp) { return e.stamp_ns < stamp; });
  if (after == seed.end() || (after == seed.begin() && after->stamp_ns != t)) return false;
  const EstimatorState& b = *after;
  const EstimatorState& a = after == seed.begin() ? b : *(after - 1);
  if (b.stamp_ns - a.stamp_ns > kMaxSeedGapNs) return false;
  const double lambda = b.stamp_ns == a.stamp_ns
                            ? 1.0
                            : toSeconds(t - a.stamp_ns) / toSeconds(b.stamp_ns - a.stamp_ns);
  se3ToPose(lie::interpolatePose(a.T_G_I, b.T_G_I, lambda), s->pose);
  Eigen::Map<Eigen::Vector3d>(s->speed_bias) = a.v_G + lambda * (b.v_G - a.v_G);
  Eigen::Map<Eigen::Vector3d>(s->speed_bias + 3) =
      a.bias_gyro + lambda * (b.bias_gyro - a.bias_gyro);
  Eigen::Map<Eigen::Vector3d>(s->speed_bias + 6) =
      a.bias_accel + lambda * (b.bias_accel - a.bias_accel);
  return true;
}

void Estimator::Impl::applyStart() {
  if (!start) return;
  calibration.setValues(*start);
  intrinsics.setValues(*start);
}

estimator_internal::RowClusters Estimator::Impl::rowClusters() const {
  estimator_internal::RowClusters out;
  // Way A: a corner's track (with a board per camera and board point, else per landmark block
  // and index), an inertial sensor's factors within a span; way B: the frames within a span,
  // an inertial factor itself.
  std::map<std::tuple<std::size_t, double, double, double>, int> board_ids;
  std::map<std::pair<const double*, int>, int> landmark_ids;
  std::map<std::pair<int, TimeNs>, int> inertial_ids;
  int state_index = 0, next_id = 0;
  const TimeNs t0 = window.states().empty() ? 0 : window.states().front()->t;
  for (const auto& state : window.states()) {
    for (const auto& r : state->residuals) {
      if (r.inertial >= 0) {
        const auto key = std::make_pair(r.inertial, (state->t - t0) / kClusterSpanNs);
        const int id = inertial_ids.emplace(key, next_id).first->second;
        if (id == next_id) ++next_id;
        auto& block = out.blocks[r.id];
        block.group = 1 + r.inertial;
        block.rows.assign(static_cast<std::size_t>(r.cost->num_residuals()), {id, state_index});
        continue;
      }
      const auto* tag = dynamic_cast<const TagReprojectionFactor*>(r.cost);
      if (tag == nullptr ||
          2 * static_cast<int>(tag->corners().size()) != r.cost->num_residuals()) {
        continue;
      }
      std::size_t camera = rig.cameras.size();
      for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
        if (std::find(r.blocks.begin(), r.blocks.end(), calibration.camera(c).extrinsic) !=
            r.blocks.end()) {
          camera = c;
        }
      }
      const int landmark = tag->landmarkBlock();
      if (camera == rig.cameras.size() ||
          (landmark >= 0 && static_cast<std::size_t>(landmark) >= r.blocks.size())) {
        continue;
      }
      auto& block = out.blocks[r.id];
      block.group = 0;
      auto& rows = block.rows;
      for (const CornerObservation& o : tag->corners()) {
        int id = 0;
        if (landmark >= 0) {
          const auto key =
              std::make_pair(static_cast<const double*>(r.blocks[landmark]), o.landmark);
          id = landmark_ids.emplace(key, next_id).first->second;
        } else {
          const auto key = std::make_tuple(camera, o.p_G.x(), o.p_G.y(), o.p_G.z());
          id = board_ids.emplace(key, next_id).first->second;
        }
        if (id == next_id) ++next_id;
        const int span = static_cast<int>((state->t - t0) / kClusterSpanNs);
        rows.emplace_back(id, span);
        rows.emplace_back(id, span);
      }
    }
    ++state_index;
  }
  return out;
}

StatusOr<BatchSummary> Estimator::Impl::solveBatch(
    int max_iterations, const std::function<void(int, double)>& progress) {
  if (!options.batch) return Status::Error("solveBatch needs EstimatorOptions::batch");
  if (!initialized || window.empty()) {
    return Status::Error("the batch has no states to solve (" + status_text + ")");
  }
  ceres::Problem* problem = window.problem();
  const auto start_time = Clock::now();
  // What the recording's motion cannot observe is held, as online.
  monitor.check(problem);
  BatchSummary out;
  problem->Evaluate(ceres::Problem::EvaluateOptions(), &out.initial_cost, nullptr, nullptr,
                    nullptr);
  ProgressCallback callback(progress);
  out.solve = window.solve(max_iterations, 1e9, &callback, &out.converged);
  intrinsics.refreshBase();
  ++counters.solves;
  if (!out.solve.usable) return Status::Error("the batch's solve failed (Ceres: not usable)");
  residualSummary(&out);
  out.pixel_sigma_px = options.pixel_sigma_px;
  // The calibration's standard deviations (and the newest pose's covariance).
  Eigen::Matrix<double, 6, 6> newest;
  std::optional<Clustered> clustered;
  if (options.batch_covariance == BatchCovariance::kClustered) {
    clustered.emplace();
    clustered->clusters = rowClusters();
  }
  batch_solved = true;
  const Status cov = covariance(&newest, clustered ? &*clustered : nullptr);
  if (clustered) {
    out.sigma_ratio_min = clustered->ratio_min;
    out.sigma_ratio_max = clustered->ratio_max;
    out.model_calibration = std::move(clustered->model);
  }
  if (!cov.ok()) return Status::Error("the batch's covariance failed: " + cov.message());
  // Pose covariances about a second apart, from one factorization.
  batch_pose_covariances.clear();
  std::vector<double*> poses;
  std::vector<TimeNs> times;
  TimeNs next = std::numeric_limits<TimeNs>::min();
  for (const auto& state : window.states()) {
    if (state->t < next && state.get() != &window.newest()) continue;
    poses.push_back(state->pose);
    times.push_back(state->t);
    next = state->t + kPoseCovarianceSpacingNs;
  }
  std::vector<Eigen::Matrix<double, 6, 6>> covariances;
  const Status s = monitor.poseCovarianceWithHeld(problem, poses, &covariances);
  if (!s.ok()) return Status::Error("the batch's pose covariances failed: " + s.message());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    batch_pose_covariances.emplace_back(times[k], covariances[k]);
  }
  out.solve.total_s = std::chrono::duration<double>(Clock::now() - start_time).count();
  return out;
}

Status Estimator::setInitialCalibration(const Rig& start) {
  const Rig& rig = impl_->rig;
  if (!impl_->imu.empty() || impl_->initialized) {
    return Status::Error("setInitialCalibration: the estimator has had data already");
  }
  bool same =
      start.cameras.size() == rig.cameras.size() && start.inertial.size() == rig.inertial.size();
  for (std::size_t c = 0; same && c < rig.cameras.size(); ++c) {
    same = start.cameras[c].name == rig.cameras[c].name;
  }
  for (std::size_t i = 0; same && i < rig.inertial.size(); ++i) {
    same = start.inertial[i].name == rig.inertial[i].name &&
           start.inertial[i].type == rig.inertial[i].type &&
           start.inertial[i].model == rig.inertial[i].model;
  }
  if (!same) {
    return Status::Error(
        "setInitialCalibration: the starting calibration's sensors (names, types, IMU models) "
        "differ from the configured rig's");
  }
  impl_->start = start;
  return Status::Ok();
}

void Estimator::setSeedTrajectory(std::vector<EstimatorState> seed) {
  std::stable_sort(seed.begin(), seed.end(), [](const EstimatorState& a, const EstimatorState& b) {
    return a.stamp_ns < b.stamp_ns;
  });
  impl_->seed = std::move(seed);
}

StatusOr<BatchSummary> Estimator::solveBatch(int max_iterations,
                                             const std::function<void(int, double)>& progress) {
  return impl_->solveBatch(max_iterations, progress);
}

std::vector<std::pair<TimeNs, Eigen::Matrix<double, 6, 6>>> Estimator::batchPoseCovariances()
    const {
  return impl_->batch_pose_covariances;
}

double Estimator::heldIntrinsicsStatistic(std::size_t sensor, int* dof) const {
  *dof = 0;
  return sensor < impl_->rig.inertial.size() ? impl_->inertial_fit.statistic(sensor, dof) : 0.0;
}

}  // namespace mvis
