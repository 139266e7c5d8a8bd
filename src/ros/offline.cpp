#include "mvis/ros/offline.h"

#include <mvis/TagDetectionArray.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <cctype>
#include <chrono>
#include <map>
#include <set>

#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The bag's topics by message type.
std::map<std::string, std::string> bagTopics(const rosbag::Bag& bag) {
  std::map<std::string, std::string> out;
  rosbag::View all(bag);
  for (const rosbag::ConnectionInfo* c : all.getConnections()) out[c->topic] = c->datatype;
  return out;
}

// The bag's topics of the types a rig reads that `used` does not hold, as
// "/cam0/image_raw/compressed (sensor_msgs/CompressedImage), ...", or "" if none.
std::string otherRigLikeTopics(const std::map<std::string, std::string>& topics,
                               const std::set<std::string>& used) {
  static const std::set<std::string> kTypes = {"sensor_msgs/Imu", "sensor_msgs/Image",
                                               "sensor_msgs/CompressedImage",
                                               "mvis/TagDetectionArray"};
  std::string out;
  for (const auto& [topic, type] : topics) {
    if (!kTypes.count(type) || used.count(topic)) continue;
    out += (out.empty() ? "" : ", ") + topic + " (" + type + ")";
  }
  return out;
}

// A message's kind: the message with every number in it replaced by '#'.
std::string kindOf(const std::string& message) {
  std::string out;
  bool in_number = false;
  for (std::size_t i = 0; i < message.size(); ++i) {
    const char c = message[i];
    const bool digit = std::isdigit(static_cast<unsigned char>(c)) != 0;
    const bool part = digit || (in_number && (c == '.' || c == 'e' || c == '-'));
    if (part && !in_number) out += '#';
    if (!part) out += c;
    in_number = part;
  }
  return out;
}

}  // namespace

StatusOr<OfflineResult> runOffline(const Rig& initial, const std::string& bag_path,
                                   const OfflineOptions& options) {
  auto created = Estimator::create(initial, options.estimator);
  if (!created.ok()) return created.status();
  std::unique_ptr<Estimator> estimator = std::move(created).value();
  const bool batch = options.estimator.batch;
  if (batch && options.batch_start != nullptr) {
    const Status started = estimator->setInitialCalibration(*options.batch_start);
    if (!started.ok()) return started;
  }
  if (batch) estimator->setSeedTrajectory(options.batch_seed);
  auto frontend_made = TagFrontend::create(initial, options.frontend);
  if (!frontend_made.ok()) return frontend_made.status();
  std::unique_ptr<TagFrontend> frontend = std::move(frontend_made).value();

  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    return Status::Error(bag_path + ": cannot open the bag: " + e.what());
  }
  const std::map<std::string, std::string> in_bag = bagTopics(bag);
  // Per camera one input, the first the bag has: images, compressed images (decoded here:
  // Debian has no compressed_image_transport), tag detections made elsewhere.
  std::map<std::string, std::size_t> imu_topics, image_topics, compressed_topics, detection_topics;
  std::vector<std::string> topics;
  for (std::size_t i = 0; i < initial.inertial.size(); ++i) {
    imu_topics[initial.inertial[i].rostopic] = i;
    topics.push_back(initial.inertial[i].rostopic);
  }
  std::vector<std::string> camera_inputs(initial.cameras.size());
  for (std::size_t c = 0; c < initial.cameras.size(); ++c) {
    const std::string& raw = initial.cameras[c].rostopic;
    const std::string compressed = raw + "/compressed", detections = raw + "/tag_detections";
    if (in_bag.count(raw) || (!in_bag.count(compressed) && !in_bag.count(detections))) {
      image_topics[raw] = c;
      camera_inputs[c] = raw;
    } else if (in_bag.count(compressed)) {
      compressed_topics[compressed] = c;
      camera_inputs[c] = compressed;
    } else {
      detection_topics[detections] = c;
      camera_inputs[c] = detections;
    }
    topics.push_back(camera_inputs[c]);
  }
  std::vector<long> imu_count(initial.inertial.size(), 0), camera_count(initial.cameras.size(), 0);
  const auto silent = [&]() {
    std::string out;
    for (std::size_t i = 0; i < imu_count.size(); ++i) {
      if (imu_count[i] > 0) continue;
      out += (out.empty() ? "" : "; ") + initial.inertial[i].name + ": no message on " +
             initial.inertial[i].rostopic;
    }
    for (std::size_t c = 0; c < camera_count.size(); ++c) {
      if (camera_count[c] > 0) continue;
      const std::string& raw = initial.cameras[c].rostopic;
      out += (out.empty() ? "" : "; ") + initial.cameras[c].name + ": no message on " + raw +
             " (sensor_msgs/Image), " + raw + "/compressed (sensor_msgs/CompressedImage) or " +
             raw + "/tag_detections (mvis/TagDetectionArray)";
    }
    if (out.empty()) return out;
    const std::string others =
        otherRigLikeTopics(in_bag, std::set<std::string>(topics.begin(), topics.end()));
    return out + (others.empty() ? "; the bag has no other topic of those types"
                                 : "; the bag has " + others);
  };

  OfflineResult result;
  double bag_time = 0.0;  // of the message being read [s from the start]
  CalibrationStatusTracker tracker(initial, options.estimator, options.status_targets);
  estimator->setUpdateCallback(
      [&result, &estimator, &bag_time, &tracker, batch](const EstimatorUpdate& u) {
        result.update_ms.push_back(u.solve.total_s * 1e3);
        if (u.solve.iterations > 0 && !batch) {
          result.solve_iterations.push_back(u.solve.iterations);
          result.log.addCalibration(u.state.stamp_ns, estimator->calibration());
        }
        result.log.addPose(u.state.stamp_ns, u.state.T_G_I, u.pose_covariance);
        for (const auto& c : u.changes) {
          result.log.addChange(c.stamp_ns, c.sensor, c.quantity, c.size, c.size_sigma);
          result.changes.push_back(c);
          result.change_bag_s.push_back(bag_time);
        }
        result.unobservable.clear();
        for (const auto& d : u.unobservable) result.unobservable.push_back(d.text());
        if (u.calibration_covariance_updated && !batch) {
          for (const QuantityState& s :
               tracker.update(u.state.stamp_ns, estimator->calibration(), u.unobservable)) {
            result.log.addStatus(u.state.stamp_ns, s.sensor, s.quantity, s.statusText(), s.sigma,
                                 s.target, s.advice);
            result.status_timeline.push_back({bag_time, s});
          }
        }
      });
  std::map<std::string, std::size_t> kinds;  // kind -> index in result.warning_kinds
  const auto note = [&](const std::string& message) {
    const auto [it, added] = kinds.emplace(kindOf(message), result.warning_kinds.size());
    if (added) result.warning_kinds.push_back({message, 0, bag_time});
    ++result.warning_kinds[it->second].count;
  };
  const auto start = Clock::now();
  try {
    rosbag::View view(bag, rosbag::TopicQuery(topics));
    if (view.size() == 0) {
      return Status::Error(bag_path + ": no message on the rig's topics: " + silent());
    }
    const double begin = view.getBeginTime().toSec(), end = view.getEndTime().toSec();
    std::size_t done = 0;
    const std::size_t total = view.size();
    for (const rosbag::MessageInstance& m : view) {
      ++done;
      bag_time = m.getTime().toSec() - begin;
      if (options.progress && done % 2000 == 0) {
        options.progress(static_cast<double>(done) / total, m.getTime().toSec() - begin);
      }
      const std::string& topic = m.getTopic();
      if (auto it = imu_topics.find(topic); it != imu_topics.end()) {
        const auto msg = m.instantiate<sensor_msgs::Imu>();
        if (!msg) continue;
        ++result.imu_messages;
        ++imu_count[it->second];
        ImuMeasurement reading;
        std::string why;
        const bool gyro_only = initial.inertial[it->second].type == InertialType::kGyroscope;
        if (!ros_conversions::toImuMeasurement(*msg, gyro_only, &reading, &why)) {
          ++result.dropped_messages;
          note(initial.inertial[it->second].name + ": dropped " + why);
          continue;
        }
        const Status status = estimator->addImu(it->second, reading);
        if (!status.ok()) note(status.message());
      } else if (image_topics.count(topic) || compressed_topics.count(topic)) {
        const bool compressed = compressed_topics.count(topic) > 0;
        const std::size_t camera = compressed ? compressed_topics[topic] : image_topics[topic];
        // gray may share the raw message's pixels: the message stays alive as long as it.
        sensor_msgs::ImageConstPtr raw_msg;
        cv::Mat gray;
        std::string why;
        TimeNs stamp = 0;
        if (compressed) {
          const auto msg = m.instantiate<sensor_msgs::CompressedImage>();
          if (!msg) continue;
          const auto t0 = Clock::now();
          const bool decoded = ros_conversions::toGray(*msg, &gray, &why);
          result.decode_ms.push_back(msSince(t0));
          if (!decoded) {
            ++result.dropped_messages;
            note(initial.cameras[camera].name + ": dropped " + why);
            continue;
          }
          stamp = ros_conversions::toTimeNs(msg->header.stamp);
        } else {
          raw_msg = m.instantiate<sensor_msgs::Image>();
          if (!raw_msg) continue;
          if (!ros_conversions::toGray(raw_msg, &gray, &why)) {
            ++result.image_messages;
            ++result.dropped_messages;
            note(initial.cameras[camera].name + ": dropped " + why);
            continue;
          }
          stamp = ros_conversions::toTimeNs(raw_msg->header.stamp);
        }
        ++result.image_messages;
        ++camera_count[camera];
        const auto t0 = Clock::now();
        auto tags = frontend->processImage(camera, stamp, gray);
        result.frontend_ms.push_back(msSince(t0));
        if (!tags.ok()) {
          ++result.dropped_messages;
          note(initial.cameras[camera].name + ": dropped: " + tags.status().message());
          continue;
        }
        frontend->dropBefore(camera, stamp - kNsPerSecond);
        const Status status = estimator->addTagFrame(tags.value().frame);
        if (!status.ok()) note(status.message());
        if (status.ok()) tracker.addFrame(tags.value().frame);
      } else if (auto id = detection_topics.find(topic); id != detection_topics.end()) {
        const auto msg = m.instantiate<mvis::TagDetectionArray>();
        if (!msg) continue;
        ++result.detection_messages;
        ++camera_count[id->second];
        auto tags = frontend->processDetections(ros_conversions::toTagFrame(*msg, id->second));
        if (!tags.ok()) {
          ++result.dropped_messages;
          note(initial.cameras[id->second].name + ": dropped: " + tags.status().message());
          continue;
        }
        const TimeNs stamp = ros_conversions::toTimeNs(msg->header.stamp);
        frontend->dropBefore(id->second, stamp - kNsPerSecond);
        const Status status = estimator->addTagFrame(tags.value().frame);
        if (!status.ok()) note(status.message());
        if (status.ok()) tracker.addFrame(tags.value().frame);
      }
    }
    result.bag_seconds = end - begin;
  } catch (const std::exception& e) {
    return Status::Error(bag_path + ": reading the bag failed: " + e.what());
  }
  if (options.progress) options.progress(1.0, result.bag_seconds);
  result.wall_seconds = msSince(start) * 1e-3;
  const std::string missing = silent();
  if (!estimator->initialized()) {
    // Started over (a fault, a restart of the base IMU's clock) too near the end to initialize
    // again: what it estimated before is still the result, its calibration the one it started
    // over from. Only a run that never got a state has nothing to write.
    if (batch || estimator->trajectory().empty()) {
      return Status::Error("the estimator never initialized: " + estimator->status() +
                           (missing.empty() ? "" : " (" + missing + ")"));
    }
    result.warnings.push_back(
        "the estimator was initializing again at the end of the bag (" + estimator->status() +
        "): the calibration written is the one it started over from, the trajectory ends there");
  }
  if (!missing.empty()) result.warnings.push_back(missing);
  if (batch) {
    auto solved = estimator->solveBatch(options.batch_iterations, options.batch_progress);
    if (!solved.ok()) return solved.status();
    result.batch = std::move(solved).value();
    result.wall_seconds = msSince(start) * 1e-3;
  } else if (estimator->initialized()) {
    const Status covariance = estimator->computeCovariance();
    if (!covariance.ok()) result.warnings.push_back(covariance.message());
  }
  result.calibration = estimator->calibration();
  result.trajectory = estimator->trajectory();
  if (batch) {
    // One solution: its calibration once, and the states whose covariance it computed.
    result.log = EstimateLog();
    if (!result.trajectory.empty()) {
      result.log.addCalibration(result.trajectory.back().stamp_ns, result.calibration);
    }
    const auto covariances = estimator->batchPoseCovariances();
    std::size_t k = 0;
    for (const EstimatorState& s : result.trajectory) {
      while (k < covariances.size() && covariances[k].first < s.stamp_ns) ++k;
      if (k < covariances.size() && covariances[k].first == s.stamp_ns) {
        result.log.addPose(s.stamp_ns, s.T_G_I, covariances[k].second);
      }
    }
  }
  result.residuals = estimator->residualStatistics();
  result.statuses = tracker.states();
  result.coverage = tracker.coverage();
  result.counters = estimator->counters();
  result.sigma_inflation = estimator->sigmaInflation();
  result.time_offset_floor = estimator->timeOffsetFloor();
  result.status = estimator->status();
  return result;
}

}  // namespace mvis
