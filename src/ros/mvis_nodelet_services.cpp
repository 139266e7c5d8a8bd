// The nodelet's services and its result directory (mvis_nodelet.h). The services run on the
// estimator's thread, after every message that came before them.
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <memory>

#include "mvis/estimator/report.h"
#include "mvis/estimator/result_directory.h"
#include "mvis/ros/mvis_nodelet.h"

namespace mvis {

namespace {

// A new directory under `base` named after the UTC time, with _2, _3 ... when it exists.
std::string newResultDirectory(const std::string& base, std::string* utc) {
  const std::time_t now = std::time(nullptr);
  std::tm t{};
  gmtime_r(&now, &t);
  char name[32], text[32];
  std::strftime(name, sizeof(name), "%Y-%m-%d_%H-%M-%S", &t);
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S UTC", &t);
  *utc = text;
  std::string dir = base + "/" + name;
  for (int n = 2; std::filesystem::exists(dir); ++n) {
    dir = base + "/" + name + "_" + std::to_string(n);
  }
  return dir;
}

}  // namespace

std::string MvisNodelet::saveResult(const std::string& requested, std::string* written) {
  std::string base = options_.result_dir;
  if (base.empty()) {
    const char* ros_home = std::getenv("ROS_HOME");
    const char* home = std::getenv("HOME");
    base = ros_home ? std::string(ros_home) : std::string(home ? home : ".") + "/.ros";
    base += "/mvis_results";
  }
  std::string utc;
  std::string dir = requested;
  if (dir.empty()) {
    dir = newResultDirectory(base, &utc);
  } else {
    newResultDirectory(base, &utc);  // the time only
    std::error_code ec;
    if (std::filesystem::exists(dir, ec) && !std::filesystem::is_empty(dir, ec)) {
      return dir +
             " exists and is not empty: a result is never overwritten (give a new "
             "directory, or none for a new one under ~result_dir)";
    }
  }
  const Status covariance = estimator_->computeCovariance();
  if (!covariance.ok()) NODELET_WARN_STREAM(getName() << ": " << covariance.message());
  const Rig calibration = estimator_->calibration();
  const std::vector<EstimatorState> trajectory = estimator_->trajectory();
  Status status = writeResultDirectory(dir, calibration, trajectory, estimate_log_);
  if (status.ok()) {
    ReportInputs in;
    in.tool = "mvis nodelet " + getName();
    in.source = "live topics";
    in.pass = "online (sliding window)";
    in.written = utc;
    if (!trajectory.empty()) {
      in.first_ns = first_stamp_ns_ > 0 ? first_stamp_ns_ : trajectory.front().stamp_ns;
      in.last_ns = trajectory.back().stamp_ns;
    }
    in.initial = &rig_;
    in.estimate = &calibration;
    in.residuals = estimator_->residualStatistics();
    in.options = options_.estimatorOptions();
    char decimate[32];
    std::snprintf(decimate, sizeof(decimate), "%g", options_.tag_decimate);
    in.extra_options = {{"tag_decimate", decimate},
                        {"tag_full_search_every", std::to_string(options_.tag_full_search_every)},
                        {"camera_input", options_.camera_input}};
    if (have_update_) {
      for (const auto& d : last_update_.unobservable) in.unobservable.push_back(d.text());
    }
    in.changes = estimator_->changes();
    if (!estimator_error_.empty()) in.warnings.push_back("last problem: " + estimator_error_);
    in.counters = estimator_->counters();
    in.sigma_inflation = estimator_->sigmaInflation();
    if (status_) {
      in.statuses = status_->states();
      in.status_timeline = status_timeline_;
      in.coverage = status_->coverage();
    }
    status = writeReport(dir, in);
  }
  if (!status.ok()) return status.message();
  if (requested.empty()) {
    // <result_dir>/latest names the newest.
    std::error_code ec;
    const std::string latest = base + "/latest";
    std::filesystem::remove(latest, ec);
    std::filesystem::create_directory_symlink(std::filesystem::path(dir).filename(), latest, ec);
  }
  if (written != nullptr) *written = dir;
  NODELET_INFO_STREAM(getName() << ": wrote the calibration, report.md, trajectory.tum and the "
                                   "estimate log (calibration.csv, pose_covariance.csv) to "
                                << dir);
  return "";
}

namespace {
// How long a service waits for the estimator's thread to get to it.
constexpr double kServiceTimeoutS = 60.0;
}  // namespace

std::string MvisNodelet::saveForService(const std::string& requested, bool* success,
                                        std::string* written) {
  *success = false;
  if (!estimator_) return "no estimator is running (see the log)";
  auto problem = std::make_shared<std::string>();
  auto directory = std::make_shared<std::string>();
  const bool done = worker_->runAndWait(
      [this, problem, directory, requested] {
        std::lock_guard<std::mutex> lock(estimator_mutex_);
        *problem = saveResult(requested, directory.get());
        if (problem->empty()) publishCalibration();
      },
      kServiceTimeoutS);
  if (!done) {
    return "the estimator did not get to it in time (see the diagnostics' estimator backlog)";
  }
  if (!problem->empty()) return *problem;
  *success = true;
  *written = *directory;
  return "saved to " + *directory;
}

bool MvisNodelet::onSaveCalibration(std_srvs::Trigger::Request&,
                                    std_srvs::Trigger::Response& response) {
  std::string written;
  bool success = false;
  response.message = saveForService("", &success, &written);
  response.success = success;
  return true;
}

bool MvisNodelet::onSaveCalibrationTo(mvis::SaveCalibration::Request& request,
                                      mvis::SaveCalibration::Response& response) {
  bool success = false;
  response.message = saveForService(request.directory, &success, &response.directory);
  response.success = success;
  return true;
}

bool MvisNodelet::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
  if (!estimator_) {
    response.success = false;
    response.message = "no estimator is running (see the log)";
    return true;
  }
  const bool done = worker_->runAndWait(
      [this] {
        std::lock_guard<std::mutex> lock(estimator_mutex_);
        estimator_->reset();
        path_.poses.clear();
        have_update_ = false;
        std::lock_guard<std::mutex> odometry_lock(odometry_mutex_);
        odometry_->setAnchor(PropagationAnchor());
      },
      kServiceTimeoutS);
  if (!done) {
    response.success = false;
    response.message =
        "the estimator did not get to it in time (see the diagnostics' estimator "
        "backlog)";
    return true;
  }
  NODELET_INFO("mvis: reset on request; the window starts over from the trusted calibration");
  response.success = true;
  response.message = "reset; the window starts over from the trusted calibration";
  return true;
}

}  // namespace mvis
