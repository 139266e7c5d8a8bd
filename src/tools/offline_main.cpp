// mvis_offline --config DIR --bag FILE --output DIR [--imu-chain F] [--cam-chain F] [--target F]
//              [--truth DIR] [--interpolation imu|report]
//              [--pixel-sigma PX] [--huber S] [--robust-loss frame|corner] [--window N]
//              [--threads N]
//              [--max-iterations N] [--solve-every N]
//              [--max-solve-time S]
//              [--aux-model velocity_state|rigid_velocity] [--observability-ratio R]
//              [--imu-observability-ratio R] [--window-observability-ratio R]
//              [--estimate-intrinsics] [--estimate-imu-intrinsics]
//              [--estimate-gravity-sensitivity] [--fixed-imu-linearization]
//              [--propagation-noise] [--imu-step S] [--hold SENSOR.QUANTITY]...
//              [--failure-step-sigma S] [--frame-gate-sigma S] [--no-change-detection]
//              [--batch [--batch-iterations N]]
// Runs the estimator over a bag as fast as it can (no ROS master), writes the result directory
// (the calibration files with *_std keys, trajectory.tum) and prints the calibration. With
// --truth (a simulation's truth/ directory) it prints errors against the truth and the ATE.
// With --batch the online pass is followed by one solve over every state of the recording
// (report Eq. 23) started from the online result: the result directory is the batch's, the
// online pass's goes to DIR/online.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

#include "mvis/estimator/evaluation.h"
#include "mvis/estimator/result_directory.h"
#include "mvis/rig/rig_io.h"
#include "mvis/rig/trajectory_io.h"
#include "mvis/ros/offline.h"

namespace {

void printUsage(std::FILE* out) {
  std::fprintf(out,
               "usage: mvis_offline --config DIR --bag FILE --output DIR [--truth DIR]\n"
               "                    [--imu-chain FILE] [--cam-chain FILE] [--target FILE]\n"
               "                    [--interpolation imu|report] [--pixel-sigma PX] [--huber S]\n"
               "                    [--robust-loss frame|corner]\n"
               "                    [--window N] [--carried-tags N] [--no-own-tags] [--threads N]\n"
               "                    [--max-iterations N] [--solve-every N] [--max-solve-time S]\n"
               "                    [--aux-model velocity_state|rigid_velocity]\n"
               "                    [--observability-ratio R] [--imu-observability-ratio R]\n"
               "                    [--window-observability-ratio R]\n"
               "                    [--estimate-intrinsics]\n"
               "                    [--estimate-imu-intrinsics] [--estimate-gravity-sensitivity]\n"
               "                    [--fixed-imu-linearization] [--propagation-noise]\n"
               "                    [--imu-step S]\n"
               "                    [--hold SENSOR.QUANTITY]...\n"
               "                    [--failure-step-sigma S] [--frame-gate-sigma S]\n"
               "                    [--no-change-detection]\n"
               "                    [--batch [--batch-iterations N]\n"
               "                             [--batch-covariance clustered|model]]\n"
               "  --config DIR     the rig's initial calibration (kalibr_imu_chain.yaml,\n"
               "                   kalibr_imucam_chain.yaml, aprilgrid.yaml)\n"
               "  --imu-chain F, --cam-chain F, --target F  other names for those files\n"
               "                   (relative to --config unless absolute), e.g. Kalibr's\n"
               "                   imu-rig.yaml and camchain-imucam-rig.yaml\n"
               "  --bag FILE       IMU and image (or tag detection) messages\n"
               "  --output DIR     where the calibration and trajectory.tum go\n"
               "  --truth DIR      a simulation's truth/: print errors and the ATE\n"
               "  --interpolation  frame poses from the IMU (default) or the report's\n"
               "                   kinematic/pose-based interpolation\n"
               "  --pixel-sigma PX corner noise (default 1)\n"
               "  --huber S        robust loss threshold [sigma] (default 3, 0: none)\n"
               "  --robust-loss L  where the Huber loss acts: on each corner (corner, default)\n"
               "                   or on a frame's corners together (frame)\n"
               "  --window N       states in the sliding window (default 5)\n"
               "  --carried-tags N without a board, the most tags carried across the window's\n"
               "                   marginalizations (default 12, 0: every tag)\n"
               "  --no-own-tags    without a board, leave out the tags beyond the carried ones\n"
               "                   (window_own_tags: false; faster, less precise)\n"
               "  --threads N      Ceres's threads for the solves (default 1; with more the\n"
               "                   last digits of the result may vary from run to run)\n"
               "  --max-iterations N  Ceres iterations per update (default 10)\n"
               "  --solve-every N  solve after every n-th cam0 frame (default 3, at most the\n"
               "                   window's states - 2)\n"
               "  --max-solve-time S  time budget per solve [s] as the nodelet has it (0.05);\n"
               "                   default none, so that results do not depend on the load\n"
               "  --aux-model M    auxiliary IMU velocity as a state (velocity_state, default)\n"
               "                   or rigid-body (rigid_velocity, the report's Appendix B)\n"
               "  --observability-ratio R  degenerate-motion check threshold (default 500,\n"
               "                   0: off; see config/mvis.yaml)\n"
               "  --imu-observability-ratio R  the same for the IMU intrinsics (default 1)\n"
               "  --window-observability-ratio R  the same asked of the window's information\n"
               "                   about every calibration block jointly (default 0: off)\n"
               "  --estimate-intrinsics  calibrate every camera's intrinsics and distortion\n"
               "  --estimate-imu-intrinsics  calibrate Dw, Da, R_IMUtoACC (kalibr: R_IMUtoGYRO)\n"
               "                   of every rpng or kalibr\n"
               "                   inertial sensor (a gyroscope's Dw), re-integrating\n"
               "  --estimate-gravity-sensitivity  and their Tg (a gyroscope's too)\n"
               "  --fixed-imu-linearization  first order about the configured IMU intrinsics\n"
               "                   instead of re-integrating (for comparison)\n"
               "  --propagation-noise  a frame's IMU-propagated pose carries the readings'\n"
               "                   noise instead of being exact (for corners of ~0.05 px)\n"
               "  --imu-step S     inertial readings integrated in steps of at most S [s],\n"
               "                   cubic in between (default 0.0025; 0: as they come)\n"
               "  --hold S.Q       hold sensor S's quantity Q (extrinsic, time_offset,\n"
               "                   intrinsics, gravity_sensitivity) at its configured value;\n"
               "                   repeatable\n"
               "  --failure-step-sigma S  an extrinsic's or time offset's step from the\n"
               "                   trusted calibration beyond S of its sigma (scaled by how\n"
               "                   much the calibration moves on this data) is a failure and\n"
               "                   the window starts over (default 10, 0: no calibration checks;\n"
               "                   see config/mvis.yaml)\n"
               "  --frame-gate-sigma S  frames whose corners are beyond S sigma (median) of\n"
               "                   where the trusted estimate puts them are dropped, and so\n"
               "                   are single corners beyond it (default 10, 0: off)\n"
               "  --no-change-detection  do not test the sensors for a changed calibration\n"
               "                   (a knocked mount; on by default, with a board)\n"
               "  --batch          after the online pass, solve every state of the recording\n"
               "                   and the calibration at once from its result (the same\n"
               "                   factors and priors), with the batch's covariance; the\n"
               "                   online result goes to OUTPUT/online\n"
               "  --batch-iterations N  at most N iterations of the batch (default 100)\n"
               "  --batch-covariance  the batch's calibration sigmas: clustered (default;\n"
               "                   the model's, plus what the residuals show beyond it, with\n"
               "                   errors correlated along a corner's track, over a second of\n"
               "                   frames or of inertial factors counted as they are) or\n"
               "                   model (the inverse information: every residual as its\n"
               "                   noise model says)\n");
}

int usage(const char* message) {
  std::fprintf(stderr, "%s\n", message);
  printUsage(stderr);
  return 2;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * v.size()))];
}

// The batch's solve and its whitened residuals per sensor.
void printBatch(const mvis::OfflineResult& batch, const mvis::OfflineResult& online) {
  const mvis::BatchSummary& b = *batch.batch;
  std::printf(
      "\nbatch: %d states, %d frames, %d corners; %d iterations (%s), cost %.6g -> %.6g; solve "
      "%.1f s, with covariances %.1f s; reading the bag again and the solve %.1f s (%.1fx real "
      "time)\n",
      b.solve.states, b.solve.frames, b.solve.corners, b.solve.iterations,
      b.converged ? "converged" : "iteration limit", b.initial_cost, b.solve.cost, b.solve.solve_s,
      b.solve.total_s, batch.wall_seconds, batch.bag_seconds / batch.wall_seconds);
  const mvis::TimeNs t0 = online.trajectory.empty() ? 0 : online.trajectory.front().stamp_ns;
  if (!batch.trajectory.empty()) {
    // A restart (a long hole in the base IMU's readings) leaves the batch what follows it.
    std::printf(
        "batch: its states span %.2f-%.2f s of the online pass's %.2f s%s\n",
        mvis::toSeconds(batch.trajectory.front().stamp_ns - t0),
        mvis::toSeconds(batch.trajectory.back().stamp_ns - t0),
        online.trajectory.empty() ? 0.0 : mvis::toSeconds(online.trajectory.back().stamp_ns - t0),
        batch.counters.restarts > 0 ? " (it started over: see its warnings)" : "");
  }
  std::printf(
      "batch residuals, whitened, at the solution (a camera's RMS in px; chi-square per "
      "residual about 1 when the noise model fits):\n"
      "sensor  kind            factors  residuals  chi2/residual       RMS  worst states (t [s]: "
      "chi2/residual)\n");
  for (const auto& s : b.residuals) {
    std::printf("%-7s %-14s %8ld %10ld %14.3f %9.4f ", s.sensor.c_str(), s.kind.c_str(), s.factors,
                s.residuals, s.chi_square / static_cast<double>(s.residuals), s.rms);
    for (const auto& [t, chi2] : s.worst) std::printf(" %.2f: %.2f", mvis::toSeconds(t - t0), chi2);
    std::printf("\n");
  }
  if (b.model_calibration) {  // the clustered covariance
    std::printf(
        "batch: the calibration's sigmas, with the errors the residuals show beyond their noise "
        "model (clustered per corner track, second of frames, second of inertial factors), are "
        "%.2f-%.2fx the inverse information's\n",
        b.sigma_ratio_min, b.sigma_ratio_max);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string config_dir, bag_path, output_dir, truth_dir, interpolation = "imu";
  std::string imu_chain, cam_chain, target;
  std::string aux_model = "velocity_state";
  double observability_ratio = mvis::EstimatorOptions{}.observability_ratio;
  double imu_observability_ratio = mvis::EstimatorOptions{}.imu_intrinsics_observability_ratio;
  double window_observability_ratio = mvis::EstimatorOptions{}.window_observability_ratio;
  double failure_step_sigma = mvis::EstimatorOptions{}.failure_step_sigma;
  double frame_gate_sigma = mvis::EstimatorOptions{}.frame_gate_sigma;
  bool estimate_intrinsics = false;
  bool estimate_imu_intrinsics = false, estimate_gravity_sensitivity = false;
  bool fixed_imu_linearization = false;
  std::vector<std::string> hold;
  double pixel_sigma = mvis::EstimatorOptions{}.pixel_sigma_px;
  double huber = mvis::EstimatorOptions{}.huber_sigma;
  mvis::RobustLoss robust_loss = mvis::EstimatorOptions{}.robust_loss;
  bool propagation_noise = false;
  bool detect_changes = true;
  double imu_step = mvis::EstimatorOptions{}.imu_integration_step_s;
  double max_solve_time = 1e3;
  int window = mvis::EstimatorOptions{}.window_size;
  int carried_tags = mvis::EstimatorOptions{}.carried_tags;
  bool window_own_tags = mvis::EstimatorOptions{}.window_own_tags;
  int threads = mvis::EstimatorOptions{}.threads;
  int iterations = mvis::EstimatorOptions{}.max_iterations;
  int solve_every = mvis::EstimatorOptions{}.solve_every;
  bool batch = false;
  int batch_iterations = mvis::OfflineOptions{}.batch_iterations;
  mvis::BatchCovariance batch_covariance = mvis::EstimatorOptions{}.batch_covariance;
  for (int i = 1; i < argc; ++i) {
    const auto value = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    const std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      printUsage(stdout);
      return 0;
    }
    if (arg == "--config") {
      if (!value(&config_dir)) return usage("--config needs a directory");
    } else if (arg == "--bag") {
      if (!value(&bag_path)) return usage("--bag needs a file");
    } else if (arg == "--output") {
      if (!value(&output_dir)) return usage("--output needs a directory");
    } else if (arg == "--imu-chain") {
      if (!value(&imu_chain)) return usage("--imu-chain needs a file");
    } else if (arg == "--cam-chain") {
      if (!value(&cam_chain)) return usage("--cam-chain needs a file");
    } else if (arg == "--target") {
      if (!value(&target)) return usage("--target needs a file");
    } else if (arg == "--truth") {
      if (!value(&truth_dir)) return usage("--truth needs a directory");
    } else if (arg == "--pixel-sigma") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) > 0.0))
        return usage("--pixel-sigma takes pixels > 0");
      pixel_sigma = std::atof(v.c_str());
    } else if (arg == "--robust-loss") {
      std::string v;
      if (!value(&v) || (v != "frame" && v != "corner"))
        return usage("--robust-loss takes frame or corner");
      robust_loss = v == "corner" ? mvis::RobustLoss::kCorner : mvis::RobustLoss::kFrame;
    } else if (arg == "--huber") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0)) return usage("--huber takes sigmas >= 0");
      huber = std::atof(v.c_str());
    } else if (arg == "--max-solve-time") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) > 0.0)) {
        return usage("--max-solve-time takes seconds > 0");
      }
      max_solve_time = std::atof(v.c_str());
    } else if (arg == "--threads") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) return usage("--threads takes a count >= 1");
      threads = std::atoi(v.c_str());
    } else if (arg == "--no-own-tags") {
      window_own_tags = false;
    } else if (arg == "--carried-tags") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 0) return usage("--carried-tags takes a count >= 0");
      carried_tags = std::atoi(v.c_str());
    } else if (arg == "--window") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 3) return usage("--window takes a state count >= 3");
      window = std::atoi(v.c_str());
    } else if (arg == "--solve-every") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) return usage("--solve-every takes a count >= 1");
      solve_every = std::atoi(v.c_str());
    } else if (arg == "--max-iterations") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) {
        return usage("--max-iterations takes a count >= 1");
      }
      iterations = std::atoi(v.c_str());
    } else if (arg == "--aux-model") {
      if (!value(&aux_model) || (aux_model != "velocity_state" && aux_model != "rigid_velocity")) {
        return usage("--aux-model takes velocity_state or rigid_velocity");
      }
    } else if (arg == "--observability-ratio" || arg == "--imu-observability-ratio" ||
               arg == "--window-observability-ratio") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0)) {
        return usage((arg + " takes a number >= 0").c_str());
      }
      (arg == "--observability-ratio"       ? observability_ratio
       : arg == "--imu-observability-ratio" ? imu_observability_ratio
                                            : window_observability_ratio) = std::atof(v.c_str());
    } else if (arg == "--estimate-intrinsics") {
      estimate_intrinsics = true;
    } else if (arg == "--estimate-imu-intrinsics") {
      estimate_imu_intrinsics = true;
    } else if (arg == "--estimate-gravity-sensitivity") {
      estimate_gravity_sensitivity = true;
    } else if (arg == "--fixed-imu-linearization") {
      fixed_imu_linearization = true;
    } else if (arg == "--imu-step") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0))
        return usage("--imu-step takes seconds >= 0");
      imu_step = std::atof(v.c_str());
    } else if (arg == "--propagation-noise") {
      propagation_noise = true;
    } else if (arg == "--no-change-detection") {
      detect_changes = false;
    } else if (arg == "--hold") {
      std::string v;
      if (!value(&v)) return usage("--hold takes SENSOR.QUANTITY, e.g. cam1.intrinsics");
      hold.push_back(v);
    } else if (arg == "--failure-step-sigma" || arg == "--frame-gate-sigma") {
      std::string v;
      const double s = value(&v) ? std::atof(v.c_str()) : -1.0;
      if (!(s == 0.0 || s >= 3.0)) return usage((arg + " takes 0 (off) or sigmas >= 3").c_str());
      (arg == "--failure-step-sigma" ? failure_step_sigma : frame_gate_sigma) = s;
    } else if (arg == "--batch") {
      batch = true;
    } else if (arg == "--batch-covariance") {
      std::string v;
      if (!value(&v) || (v != "clustered" && v != "model")) {
        return usage("--batch-covariance takes clustered or model");
      }
      batch_covariance =
          v == "model" ? mvis::BatchCovariance::kModel : mvis::BatchCovariance::kClustered;
    } else if (arg == "--batch-iterations") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) {
        return usage("--batch-iterations takes a count >= 1");
      }
      batch_iterations = std::atoi(v.c_str());
    } else if (arg == "--interpolation") {
      if (!value(&interpolation) || (interpolation != "imu" && interpolation != "report")) {
        return usage("--interpolation takes imu or report");
      }
    } else {
      return usage(("unknown argument " + arg).c_str());
    }
  }
  if (config_dir.empty() || bag_path.empty() || output_dir.empty()) {
    return usage("--config, --bag and --output are required");
  }
  std::vector<std::string> warnings;
  const auto initial =
      imu_chain.empty() && cam_chain.empty() && target.empty()
          ? mvis::loadRig(config_dir, &warnings)
          : mvis::loadRig(mvis::RigFiles::in(config_dir, imu_chain, cam_chain, target), &warnings);
  for (const auto& w : warnings) std::fprintf(stderr, "mvis_offline: warning: %s\n", w.c_str());
  if (!initial.ok()) {
    std::fprintf(stderr, "mvis_offline: %s\n", initial.status().message().c_str());
    return 1;
  }
  std::optional<mvis::Rig> truth;
  if (!truth_dir.empty()) {
    auto loaded = mvis::loadRig(truth_dir);
    if (!loaded.ok()) {
      std::fprintf(stderr, "mvis_offline: %s\n", loaded.status().message().c_str());
      return 1;
    }
    truth = loaded.value();
  }

  mvis::OfflineOptions options;
  options.estimator.pixel_sigma_px = pixel_sigma;
  options.estimator.huber_sigma = huber;
  options.estimator.robust_loss = robust_loss;
  options.estimator.propagation_noise = propagation_noise;
  options.estimator.detect_changes = detect_changes;
  options.estimator.imu_integration_step_s = imu_step;
  options.estimator.window_size = window;
  options.estimator.carried_tags = carried_tags;
  options.estimator.window_own_tags = window_own_tags;
  options.estimator.threads = threads;
  options.estimator.max_iterations = iterations;
  options.estimator.solve_every = solve_every;
  // Offline there is no deadline: without the per-solve time budget, results do not depend on
  // the machine's load (unless --max-solve-time asks for the nodelet's).
  options.estimator.max_solve_time_s = max_solve_time;
  options.estimator.init_solve_time_s = 1e3;
  options.estimator.aux_imu_model = aux_model == "rigid_velocity"
                                        ? mvis::AuxImuModel::kRigidVelocity
                                        : mvis::AuxImuModel::kVelocityState;
  options.estimator.observability_ratio = observability_ratio;
  options.estimator.imu_intrinsics_observability_ratio = imu_observability_ratio;
  options.estimator.window_observability_ratio = window_observability_ratio;
  options.estimator.estimate_intrinsics = estimate_intrinsics;
  options.estimator.estimate_imu_intrinsics = estimate_imu_intrinsics;
  options.estimator.estimate_gravity_sensitivity = estimate_gravity_sensitivity;
  if (fixed_imu_linearization) {
    options.estimator.imu_intrinsics_linearization = mvis::IntrinsicsLinearization::kFixed;
  }
  options.estimator.hold = hold;
  options.estimator.failure_step_sigma = failure_step_sigma;
  options.estimator.frame_gate_sigma = frame_gate_sigma;
  options.estimator.interpolation =
      interpolation == "imu" ? mvis::FrameInterpolation::kImu : mvis::FrameInterpolation::kReport;
  if (isatty(STDERR_FILENO)) {
    options.progress = [](double share, double bag_s) {
      const int width = 40, filled = static_cast<int>(share * width);
      std::fprintf(stderr, "\r[%s%s] %3.0f%%  %.1f s of bag", std::string(filled, '#').c_str(),
                   std::string(width - filled, ' ').c_str(), 100.0 * share, bag_s);
      if (share >= 1.0) std::fprintf(stderr, "\n");
    };
  }
  const auto online = mvis::runOffline(initial.value(), bag_path, options);
  if (!online.ok()) {
    std::fprintf(stderr, "mvis_offline: %s\n", online.status().message().c_str());
    return 1;
  }
  std::optional<mvis::StatusOr<mvis::OfflineResult>> batched;
  if (batch) {
    // The same factors and priors over every state, from the online result.
    mvis::OfflineOptions b = options;
    b.estimator.batch = true;
    b.estimator.batch_covariance = batch_covariance;
    b.estimator.observability_horizon_s = 1e9;  // the degeneracy check asks the whole recording
    b.estimator.failure_step_sigma = 0.0;       // nothing to start over to
    b.batch_start = &online.value().calibration;
    b.batch_seed = online.value().trajectory;
    b.batch_iterations = batch_iterations;
    b.batch_progress = [](int iteration, double cost) {
      std::fprintf(stderr, "batch: iteration %d, cost %.6g\n", iteration, cost);
    };
    if (b.progress) std::fprintf(stderr, "batch: reading the bag again\n");
    batched = mvis::runOffline(initial.value(), bag_path, b);
    if (!batched->ok()) {
      std::fprintf(stderr, "mvis_offline: batch: %s\n", batched->status().message().c_str());
      return 1;
    }
  }
  const mvis::OfflineResult& r = batched ? batched->value() : online.value();
  for (const auto& w : online.value().warnings) {
    std::fprintf(stderr, "mvis_offline: warning: %s\n", w.c_str());
  }
  if (!online.value().warning_kinds.empty()) {
    std::fprintf(stderr, "mvis_offline: what went wrong in the bag, by kind (count, first at):\n");
    for (const auto& w : online.value().warning_kinds) {
      std::fprintf(stderr, "  %6ldx  %s  (first at %.2f s)\n", w.count, w.example.c_str(),
                   w.first_s);
    }
  }
  if (batched) {
    for (const auto& w : r.warnings) {
      std::fprintf(stderr, "mvis_offline: batch: warning: %s\n", w.c_str());
    }
    for (const auto& w : r.warning_kinds) {
      std::fprintf(stderr, "mvis_offline: batch: %ldx  %s  (first at %.2f s)\n", w.count,
                   w.example.c_str(), w.first_s);
    }
    const mvis::Status saved_online =
        mvis::writeResultDirectory(output_dir + "/online", online.value().calibration,
                                   online.value().trajectory, online.value().log);
    if (!saved_online.ok()) {
      std::fprintf(stderr, "mvis_offline: %s\n", saved_online.message().c_str());
      return 1;
    }
  }

  mvis::Status saved = mvis::writeResultDirectory(output_dir, r.calibration, r.trajectory, r.log);
  if (saved.ok() && r.batch) {
    saved = mvis::writeBatchResiduals(output_dir, r.calibration, *r.batch,
                                      r.trajectory.empty() ? 0 : r.trajectory.back().stamp_ns);
  }
  if (!saved.ok()) {
    std::fprintf(stderr, "mvis_offline: %s\n", saved.message().c_str());
    return 1;
  }

  const mvis::OfflineResult& o = online.value();
  std::printf(
      "mvis_offline: %.1f s of data in %.1f s (%.1fx real time); %ld IMU, %ld image, "
      "%ld detection messages, %ld dropped\n",
      o.bag_seconds, o.wall_seconds, o.bag_seconds / o.wall_seconds, o.imu_messages,
      o.image_messages, o.detection_messages, o.dropped_messages);
  const mvis::EstimatorCounters& c = o.counters;
  std::printf(
      "failure checks: %ld restarts, %ld failures, %ld frames and %ld corners dropped, %ld "
      "intrinsics inconsistencies, %ld held gravity sensitivities refuted; the calibration "
      "moves %.1fx what its sigmas allow\n",
      c.restarts, c.failures, c.frames_rejected, c.corners_rejected, c.inconsistencies,
      c.held_intrinsics_misfits, o.sigma_inflation);
  if (std::isfinite(o.time_offset_floor)) {
    std::printf(
        "time offsets' floor from imu0's noise along the motion its readings show: %.4f ms (1 "
        "sigma; %ld covariances had a time offset's sigma under 0.9 of it)\n",
        o.time_offset_floor * 1e3, c.time_offsets_under_floor);
  }
  double update_total_ms = 0.0;
  for (double ms : o.update_ms) update_total_ms += ms;
  std::printf("estimator updates: %zu, median %.1f ms, p99 %.1f ms, total %.2f s",
              o.update_ms.size(), percentile(o.update_ms, 0.5), percentile(o.update_ms, 0.99),
              update_total_ms * 1e-3);
  if (!o.solve_iterations.empty()) {
    double iterations = 0.0;
    for (int i : o.solve_iterations) iterations += i;
    std::printf("; %zu solves, %.1f iterations each", o.solve_iterations.size(),
                iterations / o.solve_iterations.size());
  }
  if (!o.frontend_ms.empty()) {
    std::printf("; tag detection median %.1f ms, p99 %.1f ms", percentile(o.frontend_ms, 0.5),
                percentile(o.frontend_ms, 0.99));
  }
  if (!o.decode_ms.empty()) {
    std::printf("; image decoding median %.1f ms, p99 %.1f ms", percentile(o.decode_ms, 0.5),
                percentile(o.decode_ms, 0.99));
  }
  if (c.degeneracy_checks > 0) {
    std::printf("; degeneracy checks %.2f ms per solve (%.1f%% of the updates' time)",
                1e3 * c.degeneracy_check_s / c.degeneracy_checks,
                update_total_ms > 0.0 ? 100.0 * 1e3 * c.degeneracy_check_s / update_total_ms : 0.0);
  }
  if (c.window_checks > 0) {
    std::printf("; degeneracy check of the window's information %.1f ms each (%ld checks)",
                1e3 * c.window_check_s / c.window_checks, c.window_checks);
  }
  if (batched) printBatch(r, o);
  const mvis::OfflineResult& with_changes = batched ? online.value() : r;
  const auto& changes = with_changes.changes;
  if (changes.empty()) {
    std::printf("\nno sensor's calibration changed during the recording");
  }
  for (std::size_t i = 0; i < changes.size(); ++i) {
    // One line per declaration (its quantities share its text).
    if (i > 0 && changes[i].stamp_ns == changes[i - 1].stamp_ns &&
        changes[i].sensor == changes[i - 1].sensor) {
      continue;
    }
    std::printf("\ncalibration change at %.2f s of the bag: %s", with_changes.change_bag_s[i],
                changes[i].text.c_str());
  }
  for (const std::string& u : r.unobservable) {
    std::printf("\nheld at the end (the motion could not calibrate it): %s", u.c_str());
  }
  std::printf(
      "\n\n%s%s", batched ? "batch calibration:\n" : "",
      mvis::calibrationTable(initial.value(), r.calibration, truth ? &*truth : nullptr).c_str());
  if (truth) {
    auto true_trajectory = mvis::readTumTrajectory(truth_dir + "/trajectory.tum");
    if (true_trajectory.ok() && initial.value().target) {
      std::printf("\nATE (position RMSE, board frame, no alignment): %.2f mm over %zu states\n",
                  mvis::positionRmse(r.trajectory, true_trajectory.value()) * 1e3,
                  r.trajectory.size());
      if (batched) {
        std::printf("ATE of the online pass: %.2f mm over %zu states\n",
                    mvis::positionRmse(online.value().trajectory, true_trajectory.value()) * 1e3,
                    online.value().trajectory.size());
      }
    } else if (true_trajectory.ok()) {
      std::printf(
          "\nATE (position RMSE, SE(3)-aligned: without a board the estimate's frame is its "
          "own): %.2f mm over %zu states\n",
          mvis::positionRmse(r.trajectory, true_trajectory.value(), true) * 1e3,
          r.trajectory.size());
    }
    if (true_trajectory.ok() && !truth->inertial.empty()) {
      std::printf(
          "time offsets' floor from imu0's noise along this motion, all else known: %.4f ms "
          "(1 sigma; no estimate is more certain)\n",
          mvis::timeOffsetFloor(true_trajectory.value(), truth->inertial[0].noise) * 1e3);
    }
  }
  std::printf(
      "\nresult: %s (kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml, trajectory.tum, "
      "calibration.csv, pose_covariance.csv, calibration_changes.csv%s)\n",
      output_dir.c_str(),
      batched ? ", corner_residuals.csv, inertial_residuals.csv, calibration_model.csv with "
                "--batch-covariance clustered; the online pass's in online/"
              : "");
  return 0;
}
