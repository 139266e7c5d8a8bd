// Conversions between ROS messages and the core's plain types. The only place both meet.
#pragma once

#include <geometry_msgs/Transform.h>
#include <mvis/Calibration.h>
#include <mvis/TagDetectionArray.h>
#include <ros/time.h>

#include <string>

#include "mvis/common/lie.h"
#include "mvis/common/time.h"
#include "mvis/frontend/tag_observation.h"
#include "mvis/rig/rig.h"

namespace mvis::ros_conversions {

inline TimeNs toTimeNs(const ros::Time& stamp) { return fromSecNsec(stamp.sec, stamp.nsec); }
ros::Time toRosTime(TimeNs stamp_ns);

geometry_msgs::Transform toTransformMsg(const SE3& T);

// Detections made elsewhere, for camera index `camera`. Values are copied as they are; the
// front end's checks decide what is usable.
TagFrame toTagFrame(const mvis::TagDetectionArray& msg, std::size_t camera);

// The rig's calibration as a message. Sensors without std get NaN standard deviations
// ("not yet known"). Frame ids are frame_prefix + sensor name.
mvis::Calibration toCalibrationMsg(const Rig& rig, const std::string& frame_prefix);

}  // namespace mvis::ros_conversions
