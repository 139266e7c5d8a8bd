// mvis_node: the mvis nodelet loaded in-process, for users who do not run a nodelet manager.
// Node and nodelet share one code path.
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <unistd.h>

#include <cstdlib>

int main(int argc, char** argv) {
  // CHOLMOD (under Ceres's solves) runs OpenMP regions; by default libgomp's idle threads then
  // spin for a while, and on a second core they delayed the IMU callback: odometry latency p99
  // 2.1-2.2 ms on two cores against 0.12 ms with passive waiting (scripts/bench part 7). libgomp
  // reads the policy from the environment only, when it is loaded (before main), so the node
  // starts itself again with it set, unless the user chose one. A nodelet manager needs it in
  // its own environment (doc/live_rig.md, "Threads").
  if (std::getenv("OMP_WAIT_POLICY") == nullptr && setenv("OMP_WAIT_POLICY", "passive", 1) == 0) {
    execv("/proc/self/exe", argv);  // returns only on failure: then run as we are
  }
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
