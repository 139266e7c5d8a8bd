#include "mvis/ros/offline.h"

#include <mvis/TagDetectionArray.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <cctype>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "mvis/ros/conversions.h"

namespace mvis {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// An image message to detect tags in, off the thread that reads the bag.
struct ImageJob {
  std::size_t camera = 0;
  sensor_msgs::ImageConstPtr raw;               // or
  sensor_msgs::CompressedImageConstPtr packed;  // decoded by the job
  std::uint64_t ticket = 0;                     // its camera's turn (CameraTurns)
};

// What the job found, handed to the estimator in bag order.
struct ImageOutcome {
  std::size_t camera = 0;
  bool raw = true;
  TimeNs stamp = 0;
  std::string dropped;      // why the message could not be used ("" if it could)
  double decode_ms = -1.0;  // compressed images
  double frontend_ms = 0.0;
  std::optional<StatusOr<TagFrontendResult>> tags;
};

// Each camera's images are located (TagFrontend::locateTags) one at a time and in bag order (the
// front end's rule: the region searched is predicted from the camera's previous images). A job
// takes a ticket when it is submitted and waits for its turn after decoding; jobs start in
// submission order, so the turn before it is always taken or running.
class CameraTurns {
 public:
  explicit CameraTurns(std::size_t cameras) : next_ticket_(cameras, 0), serving_(cameras, 0) {}
  std::uint64_t ticket(std::size_t camera) { return next_ticket_[camera]++; }  // reader thread
  template <typename Work>
  void inTurn(std::size_t camera, std::uint64_t ticket, Work&& work) {
    std::unique_lock<std::mutex> lock(mutex_);
    turn_.wait(lock, [&] { return serving_[camera] == ticket; });
    lock.unlock();
    work();
    lock.lock();
    ++serving_[camera];
    turn_.notify_all();
  }

 private:
  std::vector<std::uint64_t> next_ticket_;
  std::mutex mutex_;
  std::condition_variable turn_;
  std::vector<std::uint64_t> serving_;
};

// A fixed set of threads running image jobs in submission order.
class ImageWorkers {
 public:
  explicit ImageWorkers(int threads) {
    for (int i = 0; i < threads; ++i) {
      threads_.emplace_back([this] {
        for (;;) {
          std::packaged_task<ImageOutcome()> task;
          {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [this] { return stop_ || !tasks_.empty(); });
            if (tasks_.empty()) return;
            task = std::move(tasks_.front());
            tasks_.pop_front();
          }
          task();
        }
      });
    }
  }
  ~ImageWorkers() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& t : threads_) t.join();
  }
  std::future<ImageOutcome> submit(std::function<ImageOutcome()> job) {
    std::packaged_task<ImageOutcome()> task(std::move(job));
    auto future = task.get_future();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      tasks_.push_back(std::move(task));
    }
    wake_.notify_one();
    return future;
  }

 private:
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<ImageOutcome()>> tasks_;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

ImageOutcome detectImage(const ImageJob& job, TagFrontend* frontend, CameraTurns* turns) {
  ImageOutcome out;
  out.camera = job.camera;
  out.raw = job.raw != nullptr;
  cv::Mat gray;  // may share the raw message's pixels (the job holds the message)
  std::string why;
  bool usable = false;
  if (!out.raw) {
    const auto t0 = Clock::now();
    usable = ros_conversions::toGray(*job.packed, &gray, &why);
    out.decode_ms = msSince(t0);
    out.stamp = ros_conversions::toTimeNs(job.packed->header.stamp);
  } else {
    usable = ros_conversions::toGray(job.raw, &gray, &why);
    out.stamp = ros_conversions::toTimeNs(job.raw->header.stamp);
  }
  // Found in turn (a dropped image takes its turn too, so that the camera's next one gets its
  // own); the corners refined outside it, beside the camera's next image.
  std::optional<StatusOr<LocatedTags>> located;
  double located_ms = 0.0;
  turns->inTurn(job.camera, job.ticket, [&] {
    if (!usable) return;
    const auto t0 = Clock::now();
    located = frontend->locateTags(job.camera, out.stamp, gray);
    located_ms = msSince(t0);
  });
  if (!usable) {
    out.dropped = "dropped " + why;
    return out;
  }
  const auto t0 = Clock::now();
  if (located->ok()) {
    out.tags = frontend->finishImage(job.camera, gray, std::move(*located).value());
  } else {
    out.tags = located->status();
  }
  out.frontend_ms = located_ms + msSince(t0);
  return out;
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
  // Images are detected on `image_threads` workers while the bag is read; everything reaches the
  // estimator in bag order, whatever the thread count (the same bytes out).
  struct Pending {
    double bag_time = 0.0;
    bool is_image = false;
    std::function<void()> now;        // an IMU reading or a detection message
    std::future<ImageOutcome> image;  // an image's tags
  };
  std::deque<Pending> pending;
  CameraTurns turns(initial.cameras.size());
  int image_threads = options.image_threads > 0
                          ? options.image_threads
                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::optional<ImageWorkers> workers;
  if (image_threads > 1) workers.emplace(image_threads);
  const std::size_t max_in_flight = 4 * static_cast<std::size_t>(image_threads);
  std::size_t images_in_flight = 0;
  const auto consume = [&](ImageOutcome o) {
    const std::string& name = initial.cameras[o.camera].name;
    if (o.decode_ms >= 0.0) result.decode_ms.push_back(o.decode_ms);
    if (!o.dropped.empty()) {
      if (o.raw) ++result.image_messages;
      ++result.dropped_messages;
      note(name + ": " + o.dropped);
      return;
    }
    ++result.image_messages;
    ++camera_count[o.camera];
    result.frontend_ms.push_back(o.frontend_ms);
    if (!o.tags->ok()) {
      ++result.dropped_messages;
      note(name + ": dropped: " + o.tags->status().message());
      return;
    }
    result.detection_stages.push_back(o.tags->value().stages);
    if (o.tags->value().predicted_region) {
      ++result.predicted_images;
      result.searched_fraction_sum += o.tags->value().searched_fraction;
    }
    frontend->dropBefore(o.camera, o.stamp - kNsPerSecond);
    const Status status = estimator->addTagFrame(o.tags->value().frame);
    if (!status.ok()) note(status.message());
    if (status.ok()) tracker.addFrame(o.tags->value().frame);
  };
  // Hands the estimator what is ready at the front; `all`: everything, waiting for the images.
  const auto drain = [&](bool all) {
    while (!pending.empty()) {
      Pending& p = pending.front();
      if (p.is_image) {
        const bool ready = p.image.wait_for(std::chrono::seconds(0)) == std::future_status::ready;
        if (!ready && !all && images_in_flight < max_in_flight) return;
        const double reading = bag_time;
        bag_time = p.bag_time;
        consume(p.image.get());
        bag_time = reading;
        --images_in_flight;
      } else {
        const double reading = bag_time;
        bag_time = p.bag_time;
        p.now();
        bag_time = reading;
      }
      pending.pop_front();
    }
  };
  const auto defer = [&](std::function<void()> call) {
    if (pending.empty()) {
      call();
      return;
    }
    Pending p;
    p.bag_time = bag_time;
    p.now = std::move(call);
    pending.push_back(std::move(p));
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
          // In bag order with everything else said (images may still be pending).
          defer([&, text = initial.inertial[it->second].name + ": dropped " + why] { note(text); });
          continue;
        }
        const std::size_t sensor = it->second;
        defer([&, sensor, reading] {
          const Status status = estimator->addImu(sensor, reading);
          if (!status.ok()) note(status.message());
        });
      } else if (image_topics.count(topic) || compressed_topics.count(topic)) {
        const bool compressed = compressed_topics.count(topic) > 0;
        ImageJob job;
        job.camera = compressed ? compressed_topics[topic] : image_topics[topic];
        if (compressed) {
          job.packed = m.instantiate<sensor_msgs::CompressedImage>();
          if (!job.packed) continue;
        } else {
          job.raw = m.instantiate<sensor_msgs::Image>();
          if (!job.raw) continue;
        }
        job.ticket = turns.ticket(job.camera);
        TagFrontend* f = frontend.get();
        CameraTurns* t = &turns;
        Pending p;
        p.bag_time = bag_time;
        if (workers) {
          p.image = workers->submit([job, f, t] { return detectImage(job, f, t); });
        } else {
          std::promise<ImageOutcome> done;
          done.set_value(detectImage(job, f, t));
          p.image = done.get_future();
        }
        p.is_image = true;
        ++images_in_flight;
        pending.push_back(std::move(p));
        drain(false);
      } else if (auto id = detection_topics.find(topic); id != detection_topics.end()) {
        const auto msg = m.instantiate<mvis::TagDetectionArray>();
        if (!msg) continue;
        ++result.detection_messages;
        ++camera_count[id->second];
        const std::size_t camera = id->second;
        defer([&, msg, camera] {
          auto tags = frontend->processDetections(ros_conversions::toTagFrame(*msg, camera));
          if (!tags.ok()) {
            ++result.dropped_messages;
            note(initial.cameras[camera].name + ": dropped: " + tags.status().message());
            return;
          }
          const TimeNs stamp = ros_conversions::toTimeNs(msg->header.stamp);
          frontend->dropBefore(camera, stamp - kNsPerSecond);
          const Status status = estimator->addTagFrame(tags.value().frame);
          if (!status.ok()) note(status.message());
          if (status.ok()) tracker.addFrame(tags.value().frame);
        });
      }
    }
    drain(true);
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
