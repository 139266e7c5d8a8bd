// mvis_faults IN.bag OUT.bag FAULTS [--seed N]
// Copies a bag with faults injected (include/mvis/sim/faults.h): streams are the bag's topics
// ("all" for every one), times are seconds from the bag's first message. Header stamps of
// sensor_msgs/Imu, Image, CompressedImage and mvis/TagDetectionArray are rewritten; other
// messages are copied as they are (they still take part in gaps, replays and reordering). The
// new arrival order is kept by the record times, which advance as the original ones did (a
// replayed stretch takes as long again). Corrupt messages: an IMU reading's angular rate NaN,
// an image's pixels cut to half, every tag corner 40 px off.
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "mvis/TagDetectionArray.h"
#include "mvis/ros/conversions.h"
#include "mvis/sim/faults.h"

namespace {

int usage(const char* message) {
  std::fprintf(
      stderr,
      "%s\nusage: mvis_faults IN.bag OUT.bag FAULTS [--seed N]\n"
      "  FAULTS  comma-separated kind:topic:at:length[:value] (topic 'all': every one;\n"
      "          times in s from the bag's first message), e.g.\n"
      "          gap:/imu0:20:0.3,restart:all:45:10,jump:/cam1/tags:30:0:-1000\n"
      "    gap:T:AT:LEN         T's messages within [AT, AT+LEN) lost\n"
      "    restart:all:AT:LEN   at AT the first LEN s replayed, then the rest\n"
      "    jump:T:AT:0:DT       T's stamps from AT on DT s later (< 0: earlier)\n"
      "    rate:T:AT:LEN:EPS    T's clock 1+EPS times too fast for LEN s, then set right\n"
      "    corrupt:T:AT:LEN:P   a share P of T's messages garbled (NaN rates, cut images,\n"
      "                         tag corners 40 px off)\n"
      "    repeat:T:AT:LEN:P    a share P delivered twice\n"
      "    swap:T:AT:LEN:P      a share P swapped with T's next message\n"
      "  --seed N  which messages a share picks (default 1)\n",
      message);
  return 2;
}

// The header stamp of a message mvis reads, rewritten to `stamp` (and garbled if `corrupt`);
// false for another type (copied as it is).
template <typename M>
bool rewrite(const rosbag::MessageInstance& m, mvis::TimeNs stamp, bool corrupt, rosbag::Bag* out,
             const ros::Time& record) {
  auto msg = m.instantiate<M>();
  if (!msg) return false;
  M copy = *msg;
  copy.header.stamp = mvis::ros_conversions::toRosTime(stamp);
  if (corrupt) {
    if constexpr (std::is_same_v<M, sensor_msgs::Imu>) {
      copy.angular_velocity.x = std::numeric_limits<double>::quiet_NaN();
    } else if constexpr (std::is_same_v<M, mvis::TagDetectionArray>) {
      for (auto& d : copy.detections) {
        for (std::size_t k = 0; k < d.corners.size(); ++k)
          d.corners[k] += k % 2 == 0 ? 40.0 : -25.0;
      }
    } else {
      copy.data.resize(copy.data.size() / 2);
    }
  }
  out->write(m.getTopic(), record, copy, m.getConnectionHeader());
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> positional;
  std::uint64_t seed = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--seed") == 0) {
      if (i + 1 >= argc) return usage("--seed needs a number");
      seed = std::strtoull(argv[++i], nullptr, 10);
    } else {
      positional.push_back(argv[i]);
    }
  }
  if (positional.size() != 3) return usage("IN.bag, OUT.bag and FAULTS are required");
  const auto faults = mvis::parseFaults(positional[2]);
  if (!faults.ok()) return usage(faults.status().message().c_str());
  try {
    rosbag::Bag in(positional[0], rosbag::bagmode::Read);
    rosbag::View view(in);
    std::vector<rosbag::MessageInstance> messages(view.begin(), view.end());
    // Streams by topic, stamped by their header (record time for other types).
    std::vector<mvis::StreamMessage> streams;
    streams.reserve(messages.size());
    for (const auto& m : messages) {
      mvis::TimeNs stamp = mvis::ros_conversions::toTimeNs(m.getTime());
      if (auto imu = m.instantiate<sensor_msgs::Imu>()) {
        stamp = mvis::ros_conversions::toTimeNs(imu->header.stamp);
      } else if (auto image = m.instantiate<sensor_msgs::Image>()) {
        stamp = mvis::ros_conversions::toTimeNs(image->header.stamp);
      } else if (auto jpeg = m.instantiate<sensor_msgs::CompressedImage>()) {
        stamp = mvis::ros_conversions::toTimeNs(jpeg->header.stamp);
      } else if (auto tags = m.instantiate<mvis::TagDetectionArray>()) {
        stamp = mvis::ros_conversions::toTimeNs(tags->header.stamp);
      }
      streams.push_back({m.getTopic(), stamp});
    }
    const auto faulted = mvis::applyFaults(streams, faults.value(), seed);
    rosbag::Bag out(positional[1], rosbag::bagmode::Write);
    mvis::TimeNs record = 0;
    for (std::size_t i = 0; i < faulted.size(); ++i) {
      const auto& f = faulted[i];
      const auto& m = messages[f.source];
      const mvis::TimeNs original = mvis::ros_conversions::toTimeNs(m.getTime());
      if (i == 0) {
        record = original;
      } else {
        // As the original record times advanced between these two sources (never backwards,
        // at most a second: a replay or reordering takes as long as the data did).
        const mvis::TimeNs step =
            original - mvis::ros_conversions::toTimeNs(messages[faulted[i - 1].source].getTime());
        record += std::min<mvis::TimeNs>(std::max<mvis::TimeNs>(step, 1), mvis::kNsPerSecond);
      }
      const ros::Time when = mvis::ros_conversions::toRosTime(record);
      if (!rewrite<sensor_msgs::Imu>(m, f.stamp_ns, f.corrupt, &out, when) &&
          !rewrite<sensor_msgs::Image>(m, f.stamp_ns, f.corrupt, &out, when) &&
          !rewrite<sensor_msgs::CompressedImage>(m, f.stamp_ns, f.corrupt, &out, when) &&
          !rewrite<mvis::TagDetectionArray>(m, f.stamp_ns, f.corrupt, &out, when)) {
        out.write(m.getTopic(), when, m, m.getConnectionHeader());
      }
    }
    std::printf("mvis_faults: %zu messages in, %zu out, with", messages.size(), faulted.size());
    for (const auto& f : faults.value()) std::printf(" %s", mvis::toString(f).c_str());
    std::printf("\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mvis_faults: %s\n", e.what());
    return 1;
  }
  return 0;
}
