// Conversions between ROS messages and the core's plain types. The only place both meet.
#pragma once

#include <geometry_msgs/Transform.h>
#include <mvis/Calibration.h>
#include <mvis/TagDetectionArray.h>
#include <ros/time.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <opencv2/core/mat.hpp>
#include <string>

#include "mvis/common/lie.h"
#include "mvis/common/time.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/inertial/imu_preintegration.h"
#include "mvis/rig/rig.h"

namespace mvis::ros_conversions {

inline TimeNs toTimeNs(const ros::Time& stamp) { return fromSecNsec(stamp.sec, stamp.nsec); }
ros::Time toRosTime(TimeNs stamp_ns);

geometry_msgs::Transform toTransformMsg(const SE3& T);

// Detections made elsewhere, for camera index `camera`. Values are copied as they are; the
// front end's checks decide what is usable.
TagFrame toTagFrame(const mvis::TagDetectionArray& msg, std::size_t camera);

// An inertial reading stamped in its sensor's clock. False (and `why` says which) when the
// angular velocity, or the linear acceleration of an IMU (not of a gyroscope), is not finite.
bool toImuMeasurement(const sensor_msgs::Imu& msg, bool gyroscope_only, ImuMeasurement* out,
                      std::string* why);

// The image as 8-bit gray (shared with the message when it is mono8 already). False, with the
// reason in `why`, for data shorter than step x height (cv_bridge would read past its end) or an
// encoding cv_bridge cannot turn into mono8.
bool toGray(const sensor_msgs::ImageConstPtr& msg, cv::Mat* gray, std::string* why);

// A sensor_msgs/CompressedImage (JPEG or PNG, as compressed_image_transport or a driver writes
// it; mono or colour, 8 or 16 bit) decoded by OpenCV to 8-bit gray: colour with OpenCV's
// weights, 16 bit scaled by 255/65535 (full range to full range). False, with the reason in
// `why`, for data OpenCV cannot decode.
bool toGray(const sensor_msgs::CompressedImage& msg, cv::Mat* gray, std::string* why);
// The same image PNG-compressed (lossless: toGray gives the same pixels back), as
// compressed_image_transport writes it ("mono8; png compressed").
sensor_msgs::CompressedImage toCompressedPng(const cv::Mat& gray);

// The rig's calibration as a message. Sensors without std get NaN standard deviations
// ("not yet known"). Frame ids are frame_prefix + sensor name.
mvis::Calibration toCalibrationMsg(const Rig& rig, const std::string& frame_prefix);

}  // namespace mvis::ros_conversions
