// Determinism: the same data and options give bit-identical results whatever the allocation
// history. ceres::Covariance orders its columns by the blocks' addresses, and so did every
// standard deviation (and the holds decided on them); block_covariance.h says how mvis avoids it.
// Measured before: 7 of the 20 numbers below differed (by up to 1.5e-17) between the two runs.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "fault_test_util.h"

namespace mvis {
namespace {

std::vector<double> everything(const Estimator& estimator) {
  std::vector<double> out;
  const Rig rig = estimator.calibration();
  for (const auto& c : rig.cameras) {
    const Eigen::Matrix3d R = c.T_cam_imu.rotation();
    out.insert(out.end(), R.data(), R.data() + 9);
    out.insert(out.end(), c.T_cam_imu.p.data(), c.T_cam_imu.p.data() + 3);
    out.push_back(c.timeshift_cam_imu);
    if (c.std) {
      out.insert(out.end(), c.std->rotation.data(), c.std->rotation.data() + 3);
      out.insert(out.end(), c.std->translation.data(), c.std->translation.data() + 3);
      out.push_back(c.std->timeshift_cam_imu);
    }
  }
  for (const auto& s : rig.inertial) {
    const Eigen::Matrix3d R = s.T_i_b.rotation();
    out.insert(out.end(), R.data(), R.data() + 9);
    out.insert(out.end(), s.T_i_b.p.data(), s.T_i_b.p.data() + 3);
    out.push_back(s.time_offset);
    if (s.std) {
      out.insert(out.end(), s.std->rotation.data(), s.std->rotation.data() + 3);
      out.insert(out.end(), s.std->translation.data(), s.std->translation.data() + 3);
      out.push_back(s.std->time_offset);
    }
  }
  for (const auto& state : estimator.trajectory()) {
    out.insert(out.end(), state.T_G_I.p.data(), state.T_G_I.p.data() + 3);
    out.insert(out.end(), state.v_G.data(), state.v_G.data() + 3);
  }
  return out;
}

// Blocks of many sizes kept alive, others freed, so that what is allocated next lands elsewhere
// and in another order.
std::vector<std::unique_ptr<char[]>> disturbHeap(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<std::unique_ptr<char[]>> keep;
  for (int i = 0; i < 5000; ++i) {
    keep.emplace_back(new char[1 + rng() % 4096]);
    if (rng() % 3 == 0) keep.erase(keep.begin() + rng() % keep.size());
  }
  return keep;
}

// The estimator over the run (with `faults` injected, fault_test_util.h) and its every output.
std::vector<double> runOnce(const test::SimRun& run, const std::string& faults) {
  std::vector<Fault> parsed;
  if (!faults.empty()) parsed = parseFaults(faults).value();
  auto created = Estimator::create(run.guess, test::deterministic());
  EXPECT_TRUE(created.ok());
  if (!created.ok()) return {};
  auto estimator = std::move(created).value();
  test::feedWithFaults(run, parsed, estimator.get(), nullptr);
  EXPECT_TRUE(estimator->initialized());
  EXPECT_TRUE(estimator->computeCovariance().ok());
  return everything(*estimator);
}

TEST(Determinism, SameResultWhateverTheAllocation) {
  const test::SimRun run = test::simulate("sim_small_rig", 8.0, 3);
  const auto first = test::runFrom(run.guess, run, test::deterministic());
  ASSERT_TRUE(first);
  const std::vector<double> a = everything(*first);
  const auto keep = disturbHeap(1);
  const auto second = test::runFrom(run.guess, run, test::deterministic());
  ASSERT_TRUE(second);
  const std::vector<double> b = everything(*second);
  ASSERT_EQ(a.size(), b.size());
  int differing = 0;
  double largest = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(double)) != 0) {
      ++differing;
      largest = std::max(largest, std::abs(a[i] - b[i]));
    }
  }
  std::printf("%d of %zu numbers differ, largest by %.3g\n", differing, a.size(), largest);
  EXPECT_EQ(differing, 0);
}

// A fault made the answer depend on the allocation (a 0.3 s hole in imu0 left the
// cameras 4.9 mm off with relative paths and 0.1 mm with absolute ones). With faults that restart
// the window from the trusted calibration (a drifting camera clock, a hole) and garble messages,
// two runs with the heap disturbed differently in between give the same bytes. (Before the
// marginalization ordered its forgotten directions by entry instead of by block address, this
// case differed in the 12th digit between mvis_offline runs with different paths.)
TEST(Determinism, SameResultWithFaultsWhateverTheAllocation) {
  const test::SimRun run = test::simulate("sim_vi_rig", 20.0, 1);
  const std::string faults =
      "rate:cam1:12:3:0.005,gap:imu0:17:0.3,corrupt:imu0:2:10:0.01,repeat:all:2:10:0.01";
  const std::vector<double> a = runOnce(run, faults);
  const auto keep = disturbHeap(2);
  const std::vector<double> b = runOnce(run, faults);
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(double)), 0);
}

}  // namespace
}  // namespace mvis
