// mvis_node: the mvis nodelet loaded in-process, for users who do not run a nodelet manager.
// Node and nodelet share one code path.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "mvis");
  nodelet::Loader loader;
  const nodelet::M_string remappings(ros::names::getRemappings());
  const nodelet::V_string nodelet_argv;
  if (!loader.load(ros::this_node::getName(), "mvis/MvisNodelet", remappings, nodelet_argv)) {
    ROS_FATAL(
        "mvis_node: could not load the nodelet mvis/MvisNodelet (is the package on "
        "ROS_PACKAGE_PATH? source devel/setup.bash)");
    return 1;
  }
  ros::spin();
  return 0;
}
