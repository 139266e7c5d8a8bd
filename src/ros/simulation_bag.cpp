#include "mvis/ros/simulation_bag.h"

#include <mvis/TagDetectionArray.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/image_encodings.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <utility>
#include <vector>

#include "mvis/rig/rig_io.h"
#include "mvis/ros/conversions.h"
#include "mvis/sim/simulation.h"

namespace mvis {
namespace {

class BagSink : public SimulationSink {
 public:
  BagSink(rosbag::Bag* bag, const Rig& rig, SimulationBagSummary* summary, bool compressed)
      : bag_(bag), rig_(rig), summary_(summary), compressed_(compressed) {}

  // The simulation hands over each sensor's whole stream in turn; a bag written in that order
  // makes every reader that follows time (rosbag::View over several topics) load a chunk per
  // switch between streams (the 60 s VI-Rig: ~13% of mvis_offline's time in the kernel's read
  // copies). Readings and detections are kept and written in time order, as a recorder would;
  // images as they come (after the readings and detections so far).
  void imu(std::size_t sensor, const ImuSample& sample) override {
    imu_.emplace_back(sensor, sample);
  }
  void tagFrame(const TagFrame& frame) override { frames_.push_back(frame); }

  // Writes what is kept, in time order (readings before detections at the same stamp).
  void flush() {
    std::vector<std::pair<TimeNs, std::size_t>> order;  // stamp, index (frames after readings)
    order.reserve(imu_.size() + frames_.size());
    for (std::size_t i = 0; i < imu_.size(); ++i) order.emplace_back(imu_[i].second.stamp_ns, i);
    for (std::size_t i = 0; i < frames_.size(); ++i) {
      order.emplace_back(frames_[i].stamp_ns, imu_.size() + i);
    }
    std::stable_sort(order.begin(), order.end());
    for (const auto& [stamp, i] : order) {
      if (i < imu_.size()) {
        writeImu(imu_[i].first, imu_[i].second);
      } else {
        writeTagFrame(frames_[i - imu_.size()]);
      }
    }
    imu_.clear();
    frames_.clear();
  }

  void image(std::size_t camera, TimeNs stamp_ns, const cv::Mat& gray) override {
    flush();
    if (compressed_) {
      sensor_msgs::CompressedImage msg = ros_conversions::toCompressedPng(gray);
      msg.header.stamp = ros_conversions::toRosTime(stamp_ns);
      msg.header.frame_id = rig_.cameras[camera].name;
      bag_->write(rig_.cameras[camera].rostopic + "/compressed", msg.header.stamp, msg);
      ++summary_->camera_messages;
      return;
    }
    sensor_msgs::Image msg;
    msg.header.stamp = ros_conversions::toRosTime(stamp_ns);
    msg.header.frame_id = rig_.cameras[camera].name;
    msg.width = gray.cols;
    msg.height = gray.rows;
    msg.encoding = sensor_msgs::image_encodings::MONO8;
    msg.step = gray.cols;
    msg.data.resize(static_cast<std::size_t>(gray.cols) * gray.rows);
    for (int r = 0; r < gray.rows; ++r) {
      std::copy(gray.ptr<std::uint8_t>(r), gray.ptr<std::uint8_t>(r) + gray.cols,
                msg.data.begin() + static_cast<std::size_t>(r) * gray.cols);
    }
    bag_->write(rig_.cameras[camera].rostopic, msg.header.stamp, msg);
    ++summary_->camera_messages;
  }

 private:
  void writeImu(std::size_t sensor, const ImuSample& sample) {
    sensor_msgs::Imu msg;
    msg.header.stamp = ros_conversions::toRosTime(sample.stamp_ns);
    msg.header.frame_id = rig_.inertial[sensor].name;
    msg.orientation_covariance[0] = -1.0;  // REP-145: no orientation estimate
    for (auto [to, from] : {std::make_pair(&msg.angular_velocity, &sample.gyro),
                            std::make_pair(&msg.linear_acceleration, &sample.accel)}) {
      to->x = from->x();
      to->y = from->y();
      to->z = from->z();
    }
    bag_->write(rig_.inertial[sensor].rostopic, msg.header.stamp, msg);
    ++summary_->imu_messages;
  }

  void writeTagFrame(const TagFrame& frame) {
    mvis::TagDetectionArray msg;
    msg.header.stamp = ros_conversions::toRosTime(frame.stamp_ns);
    msg.header.frame_id = rig_.cameras[frame.camera].name;
    for (const auto& tag : frame.tags) {
      mvis::TagDetection d;
      d.id = tag.tag_id;
      for (int c = 0; c < 4; ++c) {
        d.corners[2 * c] = tag.corners_px[c].x();
        d.corners[2 * c + 1] = tag.corners_px[c].y();
      }
      msg.detections.push_back(d);
    }
    bag_->write(rig_.cameras[frame.camera].rostopic + "/tag_detections", msg.header.stamp, msg);
    ++summary_->camera_messages;
    summary_->tags += frame.tags.size();
  }

  rosbag::Bag* bag_;
  const Rig& rig_;
  SimulationBagSummary* summary_;
  bool compressed_;
  std::vector<std::pair<std::size_t, ImuSample>> imu_;
  std::vector<TagFrame> frames_;
};

}  // namespace

StatusOr<SimulationBagSummary> writeSimulationBag(const Rig& truth, const SimulationConfig& config,
                                                  const std::string& output_dir,
                                                  bool compressed_images) {
  namespace fs = std::filesystem;
  const auto start = std::chrono::steady_clock::now();
  const fs::path out(output_dir);
  std::error_code error;
  fs::create_directories(out, error);
  if (error) return Status::Error(output_dir + ": cannot create: " + error.message());

  // With sensors that move, truth/ is the rig at the end and truth_start/ the rig before.
  const auto moved = movedRig(truth, config.moves);
  if (!moved.ok()) return moved.status();
  Status status = saveRig(moved.value(), (out / "truth").string());
  if (!status.ok()) return status;
  if (!config.moves.empty()) {
    status = saveRig(truth, (out / "truth_start").string());
    if (!status.ok()) return status;
  }
  status = saveRig(perturbRig(truth, config.perturbation, config.seed), (out / "config").string());
  if (!status.ok()) return status;

  SimulationBagSummary summary;
  StatusOr<std::vector<StampedPose>> trajectory = Status::Error("not run");
  try {
    if (!ros::Time::isValid()) ros::Time::init();
    rosbag::Bag bag((out / "sim.bag").string(), rosbag::bagmode::Write);
    BagSink sink(&bag, truth, &summary, compressed_images);
    trajectory = runSimulation(truth, config, &sink);
    sink.flush();
    bag.close();
  } catch (const std::exception& e) {  // rosbag::BagException and friends
    return Status::Error((out / "sim.bag").string() + ": " + e.what());
  }
  if (!trajectory.ok()) return trajectory.status();
  status = writeTumTrajectory((out / "truth" / "trajectory.tum").string(), trajectory.value());
  if (!status.ok()) return status;
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace mvis
