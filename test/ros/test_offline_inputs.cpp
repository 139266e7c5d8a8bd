// What bags hold for the cameras: compressed images (as rigs record them) give the same run as
// raw images, and a bag without the configured topics says which topics it does have; what went
// wrong in a bag is summed up by kind.
#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <filesystem>
#include <functional>

#include "mvis/rig/rig_io.h"
#include "mvis/ros/offline.h"
#include "mvis/ros/simulation_bag.h"

namespace mvis {
namespace {

namespace fs = std::filesystem;

// 10 s of the small rig (one 376x240 camera at 20 Hz) rendered, raw or PNG-compressed; the
// same seed gives the same images either way.
fs::path simulate(const std::string& name, bool compressed) {
  const std::string rig_dir = std::string(MVIS_SOURCE_DIR) + "/config/sim_small_rig";
  const Rig truth = loadRig(rig_dir).value();
  SimulationConfig config = loadSimulationConfig(rig_dir + "/sim.yaml", 1).value();
  config.duration_s = 10.0;
  config.threads = 1;
  const fs::path dir = fs::temp_directory_path() / ("mvis_offline_inputs_" + name);
  fs::remove_all(dir);
  const auto summary = writeSimulationBag(truth, config, dir.string(), compressed);
  EXPECT_TRUE(summary.ok()) << summary.status().message();
  return dir;
}

TEST(OfflineInputs, CompressedImagesGiveTheRunRawImagesGive) {
  const fs::path raw = simulate("raw", false), png = simulate("png", true);
  const Rig guess = loadRig((raw / "config").string()).value();
  OfflineOptions options;
  options.estimator.max_solve_time_s = 1e3;  // no time budget: the same answer whatever the load
  options.estimator.init_solve_time_s = 1e3;
  const auto a = runOffline(guess, (raw / "sim.bag").string(), options);
  const auto b = runOffline(guess, (png / "sim.bag").string(), options);
  ASSERT_TRUE(a.ok()) << a.status().message();
  ASSERT_TRUE(b.ok()) << b.status().message();
  EXPECT_EQ(a.value().image_messages, 201);
  EXPECT_EQ(b.value().image_messages, 201);
  EXPECT_TRUE(a.value().decode_ms.empty());
  EXPECT_EQ(b.value().decode_ms.size(), 201u);
  EXPECT_EQ(a.value().dropped_messages, 0);
  EXPECT_EQ(b.value().dropped_messages, 0);
  // PNG is lossless: the same pixels, the same detections, the same estimate to the last bit.
  const Camera &ca = a.value().calibration.cameras[0], &cb = b.value().calibration.cameras[0];
  EXPECT_EQ(ca.T_cam_imu.matrix(), cb.T_cam_imu.matrix());
  EXPECT_EQ(ca.timeshift_cam_imu, cb.timeshift_cam_imu);
  ASSERT_EQ(a.value().trajectory.size(), b.value().trajectory.size());
  EXPECT_EQ(a.value().trajectory.back().T_G_I.matrix(), b.value().trajectory.back().T_G_I.matrix());
  EXPECT_TRUE(b.value().warnings.empty());
  fs::remove_all(raw);
  fs::remove_all(png);
}

TEST(OfflineInputs, AWrongTopicNamesTheTopicsTheBagHas) {
  const fs::path png = simulate("wrong_topic", true);
  Rig guess = loadRig((png / "config").string()).value();
  guess.cameras[0].rostopic = "/camera/image_raw";
  OfflineOptions options;
  const auto r = runOffline(guess, (png / "sim.bag").string(), options);
  ASSERT_FALSE(r.ok());
  const std::string& message = r.status().message();
  EXPECT_NE(message.find("cam0: no message on /camera/image_raw (sensor_msgs/Image), "
                         "/camera/image_raw/compressed (sensor_msgs/CompressedImage) or "
                         "/camera/image_raw/tag_detections (mvis/TagDetectionArray); the bag has "
                         "/cam0/image_raw/compressed (sensor_msgs/CompressedImage)"),
            std::string::npos)
      << message;
  fs::remove_all(png);
}

// The small rig's detections (`duration_s`, 0: its sim.yaml's), copied message by message by
// `copy(out, message, t)` (t: seconds into the bag) into an edited bag, run offline from the
// configured guess.
StatusOr<OfflineResult> runEdited(
    const std::string& name, double duration_s,
    const std::function<void(rosbag::Bag*, const rosbag::MessageInstance&, double)>& copy) {
  const std::string rig_dir = std::string(MVIS_SOURCE_DIR) + "/config/sim_small_rig";
  const Rig truth = loadRig(rig_dir).value();
  SimulationConfig config = loadSimulationConfig(rig_dir + "/sim.yaml", 1).value();
  config.camera_output = CameraOutput::kDetections;
  if (duration_s > 0.0) config.duration_s = duration_s;
  const fs::path dir = fs::temp_directory_path() / ("mvis_offline_inputs_" + name);
  fs::remove_all(dir);
  const auto written = writeSimulationBag(truth, config, dir.string());
  if (!written.ok()) return written.status();
  {
    rosbag::Bag in((dir / "sim.bag").string(), rosbag::bagmode::Read);
    rosbag::Bag out((dir / "edited.bag").string(), rosbag::bagmode::Write);
    rosbag::View view(in);
    const ros::Time begin = view.getBeginTime();
    for (const rosbag::MessageInstance& m : view) copy(&out, m, (m.getTime() - begin).toSec());
  }
  const Rig guess = loadRig((dir / "config").string()).value();
  OfflineOptions options;
  options.estimator.pixel_sigma_px = config.pixel_noise_px;
  auto result = runOffline(guess, (dir / "edited.bag").string(), options);
  fs::remove_all(dir);
  return result;
}

// A bag with 0.3 s of imu0 missing at 5 s and one of imu1's readings repeated: each is one kind of
// warning, counted, with the bag time it first happened.
TEST(OfflineInputs, WarningsAreSummedUpByKind) {
  int repeated = 0;
  const auto r = runEdited("warnings", 0.0, [&](rosbag::Bag* out, const auto& m, double t) {
    if (m.getTopic() == "/imu0" && t >= 5.0 && t < 5.3) return;
    out->write(m.getTopic(), m.getTime(), m);
    if (m.getTopic() == "/imu1" && t >= 7.0 && repeated++ == 0) {
      out->write(m.getTopic(), m.getTime(), m);
    }
  });
  ASSERT_TRUE(r.ok()) << r.status().message();
  const auto& kinds = r.value().warning_kinds;
  ASSERT_EQ(kinds.size(), 2u);
  EXPECT_EQ(kinds[0].example.rfind("imu0: no reading for 0.30", 0), 0u) << kinds[0].example;
  EXPECT_EQ(kinds[0].count, 1);
  EXPECT_NEAR(kinds[0].first_s, 5.3, 0.01);
  EXPECT_EQ(kinds[1].example, "imu1: reading out of order or repeated, dropped");
  EXPECT_EQ(kinds[1].count, 1);
  EXPECT_NEAR(kinds[1].first_s, 7.0, 0.01);
}

// A base-IMU hole (0.1 s, beyond imu_max_gap) 0.3 s before the end of the bag: the window starts
// over from the trusted calibration and cannot initialize again before the bag ends. What it
// estimated is still written (before: "the estimator never initialized", and nothing).
TEST(OfflineInputs, AStartOverAtTheEndStillGivesTheResult) {
  const auto r = runEdited("late_restart", 10.0, [](rosbag::Bag* out, const auto& m, double t) {
    if (m.getTopic() == "/imu0" && t >= 9.6 && t < 9.7) return;
    out->write(m.getTopic(), m.getTime(), m);
  });
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r.value().counters.restarts, 1);
  EXPECT_GT(r.value().trajectory.size(), 100u);
  bool said = false;
  for (const auto& w : r.value().warnings) {
    said = said || w.find("initializing again") != std::string::npos;
  }
  EXPECT_TRUE(said);
}

}  // namespace
}  // namespace mvis
