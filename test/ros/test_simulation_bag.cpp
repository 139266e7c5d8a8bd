// mvis_simulate's output read back: topics, counts, clocks, truth files; same seed, same bag.
#include <gtest/gtest.h>
#include <mvis/TagDetectionArray.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include <filesystem>

#include "mvis/rig/rig_io.h"
#include "mvis/rig/trajectory_io.h"
#include "mvis/ros/simulation_bag.h"

namespace mvis {
namespace {

namespace fs = std::filesystem;

struct SimRun {
  Rig truth;
  SimulationConfig config;
  fs::path dir;
};

SimRun simulate(const std::string& name, double duration_s) {
  SimRun run;
  run.truth = loadRig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig").value();
  run.config = loadSimulationConfig(std::string(MVIS_SOURCE_DIR) + "/config/sim_vi_rig/sim.yaml",
                                    run.truth.cameras.size())
                   .value();
  run.config.duration_s = duration_s;
  run.config.camera_output = CameraOutput::kDetections;
  run.truth.cameras[1].timeshift_cam_imu = 0.015;
  run.truth.inertial[1].time_offset = -0.004;
  run.dir = fs::temp_directory_path() / ("mvis_sim_" + name);
  fs::remove_all(run.dir);
  const auto summary = writeSimulationBag(run.truth, run.config, run.dir.string());
  EXPECT_TRUE(summary.ok()) << summary.status().message();
  return run;
}

TEST(SimulationBag, HoldsEverySensorInItsOwnClock) {
  const SimRun run = simulate("topics", 3.0);
  rosbag::Bag bag((run.dir / "sim.bag").string(), rosbag::bagmode::Read);
  std::map<std::string, std::vector<ros::Time>> stamps;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (auto imu = m.instantiate<sensor_msgs::Imu>()) {
      stamps[m.getTopic()].push_back(imu->header.stamp);
    } else if (auto tags = m.instantiate<mvis::TagDetectionArray>()) {
      stamps[m.getTopic()].push_back(tags->header.stamp);
      EXPECT_GE(tags->detections.size(), 8u) << m.getTopic();
    }
  }
  // Rates from the rig and sim.yaml, both ends of [0, 3] s included.
  EXPECT_EQ(stamps["/imu0"].size(), 1501u);
  EXPECT_EQ(stamps["/imu1"].size(), 301u);
  EXPECT_EQ(stamps["/imu2"].size(), 601u);
  EXPECT_EQ(stamps["/cam0/image_raw/tag_detections"].size(), 91u);
  EXPECT_EQ(stamps["/cam1/image_raw/tag_detections"].size(), 76u);
  EXPECT_EQ(stamps["/cam2/image_raw/tag_detections"].size(), 91u);
  // Every sensor's clock starts at start_time_s; its offset shows in what it measured, not in
  // its stamps (t_imu0 = t_sensor + offset).
  EXPECT_EQ(stamps["/imu1"].front(), ros::Time(1700000000, 0));
  EXPECT_EQ(
      stamps["/cam1/image_raw/tag_detections"][1] - stamps["/cam1/image_raw/tag_detections"][0],
      ros::Duration(0, 40000000));
  // Truth: the rig files as given, and imu0's trajectory at its sample times.
  const auto truth = loadRig((run.dir / "truth").string());
  ASSERT_TRUE(truth.ok()) << truth.status().message();
  EXPECT_EQ(truth.value().cameras[1].timeshift_cam_imu, 0.015);
  EXPECT_EQ(truth.value().inertial[1].time_offset, -0.004);
  const auto trajectory = readTumTrajectory((run.dir / "truth" / "trajectory.tum").string());
  ASSERT_TRUE(trajectory.ok());
  ASSERT_EQ(trajectory.value().size(), 1501u);
  EXPECT_EQ(trajectory.value()[1].first, 1700000000LL * kNsPerSecond + 2000000);
  // The initial guess differs from the truth by the configured perturbation.
  const auto guess = loadRig((run.dir / "config").string());
  ASSERT_TRUE(guess.ok());
  EXPECT_NE(guess.value().cameras[0].timeshift_cam_imu, truth.value().cameras[0].timeshift_cam_imu);
  EXPECT_EQ(guess.value().inertial[0].T_i_b.matrix(), Eigen::Matrix4d::Identity());
}

TEST(SimulationBag, SameSeedSameValues) {
  const SimRun a = simulate("seed_a", 1.0), b = simulate("seed_b", 1.0);
  rosbag::Bag bag_a((a.dir / "sim.bag").string()), bag_b((b.dir / "sim.bag").string());
  rosbag::View view_a(bag_a), view_b(bag_b);
  ASSERT_EQ(view_a.size(), view_b.size());
  auto it_b = view_b.begin();
  int compared = 0;
  for (auto it_a = view_a.begin(); it_a != view_a.end(); ++it_a, ++it_b, ++compared) {
    ASSERT_EQ(it_a->getTopic(), it_b->getTopic());
    if (auto imu = it_a->instantiate<sensor_msgs::Imu>()) {
      const auto other = it_b->instantiate<sensor_msgs::Imu>();
      ASSERT_TRUE(other);
      EXPECT_EQ(imu->angular_velocity.x, other->angular_velocity.x);
      EXPECT_EQ(imu->linear_acceleration.z, other->linear_acceleration.z);
    } else if (auto tags = it_a->instantiate<mvis::TagDetectionArray>()) {
      const auto other = it_b->instantiate<mvis::TagDetectionArray>();
      ASSERT_TRUE(other);
      ASSERT_EQ(tags->detections.size(), other->detections.size());
      for (std::size_t i = 0; i < tags->detections.size(); ++i) {
        EXPECT_EQ(tags->detections[i].corners, other->detections[i].corners);
      }
    }
  }
  EXPECT_GT(compared, 800);
}

}  // namespace
}  // namespace mvis
