// The nodelet's services and its result directory (mvis_nodelet.h). The services run on the
// estimator's thread, after every message that came before them.
#include <cstdlib>
#include <memory>

#include "mvis/estimator/result_directory.h"
#include "mvis/ros/mvis_nodelet.h"

namespace mvis {

std::string MvisNodelet::saveResult() {
  std::string dir = options_.result_dir;
  if (dir.empty()) {
    const char* ros_home = std::getenv("ROS_HOME");
    const char* home = std::getenv("HOME");
    dir = ros_home ? std::string(ros_home) : std::string(home ? home : ".") + "/.ros";
    dir += "/mvis_result";
  }
  const Status covariance = estimator_->computeCovariance();
  if (!covariance.ok()) NODELET_WARN_STREAM("mvis: " << covariance.message());
  const Status status =
      writeResultDirectory(dir, estimator_->calibration(), estimator_->trajectory(), estimate_log_);
  if (!status.ok()) return status.message();
  NODELET_INFO_STREAM(
      "mvis: wrote the calibration, trajectory.tum and the estimate log (calibration.csv, "
      "pose_covariance.csv) to "
      << dir);
  return "";
}

namespace {
// How long a service waits for the estimator's thread to get to it.
constexpr double kServiceTimeoutS = 60.0;
}  // namespace

bool MvisNodelet::onSaveCalibration(std_srvs::Trigger::Request&,
                                    std_srvs::Trigger::Response& response) {
  if (!estimator_) {
    response.success = false;
    response.message = "no estimator is running (see the log)";
    return true;
  }
  auto problem = std::make_shared<std::string>();
  const bool done = worker_->runAndWait(
      [this, problem] {
        std::lock_guard<std::mutex> lock(estimator_mutex_);
        *problem = saveResult();
        if (problem->empty()) publishCalibration();
      },
      kServiceTimeoutS);
  response.success = done && problem->empty();
  response.message = !done ? "the estimator did not get to it in time (see the diagnostics' "
                             "estimator backlog)"
                     : problem->empty() ? "saved"
                                        : *problem;
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
