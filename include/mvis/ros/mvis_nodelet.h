// The mvis nodelet: loads the rig, subscribes to every sensor in it, and publishes odometry,
// TF, the calibration and diagnostics. It converts and forwards; the work happens in the core.
#pragma once

#include <image_transport/image_transport.h>
#include <mvis/TagDetectionArray.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/transform_broadcaster.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mvis/estimator/estimator.h"
#include "mvis/frontend/tag_frontend.h"
#include "mvis/rig/estimate_log.h"
#include "mvis/rig/rig.h"
#include "mvis/ros/nodelet_options.h"

namespace mvis {

class MvisNodelet : public nodelet::Nodelet {
 public:
  MvisNodelet() = default;
  // Writes the result directory when the estimator has run.
  ~MvisNodelet() override;

 private:
  // What arrives from one sensor: counts and stamps for diagnostics.
  struct SensorTraffic {
    std::string name;
    std::string topic;
    double nominal_rate_hz = 0.0;
    std::uint64_t received = 0;
    std::uint64_t rejected = 0;
    ros::WallTime last_arrival;
    std::uint64_t received_at_last_report = 0;
    ros::WallTime last_report;
    std::size_t tags_in_last_frame = 0;  // cameras only
    std::uint64_t tags_rejected = 0;     // cameras only: single tags dropped by the checks
  };

  void onInit() override;
  // Leaves the nodelet idle, saying why in the log and in diagnostics.
  void stayDown(const std::string& reason);
  void subscribeSensors();

  void onImu(std::size_t sensor, const sensor_msgs::ImuConstPtr& msg);
  void onImage(std::size_t camera, const sensor_msgs::ImageConstPtr& msg);
  void onCompressed(std::size_t camera, const sensor_msgs::CompressedImageConstPtr& msg);
  // An image of either kind, as 8-bit gray, through the front end and into the estimator.
  void processGray(std::size_t camera, const std_msgs::Header& header, const cv::Mat& gray);
  void onTagDetections(std::size_t camera, const mvis::TagDetectionArrayConstPtr& msg);
  // mvis_nodelet_outputs.cpp: diagnostics, the board's markers, unobservable directions in words
  // ('; '-separated).
  void publishDiagnostics();
  static std::string joinedText(const std::vector<UnobservableCalibration>& unobservable);
  // Called by the estimator (under estimator_mutex_) after each solve.
  void onUpdate(const EstimatorUpdate& update);
  // Called by the estimator (under estimator_mutex_) with every base-IMU reading after the
  // newest window state: odometry and the world/board/base TF at IMU rate.
  void onPropagated(const EstimatorState& state);
  void publishCalibration();
  // The board's tags as rviz markers in the board frame (latched, once).
  void publishTags();
  // Writes the result directory; empty on success, else what went wrong.
  std::string saveResult();
  bool onSaveCalibration(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  // Counts a camera message that could not be used and says why (throttled).
  void rejectCameraMessage(std::size_t camera, const std::string& why);
  // Counts the front end's result for a camera message and warns about dropped tags.
  void recordTags(std::size_t camera, const TagFrontendResult& result);
  // After a call into the estimator (estimator_mutex_ held): its complaint logged (throttled);
  // a restart of the window (counters().restarts moved past `restarts`) clears the path and is
  // logged at once.
  void noteEstimatorStatus(long restarts, const Status& status);

  NodeletOptions options_;
  Rig rig_;
  std::string config_error_;  // non-empty when the nodelet stays down

  std::mutex mutex_;                    // guards traffic_
  std::vector<SensorTraffic> traffic_;  // inertial sensors first, then cameras

  std::unique_ptr<TagFrontend> frontend_;
  std::mutex estimator_mutex_;  // guards estimator_ and everything below it
  std::unique_ptr<Estimator> estimator_;
  std::string estimator_error_;  // the estimator's last complaint, for diagnostics
  EstimatorUpdate last_update_;
  bool have_update_ = false;
  // Calibration after every solve and pose covariances, for results; thinned past 5,000 rows a
  // table (~3 and ~2 MB), so that a node left running stays flat.
  EstimateLog estimate_log_{5000};
  Eigen::Matrix<double, 6, 6> last_pose_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Vector3d last_gyro_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_G_ = Eigen::Vector3d::Zero();
  nav_msgs::Path path_;
  // What the nodelet listens to and serves.
  struct Inputs {
    std::unique_ptr<image_transport::ImageTransport> image_transport;
    std::unique_ptr<image_transport::ImageTransport> private_image_transport;
    std::vector<ros::Subscriber> subscribers;
    std::vector<image_transport::Subscriber> image_subscribers;
    ros::ServiceServer save_service, reset_service;
  } in_;
  // What it publishes.
  struct Outputs {
    ros::Publisher odometry, path, calibration, tags, diagnostics;
    std::vector<image_transport::Publisher> debug_images;  // per camera, lazy
    std::unique_ptr<tf2_ros::TransformBroadcaster> tf;
    ros::WallTimer diagnostics_timer;
  } out_;
};

}  // namespace mvis
