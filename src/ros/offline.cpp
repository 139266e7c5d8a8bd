#include "mvis/ros/offline.h"

#include <mvis/TagDetectionArray.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <chrono>
#include <map>

#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace

StatusOr<OfflineResult> runOffline(const Rig& initial, const std::string& bag_path,
                                   const OfflineOptions& options) {
  auto created = Estimator::create(initial, options.estimator);
  if (!created.ok()) return created.status();
  std::unique_ptr<Estimator> estimator = std::move(created).value();
  auto frontend_made = TagFrontend::create(initial, options.frontend);
  if (!frontend_made.ok()) return frontend_made.status();
  std::unique_ptr<TagFrontend> frontend = std::move(frontend_made).value();

  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    return Status::Error(bag_path + ": cannot open the bag: " + e.what());
  }
  std::map<std::string, std::size_t> imu_topics, image_topics, detection_topics;
  std::vector<std::string> topics;
  for (std::size_t i = 0; i < initial.inertial.size(); ++i) {
    imu_topics[initial.inertial[i].rostopic] = i;
    topics.push_back(initial.inertial[i].rostopic);
  }
  for (std::size_t c = 0; c < initial.cameras.size(); ++c) {
    image_topics[initial.cameras[c].rostopic] = c;
    detection_topics[initial.cameras[c].rostopic + "/tag_detections"] = c;
    topics.push_back(initial.cameras[c].rostopic);
    topics.push_back(initial.cameras[c].rostopic + "/tag_detections");
  }

  OfflineResult result;
  estimator->setUpdateCallback([&result, &estimator](const EstimatorUpdate& u) {
    result.update_ms.push_back(u.solve.total_s * 1e3);
    if (u.solve.iterations > 0) {
      result.solve_iterations.push_back(u.solve.iterations);
      result.log.addCalibration(u.state.stamp_ns, estimator->calibration());
    }
    result.log.addPose(u.state.stamp_ns, u.state.T_G_I, u.pose_covariance);
  });
  const auto start = Clock::now();
  try {
    rosbag::View view(bag, rosbag::TopicQuery(topics));
    if (view.size() == 0) {
      return Status::Error(bag_path + ": no message on the rig's topics (" + topics.front() +
                           ", ...)");
    }
    const double begin = view.getBeginTime().toSec(), end = view.getEndTime().toSec();
    std::size_t done = 0;
    const std::size_t total = view.size();
    for (const rosbag::MessageInstance& m : view) {
      ++done;
      if (options.progress && done % 2000 == 0) {
        options.progress(static_cast<double>(done) / total, m.getTime().toSec() - begin);
      }
      const std::string& topic = m.getTopic();
      if (auto it = imu_topics.find(topic); it != imu_topics.end()) {
        const auto msg = m.instantiate<sensor_msgs::Imu>();
        if (!msg) continue;
        ++result.imu_messages;
        ImuMeasurement reading;
        std::string why;
        const bool gyro_only = initial.inertial[it->second].type == InertialType::kGyroscope;
        if (!ros_conversions::toImuMeasurement(*msg, gyro_only, &reading, &why)) {
          ++result.dropped_messages;
          continue;
        }
        estimator->addImu(it->second, reading);
      } else if (auto ic = image_topics.find(topic); ic != image_topics.end()) {
        const auto msg = m.instantiate<sensor_msgs::Image>();
        if (!msg) continue;
        ++result.image_messages;
        cv::Mat gray;
        std::string why;
        if (!ros_conversions::toGray(msg, &gray, &why)) {
          ++result.dropped_messages;
          continue;
        }
        const auto t0 = Clock::now();
        const TimeNs stamp = ros_conversions::toTimeNs(msg->header.stamp);
        auto tags = frontend->processImage(ic->second, stamp, gray);
        result.frontend_ms.push_back(msSince(t0));
        if (!tags.ok()) {
          ++result.dropped_messages;
          continue;
        }
        frontend->dropBefore(ic->second, stamp - kNsPerSecond);
        estimator->addTagFrame(tags.value().frame);
      } else if (auto id = detection_topics.find(topic); id != detection_topics.end()) {
        const auto msg = m.instantiate<mvis::TagDetectionArray>();
        if (!msg) continue;
        ++result.detection_messages;
        auto tags = frontend->processDetections(ros_conversions::toTagFrame(*msg, id->second));
        if (!tags.ok()) {
          ++result.dropped_messages;
          continue;
        }
        const TimeNs stamp = ros_conversions::toTimeNs(msg->header.stamp);
        frontend->dropBefore(id->second, stamp - kNsPerSecond);
        estimator->addTagFrame(tags.value().frame);
      }
    }
    result.bag_seconds = end - begin;
  } catch (const std::exception& e) {
    return Status::Error(bag_path + ": reading the bag failed: " + e.what());
  }
  if (options.progress) options.progress(1.0, result.bag_seconds);
  result.wall_seconds = msSince(start) * 1e-3;
  if (!estimator->initialized()) {
    return Status::Error("the estimator never initialized: " + estimator->status());
  }
  estimator->computeCovariance();
  result.calibration = estimator->calibration();
  result.trajectory = estimator->trajectory();
  result.counters = estimator->counters();
  result.status = estimator->status();
  return result;
}

}  // namespace mvis
