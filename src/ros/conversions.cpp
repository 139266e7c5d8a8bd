#include "mvis/ros/conversions.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include <limits>
#include <opencv2/imgcodecs.hpp>

namespace mvis::ros_conversions {
namespace {

constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

template <typename Array, typename Derived>
void fill(Array& out, const Eigen::MatrixBase<Derived>& values) {
  // Row-major, as the message documents.
  int i = 0;
  for (int r = 0; r < values.rows(); ++r) {
    for (int c = 0; c < values.cols(); ++c) out[i++] = values(r, c);
  }
}

template <typename Array>
void fillUnknown(Array& out) {
  for (auto& v : out) v = kUnknown;
}

mvis::InertialCalibration toMsg(const InertialSensor& s, const std::string& frame_prefix) {
  mvis::InertialCalibration m;
  m.name = s.name;
  m.sensor_type = toString(s.type);
  m.frame_id = frame_prefix + s.name;
  m.T_i_b = toTransformMsg(s.T_i_b);
  m.time_offset = s.time_offset;
  fill(m.Tw, s.intrinsics.Tw);
  fill(m.Ta, s.intrinsics.Ta);
  fill(m.Tg, s.intrinsics.Tg);
  m.model = toString(s.model);
  const Eigen::Quaterniond q_acc(s.intrinsics.R_IMUtoACC), q_gyro(s.intrinsics.R_IMUtoGYRO);
  m.R_IMUtoACC.x = q_acc.x();
  m.R_IMUtoACC.y = q_acc.y();
  m.R_IMUtoACC.z = q_acc.z();
  m.R_IMUtoACC.w = q_acc.w();
  m.R_IMUtoGYRO.x = q_gyro.x();
  m.R_IMUtoGYRO.y = q_gyro.y();
  m.R_IMUtoGYRO.z = q_gyro.z();
  m.R_IMUtoGYRO.w = q_gyro.w();
  if (s.std) {
    fill(m.rotation_std, s.std->rotation);
    fill(m.translation_std, s.std->translation);
    m.time_offset_std = s.std->time_offset;
    fill(m.Tw_std, s.std->Tw);
    fill(m.Ta_std, s.std->Ta);
    fill(m.Tg_std, s.std->Tg);
    fill(m.R_IMUtoACC_std, s.std->R_IMUtoACC);
    fill(m.R_IMUtoGYRO_std, s.std->R_IMUtoGYRO);
  } else {
    fillUnknown(m.rotation_std);
    fillUnknown(m.translation_std);
    m.time_offset_std = kUnknown;
    fillUnknown(m.Tw_std);
    fillUnknown(m.Ta_std);
    fillUnknown(m.Tg_std);
    fillUnknown(m.R_IMUtoACC_std);
    fillUnknown(m.R_IMUtoGYRO_std);
  }
  return m;
}

mvis::CameraCalibration toMsg(const Camera& c, const std::string& frame_prefix) {
  mvis::CameraCalibration m;
  m.name = c.name;
  m.frame_id = frame_prefix + c.name;
  m.T_cam_imu = toTransformMsg(c.T_cam_imu);
  m.timeshift_cam_imu = c.timeshift_cam_imu;
  fill(m.intrinsics, c.intrinsics);
  m.distortion_model = toString(c.distortion_model);
  fill(m.distortion_coeffs, c.distortion_coeffs);
  m.resolution[0] = static_cast<uint32_t>(c.resolution[0]);
  m.resolution[1] = static_cast<uint32_t>(c.resolution[1]);
  if (c.std) {
    fill(m.rotation_std, c.std->rotation);
    fill(m.translation_std, c.std->translation);
    m.timeshift_cam_imu_std = c.std->timeshift_cam_imu;
    fill(m.intrinsics_std, c.std->intrinsics);
    fill(m.distortion_coeffs_std, c.std->distortion_coeffs);
  } else {
    fillUnknown(m.rotation_std);
    fillUnknown(m.translation_std);
    m.timeshift_cam_imu_std = kUnknown;
    fillUnknown(m.intrinsics_std);
    fillUnknown(m.distortion_coeffs_std);
  }
  return m;
}

}  // namespace

ros::Time toRosTime(TimeNs stamp_ns) {
  ros::Time t;
  t.fromNSec(static_cast<uint64_t>(stamp_ns));
  return t;
}

geometry_msgs::Transform toTransformMsg(const SE3& T) {
  geometry_msgs::Transform m;
  m.translation.x = T.p.x();
  m.translation.y = T.p.y();
  m.translation.z = T.p.z();
  m.rotation.x = T.q.x();
  m.rotation.y = T.q.y();
  m.rotation.z = T.q.z();
  m.rotation.w = T.q.w();
  return m;
}

TagFrame toTagFrame(const mvis::TagDetectionArray& msg, std::size_t camera) {
  TagFrame frame;
  frame.camera = camera;
  frame.stamp_ns = toTimeNs(msg.header.stamp);
  for (const auto& d : msg.detections) {
    TagObservation tag;
    tag.tag_id = d.id;
    for (int c = 0; c < 4; ++c) {
      tag.corners_px[c] = Eigen::Vector2d(d.corners[2 * c], d.corners[2 * c + 1]);
    }
    frame.tags.push_back(tag);
  }
  return frame;
}

mvis::Calibration toCalibrationMsg(const Rig& rig, const std::string& frame_prefix) {
  mvis::Calibration msg;
  msg.header.frame_id = frame_prefix + rig.baseImu().name;
  for (const auto& s : rig.inertial) msg.inertial.push_back(toMsg(s, frame_prefix));
  for (const auto& c : rig.cameras) msg.cameras.push_back(toMsg(c, frame_prefix));
  return msg;
}

namespace {

bool finiteVector(const geometry_msgs::Vector3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

bool toImuMeasurement(const sensor_msgs::Imu& msg, bool gyroscope_only, ImuMeasurement* out,
                      std::string* why) {
  if (!finiteVector(msg.angular_velocity) ||
      (!gyroscope_only && !finiteVector(msg.linear_acceleration))) {
    *why = "a sample with NaN or inf values";
    return false;
  }
  out->stamp_ns = toTimeNs(msg.header.stamp);
  out->gyro = {msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z};
  out->accel = gyroscope_only
                   ? Eigen::Vector3d::Zero()
                   : Eigen::Vector3d(msg.linear_acceleration.x, msg.linear_acceleration.y,
                                     msg.linear_acceleration.z);
  return true;
}

bool toGray(const sensor_msgs::ImageConstPtr& msg, cv::Mat* gray, std::string* why) {
  if (msg->width == 0 || msg->height == 0) {
    *why = "empty image (" + std::to_string(msg->width) + "x" + std::to_string(msg->height) + ")";
    return false;
  }
  try {
    // Rows that overlap would make cv_bridge read past the data's end (found by fuzzing).
    namespace enc = sensor_msgs::image_encodings;
    const std::uint64_t row_bytes = static_cast<std::uint64_t>(msg->width) *
                                    enc::numChannels(msg->encoding) * enc::bitDepth(msg->encoding) /
                                    8;
    if (msg->step < row_bytes) {
      *why = "step (" + std::to_string(msg->step) + " bytes) shorter than a row of " +
             std::to_string(msg->width) + " '" + msg->encoding + "' pixels (" +
             std::to_string(row_bytes) + " bytes)";
      return false;
    }
  } catch (const std::exception&) {
    // An encoding image_encodings does not know: cv_bridge refuses it below.
  }
  if (msg->data.size() < static_cast<std::size_t>(msg->step) * msg->height) {
    *why = "image data (" + std::to_string(msg->data.size()) + " bytes) shorter than step x height";
    return false;
  }
  try {
    *gray = cv_bridge::toCvShare(msg, sensor_msgs::image_encodings::MONO8)->image;
  } catch (const std::exception& e) {  // cv_bridge::Exception or cv::Exception
    *why = "cannot use encoding '" + msg->encoding + "': " + e.what();
    return false;
  }
  return true;
}

bool toGray(const sensor_msgs::CompressedImage& msg, cv::Mat* gray, std::string* why) {
  if (msg.data.empty()) {
    *why = "compressed image without data";
    return false;
  }
  cv::Mat decoded;
  try {
    decoded = cv::imdecode(msg.data, cv::IMREAD_GRAYSCALE | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception& e) {
    *why = "cannot decode the compressed image (format '" + msg.format + "'): " + e.what();
    return false;
  }
  if (decoded.empty()) {
    *why = "cannot decode the compressed image (format '" + msg.format + "', " +
           std::to_string(msg.data.size()) + " bytes): not a JPEG or PNG OpenCV can read";
    return false;
  }
  if (decoded.depth() == CV_8U) {
    *gray = decoded;
  } else if (decoded.depth() == CV_16U) {
    decoded.convertTo(*gray, CV_8U, 255.0 / 65535.0);
  } else {
    *why = "compressed image of an unsupported depth (format '" + msg.format + "')";
    return false;
  }
  return true;
}

sensor_msgs::CompressedImage toCompressedPng(const cv::Mat& gray) {
  sensor_msgs::CompressedImage msg;
  msg.format = "mono8; png compressed";
  cv::imencode(".png", gray, msg.data);
  return msg;
}

}  // namespace mvis::ros_conversions
