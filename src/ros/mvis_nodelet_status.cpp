// The nodelet's guided calibration (mvis_nodelet.h): statuses per quantity, the rig's verdict,
// their rviz text and each camera's image coverage.
#include <mvis/CalibrationStatus.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mvis/ros/conversions.h"
#include "mvis/ros/mvis_nodelet.h"

namespace mvis {
namespace {

// A camera's coverage as a picture: one block per cell, green where covered (brighter with more
// corners), dark red where not, a grey grid between.
sensor_msgs::Image coverageImage(const CameraCoverage& c, const ros::Time& stamp,
                                 const std::string& frame) {
  constexpr int kCell = 40;
  sensor_msgs::Image image;
  image.header.stamp = stamp;
  image.header.frame_id = frame;
  image.width = static_cast<std::uint32_t>(c.columns * kCell);
  image.height = static_cast<std::uint32_t>(c.rows * kCell);
  image.encoding = sensor_msgs::image_encodings::BGR8;
  image.step = 3 * image.width;
  image.data.assign(static_cast<std::size_t>(image.step) * image.height, 0);
  int most = 1;
  for (int n : c.corners) most = std::max(most, n);
  for (int r = 0; r < c.rows; ++r) {
    for (int k = 0; k < c.columns; ++k) {
      const int n = c.corners[static_cast<std::size_t>(r * c.columns + k)];
      std::uint8_t g = 0, red = 0;
      if (c.covered(k, r)) {
        g = static_cast<std::uint8_t>(90 + 165 * std::log1p(n) / std::log1p(most));
      } else {
        red = static_cast<std::uint8_t>(n > 0 ? 200 : 140);
      }
      for (int y = r * kCell; y < (r + 1) * kCell; ++y) {
        for (int x = k * kCell; x < (k + 1) * kCell; ++x) {
          const bool line = x % kCell == 0 || y % kCell == 0;
          std::uint8_t* px = &image.data[static_cast<std::size_t>(y) * image.step + 3 * x];
          px[0] = line ? 128 : 0;
          px[1] = line ? 128 : g;
          px[2] = line ? 128 : red;
        }
      }
    }
  }
  return image;
}

}  // namespace

void MvisNodelet::updateStatus(const EstimatorUpdate& u) {
  const bool was_ready = status_->ready();
  const double since = toSeconds(u.state.stamp_ns - first_stamp_ns_);
  for (const QuantityState& s :
       status_->update(u.state.stamp_ns, estimator_->calibration(), u.unobservable)) {
    estimate_log_.addStatus(u.state.stamp_ns, s.sensor, s.quantity, s.statusText(), s.sigma,
                            s.target, s.advice);
    status_timeline_.emplace_back(since, s);
  }
  if (status_timeline_.size() > 5000) {  // a node left running: the newest for the report
    status_timeline_.erase(status_timeline_.begin(), status_timeline_.begin() + 500);
  }
  if (status_->ready() != was_ready) {
    if (status_->ready()) {
      NODELET_INFO_STREAM(getName() << ": the rig is ready: every estimated quantity converged ("
                                    << since << " s in)");
    } else {
      std::string missing;
      for (const QuantityState& s : status_->states()) {
        if (s.status != QuantityStatus::kImproving && s.status != QuantityStatus::kUnobservable) {
          continue;
        }
        missing += (missing.empty() ? "" : "; ") + s.sensor + " " + s.quantity + " " +
                   s.statusText() + (s.advice.empty() ? "" : ": " + s.advice);
      }
      NODELET_WARN_STREAM(getName() << ": the rig is no longer ready: " << missing);
    }
  }
  publishStatus(ros_conversions::toRosTime(u.state.stamp_ns));
}

void MvisNodelet::publishStatus(const ros::Time& stamp) {
  mvis::CalibrationStatus msg;
  msg.header.stamp = stamp;
  msg.header.frame_id = bodyFrame();
  msg.ready = status_->ready();
  if (msg.ready) msg.ready_since = ros_conversions::toRosTime(status_->readySince());
  for (const QuantityState& s : status_->states()) {
    mvis::CalibrationQuantity q;
    q.sensor = s.sensor;
    q.quantity = s.quantity;
    q.status = s.statusText();
    q.sigma = s.sigma;
    q.target = s.target;
    q.unit = s.unit;
    q.advice = s.advice;
    msg.quantities.push_back(q);
  }
  const bool intrinsics = options_.estimate_intrinsics;
  for (std::size_t c = 0; c < status_->coverage().size(); ++c) {
    const CameraCoverage& coverage = status_->coverage()[c];
    if (intrinsics) {
      msg.cameras.push_back(coverage.camera);
      msg.coverage_missing.push_back(coverage.missing());
    }
    if (c < out_.coverage.size() && out_.coverage[c].getNumSubscribers() > 0) {
      out_.coverage[c].publish(
          coverageImage(coverage, stamp, options_.frame_prefix + coverage.camera));
    }
  }
  out_.status.publish(msg);

  // rviz: the verdict and one line per quantity beside the board (in its frame, so that the
  // list stands still while the rig moves), done in green, missing in red (with the advice),
  // held in grey.
  visualization_msgs::MarkerArray markers;
  const auto text = [&](int id, double line, const std::string& words, float r, float g, float b) {
    visualization_msgs::Marker m;
    m.header.frame_id = options_.frame_prefix + "board";
    m.header.stamp = ros::Time();  // the latest transform
    m.frame_locked = true;
    m.ns = "calibration_status";
    m.id = id;
    m.type = visualization_msgs::Marker::TEXT_VIEW_FACING;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.pose.position.x = -0.8;
    m.pose.position.y = 0.8 - 0.07 * line;
    m.pose.position.z = 0.1;
    m.scale.z = line == 0 ? 0.08 : 0.05;
    m.color.r = r;
    m.color.g = g;
    m.color.b = b;
    m.color.a = 1.0f;
    m.text = words;
    markers.markers.push_back(m);
  };
  text(0, 0, msg.ready ? "rig ready" : "rig improving", msg.ready ? 0.2f : 1.0f,
       msg.ready ? 1.0f : 0.3f, 0.2f);
  int id = 1;
  for (const QuantityState& s : status_->states()) {
    char sigma[64] = "";
    if (std::isfinite(s.sigma)) {
      std::snprintf(sigma, sizeof(sigma), " (%.3g of %.3g %s)", s.sigma, s.target, s.unit.c_str());
    }
    std::string words = s.sensor + " " + s.quantity + ": " + s.statusText() + sigma;
    if (!s.advice.empty() && s.status != QuantityStatus::kConverged) words += ": " + s.advice;
    if (s.status == QuantityStatus::kConverged) {
      text(id, id, words, 0.2f, 1.0f, 0.2f);
    } else if (s.status == QuantityStatus::kHeld) {
      text(id, id, words, 0.6f, 0.6f, 0.6f);
    } else {
      text(id, id, words, 1.0f, 0.3f, 0.2f);
    }
    ++id;
  }
  out_.status_markers.publish(markers);
}

}  // namespace mvis
