// The nodelet's diagnostics and the board's markers (mvis_nodelet.h).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <cstdio>

#include "mvis/ros/mvis_nodelet.h"

namespace mvis {
namespace {

// Named after the node ("<node name>: <part>", hardware_id the node's name), so that two
// instances' diagnostics stay apart.
diagnostic_msgs::DiagnosticStatus makeStatus(const std::string& node, std::uint8_t level,
                                             const std::string& name, const std::string& message) {
  diagnostic_msgs::DiagnosticStatus status;
  status.level = level;
  status.name = node + ": " + name;
  status.hardware_id = node;
  status.message = message;
  return status;
}

}  // namespace

std::string MvisNodelet::diagnosticsName() const {
  const std::string& name = getName();
  return !name.empty() && name.front() == '/' ? name.substr(1) : name;
}

// What an update says the motion leaves unobservable, in words, '; '-separated.
std::string MvisNodelet::joinedText(const std::vector<UnobservableCalibration>& unobservable) {
  std::string out;
  for (const auto& d : unobservable) out += (out.empty() ? "" : "; ") + d.text();
  return out;
}

void MvisNodelet::publishDiagnostics() {
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  if (!config_error_.empty()) {
    array.status.push_back(makeStatus(diagnosticsName(), diagnostic_msgs::DiagnosticStatus::ERROR,
                                      "configuration", config_error_));
    out_.diagnostics.publish(array);
    return;
  }
  array.status.push_back(makeStatus(diagnosticsName(), diagnostic_msgs::DiagnosticStatus::OK,
                                    "configuration", "loaded " + options_.config_dir));
  if (estimator_) {
    std::lock_guard<std::mutex> lock(estimator_mutex_);
    const bool running = estimator_->initialized();
    auto status = makeStatus(
        diagnosticsName(),
        running ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::WARN,
        "estimator", estimator_->status());
    auto add = [&status](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      status.values.push_back(kv);
    };
    if (have_update_) {
      add("solve_ms", std::to_string(last_update_.solve.total_s * 1e3));
      add("iterations", std::to_string(last_update_.solve.iterations));
      add("window_states", std::to_string(last_update_.solve.states));
      add("window_frames", std::to_string(last_update_.solve.frames));
      add("window_corners", std::to_string(last_update_.solve.corners));
    }
    const EstimatorCounters& c = estimator_->counters();
    add("solves", std::to_string(c.solves));
    add("resets", std::to_string(c.resets));
    add("restarts", std::to_string(c.restarts));
    add("failures", std::to_string(c.failures));
    add("frames_rejected", std::to_string(c.frames_rejected));
    add("corners_rejected", std::to_string(c.corners_rejected));
    add("inconsistencies", std::to_string(c.inconsistencies));
    add("held_intrinsics_misfits", std::to_string(c.held_intrinsics_misfits));
    add("sigma_inflation", std::to_string(estimator_->sigmaInflation()));
    add("stamps_implausible", std::to_string(c.stamps_implausible));
    add("calibration_changes", std::to_string(c.calibration_changes));
    if (!last_change_.empty()) add("last_calibration_change", last_change_);
    add("time_offset_floor_ms", std::to_string(estimator_->timeOffsetFloor() * 1e3));
    add("time_offsets_under_floor", std::to_string(c.time_offsets_under_floor));
    const std::string restart = estimator_->lastRestart().reason;
    if (!restart.empty()) add("last_restart", restart);
    add("frames_dropped", std::to_string(c.frames_too_old + c.frames_too_close +
                                         c.frames_out_of_order + c.frames_in_imu_gap));
    add("frames_too_few_tags", std::to_string(c.frames_too_few_tags));
    add("imu_dropped", std::to_string(c.imu_out_of_order + c.imu_non_finite));
    add("imu_gaps", std::to_string(c.imu_gaps));
    add("clock_corrections", std::to_string(c.clock_corrections));
    if (rig_.inertial.size() > 1) {
      add("aux_dropped", std::to_string(c.aux_dropped));
      add("aux_dropouts", std::to_string(c.aux_dropouts));
      add("aux_starts", std::to_string(c.aux_starts));
    }
    if (have_update_) {
      const std::string unobservable = joinedText(last_update_.unobservable);
      add("unobservable", unobservable.empty() ? "none" : unobservable);
      if (!unobservable.empty()) status.level = diagnostic_msgs::DiagnosticStatus::WARN;
    }
    if (!estimator_error_.empty()) add("last_problem", estimator_error_);
    array.status.push_back(status);
    array.status.push_back(odometryStatus());
  }
  const ros::WallTime now = ros::WallTime::now();
  std::lock_guard<std::mutex> lock(mutex_);
  for (SensorTraffic& t : traffic_) {
    const double elapsed = (now - t.last_report).toSec();
    const double rate = elapsed > 0.0 ? (t.received - t.received_at_last_report) / elapsed : 0.0;
    t.received_at_last_report = t.received;
    t.last_report = now;
    char text[160];
    std::uint8_t level = diagnostic_msgs::DiagnosticStatus::OK;
    if (t.received == 0 && t.rejected == 0) {
      level = diagnostic_msgs::DiagnosticStatus::WARN;
      std::snprintf(text, sizeof(text), "no data yet on %s", t.topic.c_str());
    } else if ((now - t.last_arrival).toSec() > options_.sensor_timeout_s) {
      level = diagnostic_msgs::DiagnosticStatus::WARN;
      std::snprintf(text, sizeof(text), "stopped: nothing on %s for %.1f s", t.topic.c_str(),
                    (now - t.last_arrival).toSec());
    } else {
      std::snprintf(text, sizeof(text), "%.1f Hz on %s", rate, t.topic.c_str());
    }
    auto status = makeStatus(diagnosticsName(), level, t.name, text);
    const auto add = [&status](const char* key, std::uint64_t value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = std::to_string(value);
      status.values.push_back(kv);
    };
    add("received", t.received);
    add("rejected", t.rejected);
    if (&t - traffic_.data() >= static_cast<std::ptrdiff_t>(rig_.inertial.size())) {
      add("tags_in_last_frame", t.tags_in_last_frame);
      add("tags_rejected", t.tags_rejected);
    }
    array.status.push_back(status);
  }
  out_.diagnostics.publish(array);
}

diagnostic_msgs::DiagnosticStatus MvisNodelet::odometryStatus() {
  const SerialWorker::Backlog backlog = worker_->backlog();
  std::lock_guard<std::mutex> lock(odometry_mutex_);
  OdometryTiming& t = odometry_timing_;
  std::vector<double>& latency = t.latency_ms;
  const auto quantile = [&latency](double q) {
    if (latency.empty()) return 0.0;
    const std::size_t k = static_cast<std::size_t>(q * static_cast<double>(latency.size() - 1));
    std::nth_element(latency.begin(), latency.begin() + static_cast<std::ptrdiff_t>(k),
                     latency.end());
    return latency[k];
  };
  char text[200];
  std::uint8_t level = diagnostic_msgs::DiagnosticStatus::OK;
  // The estimator more than a second behind: odometry still flows, from an older state.
  if (backlog.oldest_s > 1.0) level = diagnostic_msgs::DiagnosticStatus::WARN;
  if (!t.paused.empty()) {
    level = diagnostic_msgs::DiagnosticStatus::WARN;
    std::snprintf(text, sizeof(text), "paused: %s", t.paused.c_str());
  } else {
    std::snprintf(text, sizeof(text), "latency p50 %.2f ms, p99 %.2f ms; estimator %.2f s behind",
                  quantile(0.5), quantile(0.99), backlog.oldest_s);
  }
  auto status = makeStatus(diagnosticsName(), level, "odometry", text);
  const auto add = [&status](const char* key, double value) {
    diagnostic_msgs::KeyValue kv;
    kv.key = key;
    kv.value = std::to_string(value);
    status.values.push_back(kv);
  };
  // Since the last diagnostics, then since the start.
  add("latency_p50_ms", quantile(0.5));
  add("latency_p99_ms", quantile(0.99));
  add("latency_max_ms", quantile(1.0));
  add("max_interval_ms", t.max_interval_ms);
  // Since the start, from the histogram (to its 0.01 ms bins).
  const auto since_start = [&t](double q) {
    std::uint64_t total = 0;
    for (std::uint32_t n : t.histogram) total += n;
    const auto rank = static_cast<std::uint64_t>(q * static_cast<double>(total));
    std::uint64_t seen = 0;
    for (std::size_t b = 0; b < t.histogram.size(); ++b) {
      seen += t.histogram[b];
      if (seen > rank) return static_cast<double>(b + 1) * OdometryTiming::kBinMs;
    }
    return 0.0;
  };
  add("latency_p50_ms_since_start", since_start(0.5));
  add("latency_p99_ms_since_start", since_start(0.99));
  add("worst_latency_ms", t.worst_latency_ms);
  add("worst_interval_ms", t.worst_interval_ms);
  add("worst_reading_interval_ms", t.worst_input_interval_ms);
  add("published", static_cast<double>(t.published));
  add("estimator_backlog_s", backlog.oldest_s);
  add("estimator_backlog_messages", static_cast<double>(backlog.tasks));
  add("messages_dropped_backlog_full", static_cast<double>(backlog.refused));
  latency.clear();
  t.max_interval_ms = 0.0;
  return status;
}

void MvisNodelet::publishTags() {
  std::map<int, std::array<Eigen::Vector3d, 4>> tags;
  if (rig_.target) {
    for (int id = 0; id < rig_.target->numTags(); ++id) {
      for (int k = 0; k < 4; ++k) tags[id][k] = rig_.target->corner(id, k);
    }
  } else if (estimator_) {
    tags = estimator_->landmarks();
  }
  if (tags.empty()) return;
  visualization_msgs::MarkerArray array;
  visualization_msgs::Marker squares;
  squares.header.frame_id = options_.frame_prefix + "board";
  // Stamp zero: the board does not move, rviz takes the latest transform. A stamp of "now" is 0
  // under sim time before a replayed bag's clock starts (the tags are latched at start) or lies
  // behind the bag's TF: rviz then looks for a transform at that time forever and shows the
  // Tags display in error.
  squares.header.stamp = ros::Time();
  squares.ns = "tags";
  squares.id = 0;
  squares.type = visualization_msgs::Marker::TRIANGLE_LIST;
  squares.action = visualization_msgs::Marker::ADD;
  squares.pose.orientation.w = 1.0;
  squares.frame_locked = true;  // the board frame moves in the world frame as gravity is refined
  squares.scale.x = squares.scale.y = squares.scale.z = 1.0;
  squares.color.r = squares.color.g = squares.color.b = 0.1f;
  squares.color.a = 1.0f;
  auto point = [](const Eigen::Vector3d& p) {
    geometry_msgs::Point q;
    q.x = p.x();
    q.y = p.y();
    q.z = p.z();
    return q;
  };
  for (const auto& [id, c] : tags) {
    for (int k : {0, 1, 2, 0, 2, 3}) squares.points.push_back(point(c[k]));
    visualization_msgs::Marker label;
    label.header = squares.header;
    label.frame_locked = true;
    label.ns = "tag_ids";
    label.id = id;
    label.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    label.action = visualization_msgs::Marker::ADD;
    label.pose.position = point(0.25 * (c[0] + c[1] + c[2] + c[3]));
    label.pose.position.z += 0.01;
    label.pose.orientation.w = 1.0;
    label.scale.z = 0.5 * (c[1] - c[0]).norm();
    label.color.r = 1.0f;
    label.color.g = 0.6f;
    label.color.a = 1.0f;
    label.text = std::to_string(id);
    array.markers.push_back(label);
  }
  array.markers.push_back(squares);
  out_.tags.publish(array);
}

}  // namespace mvis
