#include "mvis/ros/mvis_nodelet.h"

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/TransformStamped.h>
#include <mvis/CalibrationStatus.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <sensor_msgs/image_encodings.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <pluginlib/class_list_macros.hpp>

#include "mvis/common/lie.h"
#include "mvis/frontend/debug_image.h"
#include "mvis/rig/rig_io.h"
#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

geometry_msgs::TransformStamped stampedTransform(const SE3& T, const ros::Time& stamp,
                                                 const std::string& parent,
                                                 const std::string& child) {
  geometry_msgs::TransformStamped out;
  out.header.stamp = stamp;
  out.header.frame_id = parent;
  out.child_frame_id = child;
  out.transform = ros_conversions::toTransformMsg(T);
  return out;
}

// Messages waiting for the estimator's thread at most: ~25 s of the VI-Rig's (500 + 100 + 200 Hz
// readings, three cameras at 20 Hz). Beyond it a message is dropped and said.
constexpr std::size_t kMaxBacklog = 20000;

// The gravity-aligned world frame {W} (z up) over the board frame {G} the estimator works in:
// the smallest rotation taking gravity in {G} to -z, origin at the board's.
SE3 worldFromBoard(const Eigen::Vector3d& gravity_G) {
  if (!(gravity_G.norm() > 0.0)) return SE3();
  return SE3(Eigen::Quaterniond::FromTwoVectors(gravity_G, Eigen::Vector3d(0, 0, -1)),
             Eigen::Vector3d::Zero());
}

}  // namespace

void MvisNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  out_.diagnostics = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);

  options_ = NodeletOptions::fromParameters(pnh);
  if (const std::string problem = options_.validate(); !problem.empty()) {
    stayDown(problem);
    return;
  }
  std::vector<std::string> warnings;
  auto rig = loadRig(
      RigFiles::in(options_.config_dir, options_.imu_chain, options_.cam_chain, options_.target),
      &warnings);
  for (const auto& w : warnings) NODELET_WARN_STREAM("mvis: " << w);
  if (!rig.ok()) {
    stayDown(rig.status().message());
    return;
  }
  rig_ = std::move(rig).value();
  NODELET_INFO_STREAM("mvis: loaded the rig from " << options_.config_dir << ":\n"
                                                   << rig_.summary());

  out_.odometry = pnh.advertise<nav_msgs::Odometry>("odometry", 100);
  out_.path = pnh.advertise<nav_msgs::Path>("path", 1, true);
  out_.calibration = pnh.advertise<mvis::Calibration>("calibration", 1, true);
  out_.status = pnh.advertise<mvis::CalibrationStatus>("calibration_status", 1, true);
  out_.status_markers = pnh.advertise<visualization_msgs::MarkerArray>("status_markers", 1, true);
  // Until the estimator has run, the calibration is the configured one, its uncertainty
  // not yet known (NaN standard deviations).
  mvis::Calibration calibration = ros_conversions::toCalibrationMsg(rig_, options_.frame_prefix);
  calibration.header.frame_id = bodyFrame();
  if (!calibration.inertial.empty()) calibration.inertial[0].frame_id = bodyFrame();
  calibration.header.stamp = ros::Time();  // no estimate yet
  out_.calibration.publish(calibration);

  const TagFrontendOptions frontend_options = options_.frontendOptions();
  auto frontend = TagFrontend::create(rig_, frontend_options);
  if (!frontend.ok()) {
    stayDown(frontend.status().message());
    return;
  }
  frontend_ = std::move(frontend).value();

  {
    const EstimatorOptions eo = options_.estimatorOptions();
    auto estimator = Estimator::create(rig_, eo);
    if (!estimator.ok()) {
      stayDown(estimator.status().message());
      return;
    }
    estimator_ = std::move(estimator).value();
    status_ = std::make_unique<CalibrationStatusTracker>(rig_, eo, options_.statusTargets());
    estimator_->setUpdateCallback([this](const EstimatorUpdate& u) { onUpdate(u); });
    odometry_ = std::make_unique<OdometryPropagator>(rig_.inertial[0], eo.imu_integration_step_s);
    worker_ = std::make_unique<SerialWorker>(kMaxBacklog);
  }
  if (!rig_.target) {
    NODELET_INFO_STREAM("mvis: " << options_.config_dir
                                 << " has no aprilgrid.yaml: tag corners are estimated as "
                                    "landmarks");
  }
  out_.tf = std::make_unique<tf2_ros::TransformBroadcaster>();
  out_.tags = pnh.advertise<visualization_msgs::MarkerArray>("tags", 1, true);
  publishTags();
  path_.header.frame_id = options_.world_frame;
  in_.save_service =
      pnh.advertiseService("save_calibration", &MvisNodelet::onSaveCalibration, this);
  in_.save_to_service =
      pnh.advertiseService("save_calibration_to", &MvisNodelet::onSaveCalibrationTo, this);
  in_.reset_service = pnh.advertiseService("reset", &MvisNodelet::onReset, this);

  subscribeSensors();
  // With a board its markers go out again with every diagnostics (latched as well): rviz drops a
  // marker whose frame it cannot transform when it arrives (the board frame exists only once
  // the estimator runs; on a replay the Tags display stayed in error, "Unknown reason for
  // transform failure") and forgets every marker when the clock jumps back (a bag looped).
  out_.diagnostics_timer = nh.createWallTimer(ros::WallDuration(options_.diagnostics_period_s),
                                              [this](const ros::WallTimerEvent&) {
                                                publishDiagnostics();
                                                if (rig_.target) publishTags();
                                              });
}

std::string MvisNodelet::bodyFrame() const {
  return options_.body_frame.empty() ? options_.frame_prefix + rig_.inertial[0].name
                                     : options_.body_frame;
}

void MvisNodelet::stayDown(const std::string& reason) {
  config_error_ = reason;
  NODELET_ERROR_STREAM("mvis: not starting: " << reason);
  out_.diagnostics_timer = getNodeHandle().createWallTimer(
      ros::WallDuration(options_.diagnostics_period_s > 0.0 ? options_.diagnostics_period_s : 1.0),
      [this](const ros::WallTimerEvent&) { publishDiagnostics(); });
}

void MvisNodelet::subscribeSensors() {
  ros::NodeHandle& nh = getNodeHandle();
  const ros::WallTime now = ros::WallTime::now();
  // The IMUs have a queue and a thread of their own: odometry waits for no image and no solve.
  ros::NodeHandle imu_nh(nh);
  imu_nh.setCallbackQueue(&imu_queue_);
  for (std::size_t i = 0; i < rig_.inertial.size(); ++i) {
    const auto& s = rig_.inertial[i];
    traffic_.push_back({s.name, s.rostopic, s.update_rate, 0, 0, {}, 0, now});
    in_.subscribers.push_back(imu_nh.subscribe<sensor_msgs::Imu>(
        s.rostopic, 2000,
        boost::function<void(const ros::MessageEvent<sensor_msgs::Imu const>&)>(
            [this, i](const ros::MessageEvent<sensor_msgs::Imu const>& event) { onImu(i, event); }),
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay()));
  }
  imu_spinner_ = std::make_unique<ros::AsyncSpinner>(1, &imu_queue_);
  imu_spinner_->start();
  // With more than one tag thread (by default one per core) the cameras' images are decoded
  // and detected on the nodelet manager's multi-threaded queue, in parallel (one camera's
  // frames still one at a time and in order: the front end predicts where the tags are from
  // the camera's previous frames).
  ros::NodeHandle& image_nh = options_.tagThreads() > 1 ? getMTNodeHandle() : nh;
  in_.image_transport = std::make_unique<image_transport::ImageTransport>(image_nh);
  in_.private_image_transport =
      std::make_unique<image_transport::ImageTransport>(getPrivateNodeHandle());
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    const auto& cam = rig_.cameras[c];
    out_.debug_images.push_back(
        in_.private_image_transport->advertise(cam.name + "/debug_image", 1));
    out_.coverage.push_back(in_.private_image_transport->advertise(cam.name + "/coverage", 1));
    if (options_.camera_input == "image") {
      traffic_.push_back({cam.name, cam.rostopic, 0.0, 0, 0, {}, 0, now});
      in_.image_subscribers.push_back(in_.image_transport->subscribe(
          cam.rostopic, 20, [this, c](const sensor_msgs::ImageConstPtr& msg) { onImage(c, msg); }));
    } else if (options_.camera_input == "compressed") {
      // Decoded here: Debian has no compressed_image_transport plugin.
      const std::string topic = cam.rostopic + "/compressed";
      traffic_.push_back({cam.name, topic, 0.0, 0, 0, {}, 0, now});
      in_.subscribers.push_back(image_nh.subscribe<sensor_msgs::CompressedImage>(
          topic, 20,
          [this, c](const sensor_msgs::CompressedImageConstPtr& msg) { onCompressed(c, msg); }));
    } else {
      const std::string topic = cam.rostopic + "/tag_detections";
      traffic_.push_back({cam.name, topic, 0.0, 0, 0, {}, 0, now});
      in_.subscribers.push_back(nh.subscribe<mvis::TagDetectionArray>(
          topic, 50,
          [this, c](const mvis::TagDetectionArrayConstPtr& msg) { onTagDetections(c, msg); }));
    }
  }
}

void MvisNodelet::onImu(std::size_t sensor,
                        const ros::MessageEvent<sensor_msgs::Imu const>& event) {
  // Under simulated time the receipt stamp is the bag's clock: the callback's start then.
  ros::WallTime arrival = ros::WallTime::now();
  const ros::Time receipt = event.getReceiptTime();
  if (!ros::Time::isSimTime() && !receipt.isZero()) {
    arrival = std::min(arrival, ros::WallTime(receipt.sec, receipt.nsec));
  }
  const auto& s = rig_.inertial[sensor];
  ImuMeasurement reading;
  std::string why;
  const bool usable = ros_conversions::toImuMeasurement(
      *event.getConstMessage(), s.type == InertialType::kGyroscope, &reading, &why);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    SensorTraffic& t = traffic_[sensor];
    t.last_arrival = ros::WallTime::now();
    if (!usable) {
      ++t.rejected;
      NODELET_WARN_STREAM_THROTTLE(
          5.0, "mvis: " << s.name << " (" << s.rostopic << "): dropped " << why);
      return;
    }
    ++t.received;
  }
  if (!estimator_) return;
  if (sensor == 0) {
    std::lock_guard<std::mutex> lock(odometry_mutex_);
    if (const auto state = odometry_->add(reading)) {
      publishOdometry(*state, arrival);
      odometry_timing_.paused.clear();
    } else {
      odometry_timing_.paused = odometry_->why();
    }
  }
  toEstimator(s.name, [this, sensor, reading] {
    std::lock_guard<std::mutex> lock(estimator_mutex_);
    const long restarts = estimator_->counters().restarts;
    noteEstimatorStatus(restarts, estimator_->addImu(sensor, reading));
  });
}

void MvisNodelet::toEstimator(const std::string& sensor, std::function<void()> call) {
  if (worker_->push(std::move(call))) return;
  const SerialWorker::Backlog backlog = worker_->backlog();
  if (backlog.tasks < kMaxBacklog) return;  // refused because it stopped: shutting down
  NODELET_WARN_STREAM_THROTTLE(
      5.0, "mvis: the estimator is " << backlog.oldest_s << " s behind the sensors ("
                                     << backlog.tasks << " messages waiting): dropped a message of "
                                     << sensor << " (solves slower than the data come)");
}

void MvisNodelet::noteEstimatorStatus(long restarts, const Status& status) {
  if (estimator_->counters().restarts != restarts) {
    // A gap or jump of the base clock (a bag started over) or a failure found after a solve:
    // the window started over from the trusted calibration, and so does the path. Logged at
    // most once a second: it is rare and important.
    path_.poses.clear();
    have_update_ = false;
    {
      std::lock_guard<std::mutex> lock(odometry_mutex_);
      odometry_->setAnchor(PropagationAnchor());
    }
    estimator_error_ = estimator_->lastRestart().reason;
    NODELET_WARN_STREAM_THROTTLE(1.0, "mvis: " << estimator_error_);
  } else if (!status.ok()) {
    estimator_error_ = status.message();
    NODELET_WARN_STREAM_THROTTLE(5.0, "mvis: " << status.message());
  }
}

void MvisNodelet::onImage(std::size_t camera, const sensor_msgs::ImageConstPtr& msg) {
  cv::Mat gray;
  std::string why;
  if (!ros_conversions::toGray(msg, &gray, &why)) {
    rejectCameraMessage(camera, why);
    return;
  }
  processGray(camera, msg->header, gray);  // gray may share msg's pixels: msg lives until here
}

void MvisNodelet::onCompressed(std::size_t camera,
                               const sensor_msgs::CompressedImageConstPtr& msg) {
  cv::Mat gray;
  std::string why;
  if (!ros_conversions::toGray(*msg, &gray, &why)) {
    rejectCameraMessage(camera, why);
    return;
  }
  processGray(camera, msg->header, gray);
}

void MvisNodelet::processGray(std::size_t camera, const std_msgs::Header& header,
                              const cv::Mat& gray) {
  const auto result =
      frontend_->processImage(camera, ros_conversions::toTimeNs(header.stamp), gray);
  if (!result.ok()) {
    rejectCameraMessage(camera, result.status().message());
    return;
  }
  recordTags(camera, result.value());
  auto& debug_pub = out_.debug_images[camera];
  if (debug_pub.getNumSubscribers() > 0) {
    debug_pub.publish(cv_bridge::CvImage(header, sensor_msgs::image_encodings::BGR8,
                                         drawTagFrame(gray, result.value().frame))
                          .toImageMsg());
  }
}

void MvisNodelet::onTagDetections(std::size_t camera, const mvis::TagDetectionArrayConstPtr& msg) {
  const auto result = frontend_->processDetections(ros_conversions::toTagFrame(*msg, camera));
  if (!result.ok()) {
    rejectCameraMessage(camera, result.status().message());
    return;
  }
  recordTags(camera, result.value());
  // Without the image, what was kept drawn on a grey canvas of the camera's size (rviz's
  // camera displays had nothing to show on a replay of detections).
  auto& debug_pub = out_.debug_images[camera];
  const auto& size = rig_.cameras[camera].resolution;
  if (debug_pub.getNumSubscribers() > 0 && size[0] > 0 && size[1] > 0) {
    const cv::Mat canvas(size[1], size[0], CV_8UC1, cv::Scalar(128));
    debug_pub.publish(cv_bridge::CvImage(msg->header, sensor_msgs::image_encodings::BGR8,
                                         drawTagFrame(canvas, result.value().frame))
                          .toImageMsg());
  }
}

void MvisNodelet::rejectCameraMessage(std::size_t camera, const std::string& why) {
  std::lock_guard<std::mutex> lock(mutex_);
  SensorTraffic& t = traffic_[rig_.inertial.size() + camera];
  t.last_arrival = ros::WallTime::now();
  ++t.rejected;
  NODELET_WARN_STREAM_THROTTLE(5.0, "mvis: " << rig_.cameras[camera].name << " (" << t.topic
                                             << "): dropped a message: " << why);
}

void MvisNodelet::recordTags(std::size_t camera, const TagFrontendResult& result) {
  // The front end's tracks are kept for a second, as mvis_offline keeps them: without this a
  // live node grew by ~0.25 MB/s with three cameras (scripts/soak's nodelet run).
  frontend_->dropBefore(camera, result.frame.stamp_ns - kNsPerSecond);
  if (estimator_) {
    toEstimator(rig_.cameras[camera].name, [this, frame = result.frame] {
      std::lock_guard<std::mutex> lock(estimator_mutex_);
      const long restarts = estimator_->counters().restarts;
      const Status added = estimator_->addTagFrame(frame);
      if (added.ok() && status_) status_->addFrame(frame);
      noteEstimatorStatus(restarts, added);
    });
  }
  std::lock_guard<std::mutex> lock(mutex_);
  SensorTraffic& t = traffic_[rig_.inertial.size() + camera];
  t.last_arrival = ros::WallTime::now();
  ++t.received;
  t.tags_in_last_frame = result.frame.tags.size();
  t.tags_rejected += result.rejections.total();
  if (result.rejections.total() > 0) {
    NODELET_WARN_STREAM_THROTTLE(5.0,
                                 "mvis: " << rig_.cameras[camera].name << " (" << t.topic
                                          << "): dropped tags: " << result.rejections.describe());
  }
}

MvisNodelet::~MvisNodelet() {
  if (imu_spinner_) imu_spinner_->stop();
  if (worker_) {
    const std::size_t dropped = worker_->stop();
    if (dropped > 0) {
      std::fprintf(stderr, "mvis: shutting down: %zu messages the estimator had not taken yet\n",
                   dropped);
    }
  }
  if (!estimator_ || !options_.save_on_shutdown) return;
  std::lock_guard<std::mutex> lock(estimator_mutex_);
  if (!estimator_->initialized() && estimator_->trajectory().empty()) return;
  std::string written;
  const std::string problem = saveResult("", &written);
  if (!problem.empty()) {
    std::fprintf(stderr, "mvis: could not write the result: %s\n", problem.c_str());
  } else {
    std::fprintf(stderr, "mvis: shutting down: the result is in %s\n", written.c_str());
  }
}

void MvisNodelet::onUpdate(const EstimatorUpdate& u) {
  const std::string unobservable = joinedText(u.unobservable);
  const std::string before = have_update_ ? joinedText(last_update_.unobservable) : std::string();
  if (unobservable != before) {
    if (!unobservable.empty()) {
      NODELET_WARN_STREAM_THROTTLE(
          5.0, "mvis: the recent motion cannot calibrate " << unobservable << " (held)");
    } else {
      NODELET_INFO_STREAM_THROTTLE(5.0,
                                   "mvis: the motion makes every calibration observable again");
    }
  }
  last_update_ = u;
  have_update_ = true;
  if (first_stamp_ns_ == 0) first_stamp_ns_ = u.state.stamp_ns;
  {
    // The new anchor's readings integrated here, on the estimator's thread, not the IMU's.
    PreparedAnchor anchor;
    {
      std::lock_guard<std::mutex> lock(odometry_mutex_);
      anchor = odometry_->prepare(u.anchor);
    }
    anchor.integrate();
    std::lock_guard<std::mutex> lock(odometry_mutex_);
    odometry_->install(std::move(anchor));
    gravity_G_ = u.gravity_G;
    if (u.pose_covariance.allFinite()) last_pose_covariance_ = u.pose_covariance;
    if (u.velocity_covariance.allFinite()) last_velocity_covariance_ = u.velocity_covariance;
    if (u.gyro_bias_covariance.allFinite()) last_gyro_bias_covariance_ = u.gyro_bias_covariance;
  }
  const ros::Time stamp = ros_conversions::toRosTime(u.state.stamp_ns);
  const std::string base = bodyFrame();
  std::vector<geometry_msgs::TransformStamped> transforms;
  const Rig calibration = estimator_->calibration();
  if (u.solve.iterations > 0) estimate_log_.addCalibration(u.state.stamp_ns, calibration);
  estimate_log_.addPose(u.state.stamp_ns, u.state.T_G_I, u.pose_covariance);
  for (std::size_t i = 0; i < u.changes.size(); ++i) {
    const CalibrationChange& c = u.changes[i];
    estimate_log_.addChange(c.stamp_ns, c.sensor, c.quantity, c.size, c.size_sigma);
    if (i == 0 || c.text != u.changes[i - 1].text) {
      // Rare and important (a sensor moved): said each time, not throttled.
      NODELET_WARN_STREAM("mvis: " << c.text);
      last_change_ = c.text;
    }
  }
  for (const auto& cam : calibration.cameras) {
    transforms.push_back(
        stampedTransform(cam.T_cam_imu.inverse(), stamp, base, options_.frame_prefix + cam.name));
  }
  for (std::size_t i = 1; i < calibration.inertial.size(); ++i) {
    const InertialSensor& s = calibration.inertial[i];
    transforms.push_back(
        stampedTransform(s.T_i_b.inverse(), stamp, base, options_.frame_prefix + s.name));
  }
  if (options_.publish_tf) out_.tf->sendTransform(transforms);
  // Without a board the tags are estimates: republished after every solve.
  if (!rig_.target && u.solve.iterations > 0) publishTags();

  geometry_msgs::PoseStamped pose;
  pose.header.stamp = stamp;
  pose.header.frame_id = options_.world_frame;
  const SE3 T_W_I = worldFromBoard(u.gravity_G) * u.state.T_G_I;
  pose.pose.position.x = T_W_I.p.x();
  pose.pose.position.y = T_W_I.p.y();
  pose.pose.position.z = T_W_I.p.z();
  pose.pose.orientation.x = T_W_I.q.x();
  pose.pose.orientation.y = T_W_I.q.y();
  pose.pose.orientation.z = T_W_I.q.z();
  pose.pose.orientation.w = T_W_I.q.w();
  path_.header.stamp = stamp;
  path_.poses.push_back(pose);
  if (path_.poses.size() > 20000) {
    path_.poses.erase(path_.poses.begin(), path_.poses.begin() + 1000);
  }
  if (path_.poses.size() % 30 == 0) out_.path.publish(path_);
  if (u.calibration_covariance_updated || !u.changes.empty()) publishCalibration();
  if (u.calibration_covariance_updated) updateStatus(u);
}

void MvisNodelet::publishOdometry(const EstimatorState& state, ros::WallTime arrival) {
  const ros::Time stamp = ros_conversions::toRosTime(state.stamp_ns);
  const std::string board = options_.frame_prefix + "board";
  const std::string base = bodyFrame();
  const SE3 T_W_G = worldFromBoard(gravity_G_);
  const SE3 T_W_I = T_W_G * state.T_G_I;

  nav_msgs::Odometry odom;
  odom.header.stamp = stamp;
  odom.header.frame_id = options_.world_frame;
  odom.child_frame_id = base;
  odom.pose.pose.position.x = T_W_I.p.x();
  odom.pose.pose.position.y = T_W_I.p.y();
  odom.pose.pose.position.z = T_W_I.p.z();
  odom.pose.pose.orientation.x = T_W_I.q.x();
  odom.pose.pose.orientation.y = T_W_I.q.y();
  odom.pose.pose.orientation.z = T_W_I.q.z();
  odom.pose.pose.orientation.w = T_W_I.q.w();
  // Covariance in ROS order (x y z, then rotation about x y z), all in {W}: the estimator's
  // [dtheta (body), dp (board)] of the newest window state, rotated.
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
  A.block<3, 3>(0, 3) = T_W_G.rotation();
  A.block<3, 3>(3, 0) = T_W_I.rotation();
  const Eigen::Matrix<double, 6, 6> C = A * last_pose_covariance_ * A.transpose();
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) odom.pose.covariance[6 * r + c] = C(r, c);
  }
  const Eigen::Vector3d v_I = T_W_I.q.conjugate() * (T_W_G.q * state.v_G);
  const Eigen::Vector3d w_I = odometry_->angularVelocity();
  odom.twist.twist.linear.x = v_I.x();
  odom.twist.twist.linear.y = v_I.y();
  odom.twist.twist.linear.z = v_I.z();
  odom.twist.twist.angular.x = w_I.x();
  odom.twist.twist.angular.y = w_I.y();
  odom.twist.twist.angular.z = w_I.z();
  // Twist covariance, in the body frame (ROS order: linear, then angular). Linear: the newest
  // solved state's velocity covariance rotated into the body, plus what its orientation's
  // uncertainty adds (v_I = R^T v_G, so dv_I = [v_I]x dtheta; first order, their correlation
  // left out). Angular: the gyroscope bias's covariance plus one reading's white noise
  // (noise density^2 x rate). Propagation since that state adds to both and is not counted.
  const Eigen::Matrix3d R_I_G = (T_W_I.q.conjugate() * T_W_G.q).toRotationMatrix();
  const Eigen::Matrix3d v_cross = lie::hat(v_I);
  const Eigen::Matrix3d linear =
      R_I_G * last_velocity_covariance_ * R_I_G.transpose() +
      v_cross * last_pose_covariance_.topLeftCorner<3, 3>() * v_cross.transpose();
  const ImuNoise& noise = rig_.inertial[0].noise;
  const Eigen::Matrix3d angular =
      last_gyro_bias_covariance_ + Eigen::Matrix3d::Identity() * noise.gyroscope_noise_density *
                                       noise.gyroscope_noise_density * rig_.inertial[0].update_rate;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      odom.twist.covariance[6 * r + c] = linear(r, c);
      odom.twist.covariance[6 * (r + 3) + c + 3] = angular(r, c);
    }
  }
  out_.odometry.publish(odom);
  if (options_.publish_tf) {
    out_.tf->sendTransform({stampedTransform(T_W_G, stamp, options_.world_frame, board),
                            stampedTransform(state.T_G_I, stamp, board, base)});
  }
  const ros::WallTime now = ros::WallTime::now();
  OdometryTiming& timing = odometry_timing_;
  const double latency_ms = (now - arrival).toSec() * 1e3;
  timing.latency_ms.push_back(latency_ms);
  const auto bin = static_cast<std::size_t>(std::max(0.0, latency_ms) / OdometryTiming::kBinMs);
  ++timing.histogram[std::min(bin, timing.histogram.size() - 1)];
  timing.worst_latency_ms = std::max(timing.worst_latency_ms, latency_ms);
  if (timing.published++ > 0) {
    const double interval_ms = (now - timing.last_published).toSec() * 1e3;
    timing.max_interval_ms = std::max(timing.max_interval_ms, interval_ms);
    timing.worst_interval_ms = std::max(timing.worst_interval_ms, interval_ms);
    timing.worst_input_interval_ms =
        std::max(timing.worst_input_interval_ms, (arrival - timing.last_arrival).toSec() * 1e3);
  }
  timing.last_published = now;
  timing.last_arrival = arrival;
}

void MvisNodelet::publishCalibration() {
  mvis::Calibration msg =
      ros_conversions::toCalibrationMsg(estimator_->calibration(), options_.frame_prefix);
  msg.header.frame_id = bodyFrame();
  if (!msg.inertial.empty()) msg.inertial[0].frame_id = bodyFrame();
  // The newest estimate's time (base clock); zero before the first.
  msg.header.stamp =
      have_update_ ? ros_conversions::toRosTime(last_update_.state.stamp_ns) : ros::Time();
  if (have_update_) {
    for (const auto& d : last_update_.unobservable) msg.unobservable.push_back(d.text());
  }
  const Estimator::Restart restart = estimator_->lastRestart();
  msg.restarts = static_cast<std::uint32_t>(estimator_->counters().restarts);
  msg.last_restart_reason = restart.reason;
  if (!restart.reason.empty()) msg.last_restart = ros_conversions::toRosTime(restart.stamp_ns);
  const std::vector<CalibrationChange> changes = estimator_->changes();
  for (std::size_t i = 0; i < changes.size(); ++i) {
    // One entry per declaration (its quantities share its text).
    if (i > 0 && changes[i].stamp_ns == changes[i - 1].stamp_ns &&
        changes[i].sensor == changes[i - 1].sensor) {
      continue;
    }
    msg.changes.push_back(changes[i].text);
    msg.change_stamps.push_back(ros_conversions::toRosTime(changes[i].stamp_ns));
  }
  out_.calibration.publish(msg);
}

}  // namespace mvis

PLUGINLIB_EXPORT_CLASS(mvis::MvisNodelet, nodelet::Nodelet)
