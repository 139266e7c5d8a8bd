// The mvis nodelet: loads the rig, subscribes to every sensor in it, and publishes odometry,
// TF, the calibration and diagnostics. It converts and forwards; the work happens in the core.
#pragma once

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <image_transport/image_transport.h>
#include <mvis/SaveCalibration.h>
#include <mvis/TagDetectionArray.h>
#include <nav_msgs/Path.h>
#include <nodelet/nodelet.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <ros/spinner.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/transform_broadcaster.h>

#include <array>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mvis/common/serial_worker.h"
#include "mvis/estimator/calibration_status.h"
#include "mvis/estimator/estimator.h"
#include "mvis/estimator/odometry_propagator.h"
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

  // On the IMU's own callback queue and thread (imu_spinner_): never behind an image or a solve.
  void onImu(std::size_t sensor, const ros::MessageEvent<sensor_msgs::Imu const>& event);
  void onImage(std::size_t camera, const sensor_msgs::ImageConstPtr& msg);
  void onCompressed(std::size_t camera, const sensor_msgs::CompressedImageConstPtr& msg);
  // An image of either kind, as 8-bit gray, through the front end and into the estimator.
  void processGray(std::size_t camera, const std_msgs::Header& header, const cv::Mat& gray);
  void onTagDetections(std::size_t camera, const mvis::TagDetectionArrayConstPtr& msg);
  // mvis_nodelet_outputs.cpp: diagnostics, the board's markers, unobservable directions in words
  // ('; '-separated).
  void publishDiagnostics();
  // Odometry's latency and interval since the last call (then cleared), the estimator's
  // backlog.
  diagnostic_msgs::DiagnosticStatus odometryStatus();
  static std::string joinedText(const std::vector<UnobservableCalibration>& unobservable);
  // Called by the estimator (on its thread, under estimator_mutex_) after each solve: the new
  // anchor for odometry, the path, TF of the sensors, the calibration.
  void onUpdate(const EstimatorUpdate& update);
  // With every base reading (odometry_mutex_ held): the newest solved state propagated to it as
  // odometry and the world/board/base TF; `arrival`: when the reading arrived, for the latency.
  void publishOdometry(const EstimatorState& state, ros::WallTime arrival);
  // Hands a call into the estimator to its thread; says so (throttled) when the backlog is
  // full and the message is dropped.
  void toEstimator(const std::string& sensor, std::function<void()> call);
  void publishCalibration();
  // The board's tags as rviz markers in the board frame (latched, once).
  void publishTags();
  // The node's name without the leading '/' ("mvis", "robot1/mvis"): the diagnostics' prefix.
  std::string diagnosticsName() const;
  // Guided calibration (mvis_nodelet_status.cpp), with a new covariance: the statuses
  // updated, logged for calibration_status.csv and published (~calibration_status, the rviz
  // text ~status_markers, each camera's ~<camera>/coverage while subscribed).
  void updateStatus(const EstimatorUpdate& u);
  void publishStatus(const ros::Time& stamp);
  // The base IMU's frame in odometry, TF and the calibration message (~body_frame).
  std::string bodyFrame() const;
  // Writes a result directory: `dir`, or a new <result_dir>/<UTC time> when empty; refuses a
  // directory that exists and is not empty. Empty on success, else what went wrong; `written`
  // gets the directory.
  std::string saveResult(const std::string& dir, std::string* written);
  // saveResult on the estimator's thread, for a service: the reply's message ("saved to DIR"
  // or what went wrong); `written` gets the directory.
  std::string saveForService(const std::string& requested, bool* success, std::string* written);
  bool onSaveCalibration(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  bool onSaveCalibrationTo(mvis::SaveCalibration::Request& request,
                           mvis::SaveCalibration::Response& response);
  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response);
  // Counts a camera message that could not be used and says why (throttled).
  void rejectCameraMessage(std::size_t camera, const std::string& why);
  // Counts the front end's result for a camera message and warns about dropped tags.
  void recordTags(std::size_t camera, const TagFrontendResult& result);
  // After a call into the estimator (estimator_mutex_ held): its complaint logged (throttled);
  // a restart of the window (counters().restarts moved past `restarts`) clears the path and the
  // odometry's anchor and is logged at once.
  void noteEstimatorStatus(long restarts, const Status& status);

  NodeletOptions options_;
  Rig rig_;
  std::string config_error_;  // non-empty when the nodelet stays down

  std::mutex mutex_;                    // guards traffic_
  std::vector<SensorTraffic> traffic_;  // inertial sensors first, then cameras

  std::unique_ptr<TagFrontend> frontend_;

  // Odometry, on the IMU's thread: never waits for a solve.
  std::mutex odometry_mutex_;  // guards the members up to the estimator's
  std::unique_ptr<OdometryPropagator> odometry_;
  Eigen::Matrix<double, 6, 6> last_pose_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix3d last_velocity_covariance_ = Eigen::Matrix3d::Zero();   // v_G [(m/s)^2]
  Eigen::Matrix3d last_gyro_bias_covariance_ = Eigen::Matrix3d::Zero();  // [(rad/s)^2]
  Eigen::Vector3d gravity_G_ = Eigen::Vector3d::Zero();
  // From a base reading's arrival (its receipt by ROS; the callback's start under simulated
  // time) to its odometry message: this diagnostics period's latencies and largest interval
  // between two odometry messages, and the worst since the start [ms]; the worst interval
  // between the arrivals of their readings, which an odometry interval cannot beat.
  struct OdometryTiming {
    std::vector<double> latency_ms;
    // Every latency since the start, in 0.01 ms bins to 100 ms (the last: beyond).
    static constexpr double kBinMs = 0.01;
    std::array<std::uint32_t, 10001> histogram{};
    double max_interval_ms = 0.0;
    double worst_latency_ms = 0.0;
    double worst_interval_ms = 0.0;
    double worst_input_interval_ms = 0.0;
    ros::WallTime last_published, last_arrival;
    std::uint64_t published = 0;
    std::string paused;  // why the last base reading gave no odometry ("" if it did)
  } odometry_timing_;
  ros::CallbackQueue imu_queue_;
  std::unique_ptr<ros::AsyncSpinner> imu_spinner_;
  // The estimator's thread: every call into the estimator (readings, frames, services) runs
  // there, in arrival order.
  std::unique_ptr<SerialWorker> worker_;

  std::mutex estimator_mutex_;  // guards estimator_ and everything below it
  std::unique_ptr<Estimator> estimator_;
  std::string estimator_error_;  // the estimator's last complaint, for diagnostics
  std::string last_change_;      // the last change of a sensor's calibration, for diagnostics
  EstimatorUpdate last_update_;
  bool have_update_ = false;
  TimeNs first_stamp_ns_ = 0;  // the first update's state (base clock), for the report
  std::unique_ptr<CalibrationStatusTracker> status_;
  // Every change of status, [s since first_stamp_ns_], for the report's timeline.
  std::vector<std::pair<double, QuantityState>> status_timeline_;
  // Calibration after every solve and pose covariances, for results; thinned past 5,000 rows a
  // table (~3 and ~2 MB), so that a node left running stays flat.
  EstimateLog estimate_log_{5000};
  nav_msgs::Path path_;
  // What the nodelet listens to and serves.
  struct Inputs {
    std::unique_ptr<image_transport::ImageTransport> image_transport;
    std::unique_ptr<image_transport::ImageTransport> private_image_transport;
    std::vector<ros::Subscriber> subscribers;
    std::vector<image_transport::Subscriber> image_subscribers;
    ros::ServiceServer save_service, save_to_service, reset_service;
  } in_;
  // What it publishes.
  struct Outputs {
    ros::Publisher odometry, path, calibration, tags, diagnostics, status, status_markers;
    std::vector<image_transport::Publisher> debug_images;  // per camera, lazy
    std::vector<image_transport::Publisher> coverage;      // per camera, lazy
    std::unique_ptr<tf2_ros::TransformBroadcaster> tf;
    ros::WallTimer diagnostics_timer;
  } out_;
};

}  // namespace mvis
