#include "mvis/ros/mvis_nodelet.h"

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <sensor_msgs/image_encodings.h>

#include <cmath>
#include <cstdio>
#include <pluginlib/class_list_macros.hpp>

#include "mvis/frontend/debug_image.h"
#include "mvis/rig/rig_io.h"
#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

bool finite(const geometry_msgs::Vector3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

diagnostic_msgs::DiagnosticStatus makeStatus(std::uint8_t level, const std::string& name,
                                             const std::string& message) {
  diagnostic_msgs::DiagnosticStatus status;
  status.level = level;
  status.name = "mvis: " + name;
  status.hardware_id = "mvis";
  status.message = message;
  return status;
}

}  // namespace

void MvisNodelet::onInit() {
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& pnh = getPrivateNodeHandle();
  diagnostics_pub_ = nh.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);

  options_ = NodeletOptions::fromParameters(pnh);
  if (const std::string problem = options_.validate(); !problem.empty()) {
    stayDown(problem);
    return;
  }
  auto rig = loadRig(options_.config_dir);
  if (!rig.ok()) {
    stayDown(rig.status().message());
    return;
  }
  rig_ = std::move(rig).value();
  NODELET_INFO_STREAM("mvis: loaded the rig from " << options_.config_dir << ":\n"
                                                   << rig_.summary());

  odometry_pub_ = pnh.advertise<nav_msgs::Odometry>("odometry", 100);
  path_pub_ = pnh.advertise<nav_msgs::Path>("path", 1, true);
  calibration_pub_ = pnh.advertise<mvis::Calibration>("calibration", 1, true);
  // Until the estimator has run, the calibration is the configured one, its uncertainty
  // not yet known (NaN standard deviations).
  mvis::Calibration calibration = ros_conversions::toCalibrationMsg(rig_, options_.frame_prefix);
  calibration.header.stamp = ros::Time::now();
  calibration_pub_.publish(calibration);

  TagFrontendOptions frontend_options;
  frontend_options.detector.decimate = options_.tag_decimate;
  frontend_options.detector.refine_corners = options_.tag_refine_corners;
  frontend_options.detector.max_hamming = options_.tag_max_hamming;
  frontend_options.detector.threads = options_.tag_threads;
  frontend_options.checks.max_hamming = options_.tag_max_hamming;
  auto frontend = TagFrontend::create(rig_, frontend_options);
  if (!frontend.ok()) {
    stayDown(frontend.status().message());
    return;
  }
  frontend_ = std::move(frontend).value();

  subscribeSensors();
  diagnostics_timer_ =
      nh.createWallTimer(ros::WallDuration(options_.diagnostics_period_s),
                         [this](const ros::WallTimerEvent&) { publishDiagnostics(); });
}

void MvisNodelet::stayDown(const std::string& reason) {
  config_error_ = reason;
  NODELET_ERROR_STREAM("mvis: not starting: " << reason);
  diagnostics_timer_ = getNodeHandle().createWallTimer(
      ros::WallDuration(options_.diagnostics_period_s > 0.0 ? options_.diagnostics_period_s : 1.0),
      [this](const ros::WallTimerEvent&) { publishDiagnostics(); });
}

void MvisNodelet::subscribeSensors() {
  ros::NodeHandle& nh = getNodeHandle();
  const ros::WallTime now = ros::WallTime::now();
  for (std::size_t i = 0; i < rig_.inertial.size(); ++i) {
    const auto& s = rig_.inertial[i];
    traffic_.push_back({s.name, s.rostopic, s.update_rate, 0, 0, {}, 0, now});
    subscribers_.push_back(nh.subscribe<sensor_msgs::Imu>(
        s.rostopic, 2000, [this, i](const sensor_msgs::ImuConstPtr& msg) { onImu(i, msg); },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay()));
  }
  image_transport_ = std::make_unique<image_transport::ImageTransport>(nh);
  private_image_transport_ =
      std::make_unique<image_transport::ImageTransport>(getPrivateNodeHandle());
  for (std::size_t c = 0; c < rig_.cameras.size(); ++c) {
    const auto& cam = rig_.cameras[c];
    debug_image_pubs_.push_back(private_image_transport_->advertise(cam.name + "/debug_image", 1));
    if (options_.camera_input == "image") {
      traffic_.push_back({cam.name, cam.rostopic, 0.0, 0, 0, {}, 0, now});
      image_subscribers_.push_back(image_transport_->subscribe(
          cam.rostopic, 20, [this, c](const sensor_msgs::ImageConstPtr& msg) { onImage(c, msg); }));
    } else {
      const std::string topic = cam.rostopic + "/tag_detections";
      traffic_.push_back({cam.name, topic, 0.0, 0, 0, {}, 0, now});
      subscribers_.push_back(nh.subscribe<mvis::TagDetectionArray>(
          topic, 50,
          [this, c](const mvis::TagDetectionArrayConstPtr& msg) { onTagDetections(c, msg); }));
    }
  }
}

void MvisNodelet::onImu(std::size_t sensor, const sensor_msgs::ImuConstPtr& msg) {
  const auto& s = rig_.inertial[sensor];
  const bool accel_ok = s.type == InertialType::kGyroscope || finite(msg->linear_acceleration);
  std::lock_guard<std::mutex> lock(mutex_);
  SensorTraffic& t = traffic_[sensor];
  t.last_arrival = ros::WallTime::now();
  if (!finite(msg->angular_velocity) || !accel_ok) {
    ++t.rejected;
    NODELET_WARN_STREAM_THROTTLE(5.0, "mvis: " << s.name << " (" << s.rostopic
                                               << "): dropped a sample with NaN or inf values");
    return;
  }
  ++t.received;
}

void MvisNodelet::onImage(std::size_t camera, const sensor_msgs::ImageConstPtr& msg) {
  cv::Mat gray;
  std::string why;
  if (!ros_conversions::toGray(msg, &gray, &why)) {
    rejectCameraMessage(camera, why);
    return;
  }
  const auto result =
      frontend_->processImage(camera, ros_conversions::toTimeNs(msg->header.stamp), gray);
  if (!result.ok()) {
    rejectCameraMessage(camera, result.status().message());
    return;
  }
  recordTags(camera, result.value());
  auto& debug_pub = debug_image_pubs_[camera];
  if (debug_pub.getNumSubscribers() > 0) {
    debug_pub.publish(cv_bridge::CvImage(msg->header, sensor_msgs::image_encodings::BGR8,
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

void MvisNodelet::publishDiagnostics() {
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  if (!config_error_.empty()) {
    array.status.push_back(
        makeStatus(diagnostic_msgs::DiagnosticStatus::ERROR, "configuration", config_error_));
    diagnostics_pub_.publish(array);
    return;
  }
  array.status.push_back(makeStatus(diagnostic_msgs::DiagnosticStatus::OK, "configuration",
                                    "loaded " + options_.config_dir));
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
    auto status = makeStatus(level, t.name, text);
    diagnostic_msgs::KeyValue kv;
    kv.key = "received";
    kv.value = std::to_string(t.received);
    status.values.push_back(kv);
    kv.key = "rejected";
    kv.value = std::to_string(t.rejected);
    status.values.push_back(kv);
    if (&t - traffic_.data() >= static_cast<std::ptrdiff_t>(rig_.inertial.size())) {
      kv.key = "tags_in_last_frame";
      kv.value = std::to_string(t.tags_in_last_frame);
      status.values.push_back(kv);
      kv.key = "tags_rejected";
      kv.value = std::to_string(t.tags_rejected);
      status.values.push_back(kv);
    }
    array.status.push_back(status);
  }
  diagnostics_pub_.publish(array);
}

}  // namespace mvis

PLUGINLIB_EXPORT_CLASS(mvis::MvisNodelet, nodelet::Nodelet)
