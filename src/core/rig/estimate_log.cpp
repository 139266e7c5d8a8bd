#include "mvis/rig/estimate_log.h"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <limits>

namespace mvis {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Past `max_rows`, the rows of every other stamp (the first one kept): a solve's rows stay
// together.
template <typename Row>
void thin(std::vector<Row>* rows, std::size_t max_rows) {
  if (rows->size() <= max_rows) return;
  std::size_t kept = 0, group = 0;
  for (std::size_t i = 0; i < rows->size(); ++i) {
    if (i > 0 && (*rows)[i].stamp_ns != (*rows)[i - 1].stamp_ns) ++group;
    if (group % 2 == 0) (*rows)[kept++] = (*rows)[i];
  }
  rows->resize(kept);
}

void writeNumber(std::FILE* file, double v) {
  if (std::isnan(v)) {
    std::fputs(",nan", file);
  } else {
    std::fprintf(file, ",%.10g", v);
  }
}

}  // namespace

void writeStamp(std::FILE* file, TimeNs stamp) {
  const bool negative = stamp < 0;
  const std::int64_t a = negative ? -stamp : stamp;
  std::fprintf(file, "%s%" PRId64 ".%09" PRId64, negative ? "-" : "", a / kNsPerSecond,
               a % kNsPerSecond);
}

int EstimateLog::sensorIndex(const std::string& name, const char* kind) {
  for (std::size_t i = 0; i < names_.size(); ++i) {
    if (names_[i] == name) return static_cast<int>(i);
  }
  names_.push_back(name);
  kinds_.push_back(kind);
  return static_cast<int>(names_.size()) - 1;
}

// Columns 15-38 of a row: an rpng sensor's Tw, Ta (upper triangular, column-wise), Tg
// (row-major) and Log(R_IMUtoACC), with standard deviations; nan otherwise.
static void imuIntrinsicColumns(const InertialSensor& s, Eigen::Ref<Eigen::VectorXd> value,
                                Eigen::Ref<Eigen::VectorXd> sd) {
  value.setConstant(kNaN);
  sd.setConstant(kNaN);
  if (s.model != ImuModel::kRpng) return;
  const ImuIntrinsics& in = s.intrinsics;
  int k = 0;
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r <= c; ++r, ++k) {
      value[k] = in.Tw(r, c);
      value[6 + k] = in.Ta(r, c);
      if (s.std) {
        sd[k] = s.std->Tw(r, c);
        sd[6 + k] = s.std->Ta(r, c);
      }
    }
  }
  for (int e = 0; e < 9; ++e) {
    value[12 + e] = in.Tg(e / 3, e % 3);
    if (s.std) sd[12 + e] = s.std->Tg(e / 3, e % 3);
  }
  value.tail<3>() = lie::logSO3(in.R_IMUtoACC);
  if (s.std) sd.tail<3>() = s.std->R_IMUtoACC;
}

void EstimateLog::addCalibration(TimeNs stamp_ns, const Rig& rig) {
  for (const Camera& c : rig.cameras) {
    CalibrationRow row{stamp_ns, sensorIndex(c.name, "camera"), {}, {}};
    row.value.setConstant(kNaN);
    row.std.setConstant(kNaN);
    row.value.head<15>() << lie::logQuat(c.T_cam_imu.q), c.T_cam_imu.p, c.timeshift_cam_imu,
        c.intrinsics, c.distortion_coeffs;
    if (c.std) {
      row.std.head<15>() << c.std->rotation, c.std->translation, c.std->timeshift_cam_imu,
          c.std->intrinsics, c.std->distortion_coeffs;
    }
    calibration_.push_back(row);
  }
  for (std::size_t i = 0; i < rig.inertial.size(); ++i) {
    const InertialSensor& s = rig.inertial[i];
    if (i == 0 && s.model != ImuModel::kRpng) continue;
    const bool gyro = s.type == InertialType::kGyroscope;
    CalibrationRow row{stamp_ns, sensorIndex(s.name, gyro ? "gyroscope" : "imu"), {}, {}};
    row.value.setConstant(kNaN);
    row.std.setConstant(kNaN);
    if (i > 0) {
      row.value.head<7>() << lie::logQuat(s.T_i_b.q), s.T_i_b.p, s.time_offset;
      if (s.std) row.std.head<7>() << s.std->rotation, s.std->translation, s.std->time_offset;
      if (gyro) {  // a gyroscope has no position
        row.value.segment<3>(3).setConstant(kNaN);
        row.std.segment<3>(3).setConstant(kNaN);
      }
    }
    imuIntrinsicColumns(s, row.value.tail<24>(), row.std.tail<24>());
    calibration_.push_back(row);
  }
  thin(&calibration_, max_rows_);
}

void EstimateLog::addPose(TimeNs stamp_ns, const SE3& T_G_I,
                          const Eigen::Matrix<double, 6, 6>& covariance) {
  if (!covariance.allFinite()) return;
  poses_.push_back({stamp_ns, T_G_I, covariance});
  thin(&poses_, max_rows_);
}

Status EstimateLog::write(const std::string& dir) const {
  const Status calibration = writeCalibration(dir + "/calibration.csv");
  if (!calibration.ok()) return calibration;
  const std::string pose_path = dir + "/pose_covariance.csv";
  std::FILE* file = std::fopen(pose_path.c_str(), "w");
  if (!file) return Status::Error(pose_path + ": cannot write");
  std::fputs("stamp,tx,ty,tz,qx,qy,qz,qw", file);
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) std::fprintf(file, ",c%d%d", r, c);
  }
  std::fputc('\n', file);
  for (const PoseRow& row : poses_) {
    writeStamp(file, row.stamp_ns);
    const SE3& T = row.T_G_I;
    for (double v : {T.p.x(), T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w()}) {
      writeNumber(file, v);
    }
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) writeNumber(file, row.covariance(r, c));
    }
    std::fputc('\n', file);
  }
  if (std::fclose(file) != 0) return Status::Error(pose_path + ": cannot write");
  const std::string changes_path = dir + "/calibration_changes.csv";
  file = std::fopen(changes_path.c_str(), "w");
  if (!file) return Status::Error(changes_path + ": cannot write");
  std::fputs("stamp,sensor,quantity,size,size_sigma\n", file);
  for (const ChangeRow& row : changes_) {
    writeStamp(file, row.stamp_ns);
    std::fprintf(file, ",%s,%s", row.sensor.c_str(), row.quantity.c_str());
    writeNumber(file, row.size);
    writeNumber(file, row.size_sigma);
    std::fputc('\n', file);
  }
  if (std::fclose(file) != 0) return Status::Error(changes_path + ": cannot write");
  const std::string status_path = dir + "/calibration_status.csv";
  file = std::fopen(status_path.c_str(), "w");
  if (!file) return Status::Error(status_path + ": cannot write");
  std::fputs("stamp,sensor,quantity,status,sigma,target,advice\n", file);
  for (const StatusRow& row : statuses_) {
    writeStamp(file, row.stamp_ns);
    std::fprintf(file, ",%s,%s,%s", row.sensor.c_str(), row.quantity.c_str(), row.status.c_str());
    writeNumber(file, row.sigma);
    writeNumber(file, row.target);
    std::string quoted = "\"";  // CSV: in quotes, a quote doubled
    for (char ch : row.advice) quoted += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    std::fprintf(file, ",%s\"\n", quoted.c_str());
  }
  if (std::fclose(file) != 0) return Status::Error(status_path + ": cannot write");
  return Status::Ok();
}

void EstimateLog::addStatus(TimeNs stamp_ns, const std::string& sensor, const std::string& quantity,
                            const std::string& status, double sigma, double target,
                            const std::string& advice) {
  // A node left running keeps the newest rows (a tenth of them dropped at the bound).
  if (statuses_.size() >= max_rows_) {
    statuses_.erase(statuses_.begin(),
                    statuses_.begin() + static_cast<std::ptrdiff_t>(max_rows_ / 10 + 1));
  }
  statuses_.push_back({stamp_ns, sensor, quantity, status, sigma, target, advice});
}

void EstimateLog::addChange(TimeNs stamp_ns, const std::string& sensor, const std::string& quantity,
                            double size, double size_sigma) {
  changes_.push_back({stamp_ns, sensor, quantity, size, size_sigma});
}

Status EstimateLog::writeCalibration(const std::string& calibration_path) const {
  std::FILE* file = std::fopen(calibration_path.c_str(), "w");
  if (!file) return Status::Error(calibration_path + ": cannot write");
  std::fputs(
      "stamp,sensor,kind,rx,ry,rz,px,py,pz,time_offset,std_rx,std_ry,std_rz,std_px,std_py,"
      "std_pz,std_time_offset,fu,fv,pu,pv,k1,k2,k3,k4,std_fu,std_fv,std_pu,std_pv,std_k1,std_k2,"
      "std_k3,std_k4",
      file);
  for (const char* prefix : {",", ",std_"}) {
    for (const char* m : {"tw", "ta"}) {
      for (const char* e : {"11", "12", "22", "13", "23", "33"})
        std::fprintf(file, "%s%s%s", prefix, m, e);
    }
    for (int e = 0; e < 9; ++e) std::fprintf(file, "%stg%d%d", prefix, e / 3 + 1, e % 3 + 1);
    for (const char* a : {"acc_rx", "acc_ry", "acc_rz"}) std::fprintf(file, "%s%s", prefix, a);
  }
  std::fputc('\n', file);
  for (const CalibrationRow& row : calibration_) {
    writeStamp(file, row.stamp_ns);
    std::fprintf(file, ",%s,%s", names_[row.sensor].c_str(), kinds_[row.sensor].c_str());
    for (int i = 0; i < 7; ++i) writeNumber(file, row.value[i]);
    for (int i = 0; i < 7; ++i) writeNumber(file, row.std[i]);
    for (int i = 7; i < 15; ++i) writeNumber(file, row.value[i]);
    for (int i = 7; i < 15; ++i) writeNumber(file, row.std[i]);
    for (int i = 15; i < kColumns; ++i) writeNumber(file, row.value[i]);
    for (int i = 15; i < kColumns; ++i) writeNumber(file, row.std[i]);
    std::fputc('\n', file);
  }
  if (std::fclose(file) != 0) return Status::Error(calibration_path + ": cannot write");
  return Status::Ok();
}

}  // namespace mvis
