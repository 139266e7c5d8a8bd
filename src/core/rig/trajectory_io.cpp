#include "mvis/rig/trajectory_io.h"

#include <cinttypes>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace mvis {

Status writeTumTrajectory(const std::string& path, const std::vector<StampedPose>& poses) {
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (!file) return Status::Error(path + ": cannot write");
  std::fprintf(file, "# timestamp tx ty tz qx qy qz qw (imu0 in the world, base clock)\n");
  for (const auto& [stamp, T] : poses) {
    const std::int64_t sec = stamp / kNsPerSecond, nsec = stamp % kNsPerSecond;
    std::fprintf(file, "%" PRId64 ".%09" PRId64 " %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", sec,
                 nsec, T.p.x(), T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w());
  }
  const bool ok = std::fclose(file) == 0;
  return ok ? Status::Ok() : Status::Error(path + ": cannot write");
}

StatusOr<std::vector<StampedPose>> readTumTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::Error(path + ": cannot read the file");
  std::vector<StampedPose> poses;
  int line_number = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string stamp;
    double v[7];
    fields >> stamp;
    for (double& x : v) fields >> x;
    if (!fields) {
      return Status::Error(path + ": line " + std::to_string(line_number) +
                           ": expected 'timestamp tx ty tz qx qy qz qw'");
    }
    // Whole seconds and the fraction apart, so nanoseconds survive.
    const auto dot = stamp.find('.');
    TimeNs ns = std::stoll(stamp.substr(0, dot)) * kNsPerSecond;
    if (dot != std::string::npos) {
      std::string fraction = stamp.substr(dot + 1, 9);
      fraction.resize(9, '0');
      ns += std::stoll(fraction);
    }
    poses.emplace_back(
        ns, SE3(Eigen::Quaterniond(v[6], v[3], v[4], v[5]), Eigen::Vector3d(v[0], v[1], v[2])));
  }
  return poses;
}

}  // namespace mvis
