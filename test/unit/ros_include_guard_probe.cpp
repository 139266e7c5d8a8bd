// Compiled only by the test core_rejects_ros_includes, which expects this to FAIL: a core
// translation unit that includes a ROS header must not build.
#include <ros/ros.h>

#include "mvis/rig/rig.h"
