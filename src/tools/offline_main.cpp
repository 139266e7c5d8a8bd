// mvis_offline --config DIR --bag FILE --output DIR [--params FILE]
//              [--imu-chain F] [--cam-chain F] [--target F]
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
// --params reads the nodelet's parameter file (config/mvis.yaml) through the nodelet's own reader;
// flags given on the command line override it.
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
#include "mvis/estimator/report.h"
#include "mvis/estimator/result_directory.h"
#include "mvis/rig/rig_io.h"
#include "mvis/rig/trajectory_io.h"
#include "mvis/ros/nodelet_options.h"
#include "mvis/ros/offline.h"
#include "offline_print.h"

namespace {

using mvis_offline::percentile;
using mvis_offline::printBatch;
using mvis_offline::printUsage;
using mvis_offline::writeReport;

int usage(const char* message) {
  std::fprintf(stderr, "%s\n", message);
  printUsage(stderr);
  return 2;
}

// The --params file's options (or the defaults), with a relative config_dir made relative to
// the file.
mvis::StatusOr<mvis::NodeletOptions> readParams(int argc, char** argv) {
  std::string path;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::string(argv[i]) == "--params") path = argv[i + 1];
  }
  if (path.empty()) return mvis::NodeletOptions();
  auto read = mvis::NodeletOptions::fromYamlFile(path);
  if (!read.ok()) return read;
  mvis::NodeletOptions o = read.value();
  if (!o.config_dir.empty() && o.config_dir.front() != '/') {
    const std::size_t slash = path.rfind('/');
    if (slash != std::string::npos) o.config_dir = path.substr(0, slash + 1) + o.config_dir;
  }
  mvis::NodeletOptions check = o;
  if (check.config_dir.empty()) check.config_dir = ".";  // --config may give it
  if (const std::string problem = check.validate(); !problem.empty()) {
    return mvis::Status::Error(path + ": " + problem);
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  const auto params_read = readParams(argc, argv);
  if (!params_read.ok()) {
    std::fprintf(stderr, "mvis_offline: %s\n", params_read.status().message().c_str());
    return 2;
  }
  const mvis::NodeletOptions& params = params_read.value();
  // The flags below change what the --params file (or the defaults) set.
  mvis::OfflineOptions options;
  options.estimator = params.estimatorOptions();
  options.frontend = params.frontendOptions();
  options.status_targets = params.statusTargets();
  mvis::EstimatorOptions& eo = options.estimator;
  std::string config_dir = params.config_dir, bag_path, output_dir, truth_dir;
  std::string imu_chain = params.imu_chain, cam_chain = params.cam_chain, target = params.target;
  // Offline there is no deadline: without the per-solve time budget, results do not depend on
  // the machine's load (unless --max-solve-time asks for the nodelet's).
  eo.max_solve_time_s = 1e3;
  eo.init_solve_time_s = 1e3;
  bool batch = false;
  int batch_iterations = options.batch_iterations;
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
    if (arg == "--params") {
      ++i;  // read before the loop
    } else if (arg == "--image-threads") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1)
        return usage("--image-threads takes a count >= 1");
      options.image_threads = std::atoi(v.c_str());
    } else if (arg == "--tag-decimate") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 1.0)) return usage("--tag-decimate takes >= 1");
      options.frontend.detector.decimate = std::atof(v.c_str());
    } else if (arg == "--tag-full-search-every") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) {
        return usage("--tag-full-search-every takes a count >= 1");
      }
      options.frontend.full_search_every = std::atoi(v.c_str());
    } else if (arg == "--config") {
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
      eo.pixel_sigma_px = std::atof(v.c_str());
    } else if (arg == "--robust-loss") {
      std::string v;
      if (!value(&v) || (v != "frame" && v != "corner"))
        return usage("--robust-loss takes frame or corner");
      eo.robust_loss = v == "corner" ? mvis::RobustLoss::kCorner : mvis::RobustLoss::kFrame;
    } else if (arg == "--huber") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0)) return usage("--huber takes sigmas >= 0");
      eo.huber_sigma = std::atof(v.c_str());
    } else if (arg == "--max-solve-time") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) > 0.0)) {
        return usage("--max-solve-time takes seconds > 0");
      }
      eo.max_solve_time_s = std::atof(v.c_str());
    } else if (arg == "--threads") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) return usage("--threads takes a count >= 1");
      eo.threads = std::atoi(v.c_str());
    } else if (arg == "--no-own-tags") {
      eo.window_own_tags = false;
    } else if (arg == "--carried-tags") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 0) return usage("--carried-tags takes a count >= 0");
      eo.carried_tags = std::atoi(v.c_str());
    } else if (arg == "--window") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 3) return usage("--window takes a state count >= 3");
      eo.window_size = std::atoi(v.c_str());
    } else if (arg == "--solve-every") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) return usage("--solve-every takes a count >= 1");
      eo.solve_every = std::atoi(v.c_str());
    } else if (arg == "--max-iterations") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) {
        return usage("--max-iterations takes a count >= 1");
      }
      eo.max_iterations = std::atoi(v.c_str());
    } else if (arg == "--aux-model") {
      std::string v;
      if (!value(&v) || (v != "velocity_state" && v != "rigid_velocity")) {
        return usage("--aux-model takes velocity_state or rigid_velocity");
      }
      eo.aux_imu_model = v == "rigid_velocity" ? mvis::AuxImuModel::kRigidVelocity
                                               : mvis::AuxImuModel::kVelocityState;
    } else if (arg == "--observability-ratio" || arg == "--imu-observability-ratio" ||
               arg == "--window-observability-ratio") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0)) {
        return usage((arg + " takes a number >= 0").c_str());
      }
      (arg == "--observability-ratio"       ? eo.observability_ratio
       : arg == "--imu-observability-ratio" ? eo.imu_intrinsics_observability_ratio
                                            : eo.window_observability_ratio) = std::atof(v.c_str());
    } else if (arg == "--estimate-intrinsics") {
      eo.estimate_intrinsics = true;
    } else if (arg == "--estimate-imu-intrinsics") {
      eo.estimate_imu_intrinsics = true;
    } else if (arg == "--estimate-gravity-sensitivity") {
      eo.estimate_gravity_sensitivity = true;
    } else if (arg == "--fixed-imu-linearization") {
      eo.imu_intrinsics_linearization = mvis::IntrinsicsLinearization::kFixed;
    } else if (arg == "--imu-step") {
      std::string v;
      if (!value(&v) || !(std::atof(v.c_str()) >= 0.0))
        return usage("--imu-step takes seconds >= 0");
      eo.imu_integration_step_s = std::atof(v.c_str());
    } else if (arg == "--propagation-noise") {
      eo.propagation_noise = true;
    } else if (arg == "--no-change-detection") {
      eo.detect_changes = false;
    } else if (arg == "--hold") {
      std::string v;
      if (!value(&v)) return usage("--hold takes SENSOR.QUANTITY, e.g. cam1.intrinsics");
      eo.hold.push_back(v);
    } else if (arg == "--failure-step-sigma" || arg == "--frame-gate-sigma") {
      std::string v;
      const double s = value(&v) ? std::atof(v.c_str()) : -1.0;
      if (!(s == 0.0 || s >= 3.0)) return usage((arg + " takes 0 (off) or sigmas >= 3").c_str());
      (arg == "--failure-step-sigma" ? eo.failure_step_sigma : eo.frame_gate_sigma) = s;
    } else if (arg == "--batch") {
      batch = true;
    } else if (arg == "--batch-covariance") {
      std::string v;
      if (!value(&v) || (v != "clustered" && v != "model")) {
        return usage("--batch-covariance takes clustered or model");
      }
      eo.batch_covariance =
          v == "model" ? mvis::BatchCovariance::kModel : mvis::BatchCovariance::kClustered;
    } else if (arg == "--batch-iterations") {
      std::string v;
      if (!value(&v) || std::atoi(v.c_str()) < 1) {
        return usage("--batch-iterations takes a count >= 1");
      }
      batch_iterations = std::atoi(v.c_str());
    } else if (arg == "--interpolation") {
      std::string v;
      if (!value(&v) || (v != "imu" && v != "report")) {
        return usage("--interpolation takes imu or report");
      }
      eo.interpolation =
          v == "imu" ? mvis::FrameInterpolation::kImu : mvis::FrameInterpolation::kReport;
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
    mvis::Status saved_online =
        mvis::writeResultDirectory(output_dir + "/online", online.value().calibration,
                                   online.value().trajectory, online.value().log);
    if (saved_online.ok()) {
      saved_online = writeReport(output_dir + "/online", initial.value(), online.value(), options,
                                 bag_path, "online (sliding window)");
    }
    if (!saved_online.ok()) {
      std::fprintf(stderr, "mvis_offline: %s\n", saved_online.message().c_str());
      return 1;
    }
  }

  mvis::Status saved = mvis::writeResultDirectory(output_dir, r.calibration, r.trajectory, r.log);
  if (saved.ok()) {
    saved = writeReport(
        output_dir, initial.value(), r, options, bag_path,
        batched ? "batch (every state of the recording at once)" : "online (sliding window)");
  }
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
  if (!o.detection_stages.empty()) {
    std::vector<double> quads, reading, corners;
    double total[3] = {0.0, 0.0, 0.0};
    for (const auto& s : o.detection_stages) {
      quads.push_back(s.quads_ms), reading.push_back(s.reading_ms);
      corners.push_back(s.corners_ms);
      total[0] += s.quads_ms, total[1] += s.reading_ms, total[2] += s.corners_ms;
    }
    std::printf(
        "; detection by stage, median/p99 ms (total s): quads %.2f/%.2f (%.2f), codes %.2f/%.2f "
        "(%.2f), corners %.2f/%.2f (%.2f); %.0f%% of the images searched in a predicted region "
        "(%.0f%% of the image)",
        percentile(quads, 0.5), percentile(quads, 0.99), total[0] * 1e-3, percentile(reading, 0.5),
        percentile(reading, 0.99), total[1] * 1e-3, percentile(corners, 0.5),
        percentile(corners, 0.99), total[2] * 1e-3,
        100.0 * o.predicted_images / o.detection_stages.size(),
        o.predicted_images > 0 ? 100.0 * o.searched_fraction_sum / o.predicted_images : 0.0);
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
  // Guided calibration (the online pass): when the rig became ready, or what it still misses.
  {
    double ready_at = -1.0;
    bool ready = false;
    for (const auto& e : o.status_timeline) {
      if (e.state.sensor != "rig") continue;
      ready = e.state.ready;
      ready_at = ready ? e.bag_s : -1.0;
    }
    if (ready) {
      std::printf("\nrig ready at %.1f s of the bag: every estimated quantity converged", ready_at);
    } else if (!o.statuses.empty()) {
      std::printf("\nrig not ready at the end; still missing:");
      for (const mvis::QuantityState& q : o.statuses) {
        if (q.status != mvis::QuantityStatus::kImproving &&
            q.status != mvis::QuantityStatus::kUnobservable) {
          continue;
        }
        std::printf("\n  %s %s: %s (sigma %.3g of %.3g %s)%s%s", q.sensor.c_str(),
                    q.quantity.c_str(), q.statusText().c_str(), q.sigma, q.target, q.unit.c_str(),
                    q.advice.empty() ? "" : ": ", q.advice.c_str());
      }
    }
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
      "\nresult: %s (report.md, kalibr_imu_chain.yaml, kalibr_imucam_chain.yaml, trajectory.tum, "
      "calibration.csv, pose_covariance.csv, calibration_changes.csv%s)\n",
      output_dir.c_str(),
      batched ? ", corner_residuals.csv, inertial_residuals.csv, calibration_model.csv with "
                "--batch-covariance clustered; the online pass's in online/"
              : "");
  return 0;
}
