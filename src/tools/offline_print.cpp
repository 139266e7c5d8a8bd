// mvis_offline's printing and report (offline_main.cpp): the usage, the batch's summary and
// report.md.
#include "offline_print.h"

#include <algorithm>
#include <cstdio>

#include "mvis/estimator/report.h"

namespace mvis_offline {

void printUsage(std::FILE* out) {
  std::fprintf(out,
               "usage: mvis_offline --config DIR --bag FILE --output DIR [--params FILE]\n"
               "                    [--truth DIR] [--tag-decimate D] [--tag-full-search-every N]\n"
               "                    [--image-threads N]\n"
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
               "  --params FILE    the nodelet's parameters (config/mvis.yaml's keys: estimate_*,\n"
               "                   hold, tag_*, min_tags, window_size, ...), read as the nodelet\n"
               "                   reads them; the flags below override them. Without it, the\n"
               "                   defaults of config/mvis.yaml. A relative config_dir in it is\n"
               "                   relative to the file; --config overrides\n"
               "  --bag FILE       IMU and image (or tag detection) messages\n"
               "  --output DIR     where the calibration and trajectory.tum go\n"
               "  --truth DIR      a simulation's truth/: print errors and the ATE\n"
               "  --tag-decimate D tags searched at 1/D resolution (>= 1)\n"
               "  --tag-full-search-every N  images searched whole; between, tags are searched\n"
               "                   where the previous images put them (default 10, 1: always\n"
               "                   whole)\n"
               "  --image-threads N  threads detecting tags in images while the bag is read\n"
               "                   (default: one per core; the result does not depend on it)\n"
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

// report.md for one pass's result directory.

mvis::Status writeReport(const std::string& dir, const mvis::Rig& initial,
                         const mvis::OfflineResult& r, const mvis::OfflineOptions& options,
                         const std::string& bag_path, const char* pass) {
  mvis::ReportInputs in;
  in.tool = "mvis_offline";
  const std::size_t slash = bag_path.rfind('/');
  in.source = "bag " + (slash == std::string::npos ? bag_path : bag_path.substr(slash + 1));
  in.pass = pass;
  if (!r.trajectory.empty()) {
    in.first_ns = r.trajectory.front().stamp_ns;
    in.last_ns = r.trajectory.back().stamp_ns;
  }
  in.initial = &initial;
  in.estimate = &r.calibration;
  in.residuals = r.residuals;
  in.options = options.estimator;
  char decimate[32];
  std::snprintf(decimate, sizeof(decimate), "%g", options.frontend.detector.decimate);
  in.extra_options = {
      {"tag_decimate", decimate},
      {"tag_full_search_every", std::to_string(options.frontend.full_search_every)}};
  in.unobservable = r.unobservable;
  in.changes = r.changes;
  for (const auto& w : r.warning_kinds) {
    char line[64];
    std::snprintf(line, sizeof(line), "%ldx (first at %.2f s of the bag): ", w.count, w.first_s);
    in.warnings.push_back(line + w.example);
  }
  for (const auto& w : r.warnings) in.warnings.push_back(w);
  in.counters = r.counters;
  in.sigma_inflation = r.sigma_inflation;
  in.statuses = r.statuses;
  for (const auto& e : r.status_timeline) in.status_timeline.emplace_back(e.bag_s, e.state);
  in.coverage = r.coverage;
  return mvis::writeReport(dir, in);
}

}  // namespace mvis_offline
