#include "mvis/rig/rig.h"

#include <cstdio>
#include <sstream>

namespace mvis {

const char* toString(InertialType type) { return type == InertialType::kImu ? "imu" : "gyroscope"; }

const char* toString(ImuModel model) {
  switch (model) {
    case ImuModel::kCalibrated:
      return "calibrated";
    case ImuModel::kRpng:
      return "rpng";
    case ImuModel::kKalibr:
      return "kalibr";
  }
  return "calibrated";
}

const char* toString(DistortionModel model) {
  return model == DistortionModel::kRadtan ? "radtan" : "equidistant";
}

Eigen::Vector3d AprilGrid::corner(int id, int c) const {
  const double pitch = (1.0 + tag_spacing) * tag_size;
  const double x0 = pitch * (id % tag_cols);
  const double y0 = pitch * (id / tag_cols);
  return Eigen::Vector3d(x0, y0, 0.0) + tagCorner(c, tag_size);
}

Eigen::Vector3d tagCorner(int c, double side) {
  return Eigen::Vector3d(c == 1 || c == 2 ? side : 0.0, c >= 2 ? side : 0.0, 0.0);
}

std::string Rig::summary() const {
  std::ostringstream out;
  char line[256];
  for (const auto& s : inertial) {
    // (+ 0.0 turns -0.0 into 0.0 for printing)
    const Eigen::Vector3d p_b_i = s.T_i_b.inverse().p + Eigen::Vector3d::Zero();
    std::snprintf(line, sizeof(line),
                  "%s %-9s %-28s %6.1f Hz  model %-10s  p_imu0_%s [%.3f %.3f %.3f] m  "
                  "offset %+.4f s\n",
                  s.name.c_str(), toString(s.type), s.rostopic.c_str(), s.update_rate,
                  toString(s.model), s.name.c_str(), p_b_i.x(), p_b_i.y(), p_b_i.z(),
                  s.time_offset);
    out << line;
  }
  for (const auto& c : cameras) {
    const Eigen::Vector3d p_b_c = c.T_cam_imu.inverse().p;
    std::snprintf(line, sizeof(line),
                  "%s camera    %-28s %dx%d  %-11s f [%.1f %.1f]  p_imu0_%s [%.3f %.3f %.3f] m  "
                  "shift %+.4f s\n",
                  c.name.c_str(), c.rostopic.c_str(), c.resolution[0], c.resolution[1],
                  toString(c.distortion_model), c.intrinsics[0], c.intrinsics[1], c.name.c_str(),
                  p_b_c.x(), p_b_c.y(), p_b_c.z(), c.timeshift_cam_imu);
    out << line;
  }
  if (target) {
    std::snprintf(line, sizeof(line), "target aprilgrid %dx%d %s, tag %.4f m, spacing %.3f\n",
                  target->tag_cols, target->tag_rows, target->tag_family.c_str(), target->tag_size,
                  target->tag_spacing);
    out << line;
  } else {
    out << "target none: tag corners are estimated as landmarks\n";
  }
  return out.str();
}

const std::vector<std::string>& supportedTagFamilies() {
  static const std::vector<std::string> kFamilies = {
      "tag36h11",       "tag25h9",          "tag16h5",          "tagCircle21h7",
      "tagCircle49h12", "tagStandard41h12", "tagStandard52h13", "tagCustom48h12"};
  return kFamilies;
}

}  // namespace mvis
