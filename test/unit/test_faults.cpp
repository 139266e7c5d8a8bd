// The fault suite: each class of bad data (mvis/sim/faults.h) injected into a simulated VI-Rig
// run (500 Hz base IMU, an auxiliary IMU, a gyroscope, three cameras as tag detections, 35 s)
// and fed to the estimator. Each must end with every calibrated element inside 3 sigma and its
// rotation, translation and time offset errors no larger than twice the clean run's or the clean
// error plus 1.5 sigma (the norm of the per-axis sigmas): a fault that removes a share f of the
// data moves an estimate by about sqrt(f / (1 - f)) of its sigma per axis (0.8 sigma at 40%,
// about what the restarts of the combined case discard), which twice a clean error of 0.2 sigma
// would not allow. And it must say what happened and restart where the data cannot be bridged.
#include <gtest/gtest.h>

#include <cstdlib>
#include <sstream>

#include "fault_test_util.h"

namespace mvis {
namespace {

const test::SimRun& rigRun() {
  static const test::SimRun run = test::simulate("sim_vi_rig", 35.0, 1);
  return run;
}

const test::FaultOutcome& clean() {
  static const test::FaultOutcome outcome = [] {
    auto o = test::runWithFaults(rigRun(), "", test::deterministic());
    test::print("clean", o);
    return o;
  }();
  return outcome;
}

// Every element of every sensor within the bounds above.
void expectAsClean(const test::FaultOutcome& o, const std::string& label) {
  const test::FaultOutcome& c = clean();
  ASSERT_EQ(o.names.size(), c.names.size()) << label;
  for (std::size_t i = 0; i < o.names.size(); ++i) {
    const test::CameraErrors& e = o.errors[i];
    const test::CameraErrors& e0 = c.errors[i];
    const Eigen::Vector3d got(e.rotation_deg, e.translation_mm, e.time_offset_ms);
    const Eigen::Vector3d was(e0.rotation_deg, e0.translation_mm, e0.time_offset_ms);
    for (int k = 0; k < 3; ++k) {
      const double bound = std::max(2.0 * was[k], was[k] + 1.5 * o.sigmas[i][k]);
      EXPECT_LE(got[k], bound) << label << ": " << o.names[i] << " "
                               << (k == 0   ? "rotation"
                                   : k == 1 ? "translation"
                                            : "time offset");
    }
    EXPECT_LT(e.rotation_sigma_ratio.maxCoeff(), 3.0) << label << ": " << o.names[i];
    EXPECT_LT(e.translation_sigma_ratio.maxCoeff(), 3.0) << label << ": " << o.names[i];
    EXPECT_LT(e.time_offset_sigma_ratio, 3.0) << label << ": " << o.names[i];
  }
}

bool said(const test::FaultOutcome& o, const std::string& text) {
  for (const auto& w : o.warnings) {
    if (w.find(text) != std::string::npos) return true;
  }
  return false;
}

TEST(FaultSuite, CleanRunRaisesNoAlarm) {
  const test::FaultOutcome& c = clean();
  ASSERT_TRUE(c.initialized);
  EXPECT_EQ(c.counters.restarts, 0);
  EXPECT_EQ(c.counters.failures, 0);
  EXPECT_EQ(c.counters.frames_rejected, 0);
  EXPECT_EQ(c.counters.stamps_implausible, 0);
  EXPECT_EQ(c.counters.calibration_changes, 0);
  EXPECT_TRUE(c.warnings.empty()) << c.warnings.front();
  EXPECT_LT(c.sigma_ratio, 3.0);
}

struct FaultCase {
  const char* name;
  const char* faults;
  const char* says;  // in some warning
  int restarts;      // at least
};

class FaultSuite : public ::testing::TestWithParam<FaultCase> {};

TEST_P(FaultSuite, EndsAsCleanAndSaysWhatHappened) {
  const FaultCase& f = GetParam();
  const test::FaultOutcome o = test::runWithFaults(rigRun(), f.faults, test::deterministic());
  test::print(f.name, o);
  ASSERT_TRUE(o.initialized) << f.name;
  EXPECT_TRUE(said(o, f.says)) << f.name << ": nothing said '" << f.says << "'";
  EXPECT_GE(o.counters.restarts, f.restarts) << f.name;
  // A fault is not a change of the rig: no sensor is declared moved (a drifting clock is a
  // ramp, not a step; change_detector.h).
  EXPECT_EQ(o.counters.calibration_changes, 0) << f.name;
  for (const auto& c : o.changes) ADD_FAILURE() << f.name << ": " << c.text;
  expectAsClean(o, f.name);
}

// Measured (this seed): see the note of the fault work in doc/results.md.
INSTANTIATE_TEST_SUITE_P(
    Classes, FaultSuite,
    ::testing::Values(
        // Short holes are integrated with inflated noise (imu_max_gap_s 0.03).
        FaultCase{"imu0 hole 25 ms", "gap:imu0:15:0.025", "integrated across the gap", 0},
        FaultCase{"imu0 hole 0.3 s", "gap:imu0:15:0.3", "starts over from the trusted", 1},
        FaultCase{"imu0 hole 2 s", "gap:imu0:15:2", "starts over from the trusted", 1},
        // At 25 s the first 8 s again with their stamps, then the rest: back 25 s, forward 17 s.
        FaultCase{"bag restarted", "restart:all:25:8", "time jumped back by", 2},
        FaultCase{"clock jumps forward", "jump:all:15:0:35", "no reading for 35", 1},
        // A drifting clock is caught by the innovation test (trusted_calibration.h).
        FaultCase{"cam1 clock 0.5% fast for 3 s", "rate:cam1:15:3:0.005", "cam1 time offset moved",
                  1},
        FaultCase{"cam0 clock 0.5% fast for 3 s", "rate:cam0:15:3:0.005", "cam0 time offset moved",
                  1},
        FaultCase{"imu1 clock 0.5% fast for 3 s", "rate:imu1:15:3:0.005", "imu1 time offset moved",
                  1},
        FaultCase{"cam2 restarts with new stamps", "jump:cam2:15:0:-1000", "cam2: stamped", 0},
        FaultCase{"imu1 restarts with new stamps", "jump:imu1:15:0:35", "imu1: stamped", 0},
        FaultCase{"cam0 silent for 5 s", "gap:cam0:15:5", "no camera frame entered", 1},
        FaultCase{"garbled, repeated, swapped",
                  "corrupt:imu0:5:25:0.01,corrupt:cam0:5:25:0.02,corrupt:imu1:5:25:0.01,"
                  "repeat:all:5:25:0.01,swap:all:5:25:0.01",
                  "non-finite reading dropped", 0},
        FaultCase{"all at once",
                  "gap:imu0:12:0.3,gap:imu0:30:2,restart:all:20:6,corrupt:imu0:5:25:0.01,"
                  "corrupt:cam0:5:25:0.02,repeat:all:5:25:0.01,swap:all:5:25:0.01,"
                  "gap:cam2:8:5,rate:cam1:24:3:0.005,jump:imu1:28:0:-1000",
                  "time jumped back by", 3}),
    [](const ::testing::TestParamInfo<FaultCase>& info) {
      std::string name;
      for (const char* p = info.param.name; *p != 0; ++p) {
        if (std::isalnum(static_cast<unsigned char>(*p))) name += *p;
      }
      return name;
    });

TEST(FaultInjection, ParsesAndRefuses) {
  const auto ok = parseFaults("gap:imu0:20:0.3,restart:all:45:10,jump:cam1:30:0:-1000");
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  ASSERT_EQ(ok.value().size(), 3u);
  EXPECT_EQ(toString(ok.value()[2]), "jump:cam1:30:0:-1000");
  for (const auto& [text, says] : std::vector<std::pair<std::string, std::string>>{
           {"hole:imu0:1:1", "unknown kind"},
           {"gap:imu0:1", "needs four fields"},
           {"rate:cam0:1:2", "needs five fields"},
           {"gap:imu0:x:1", "'at' is not a time"},
           {"restart:imu0:10:5", "its stream is 'all'"},
           {"restart:all:5:10", "length <= at"},
           {"corrupt:cam0:0:10:1.5", "share is not within"},
           {"", "no fault given"}}) {
    const auto bad = parseFaults(text);
    ASSERT_FALSE(bad.ok()) << text;
    EXPECT_NE(bad.status().message().find(says), std::string::npos) << bad.status().message();
  }
}

TEST(FaultInjection, AppliesEachClass) {
  // Two streams: a at 0, 1, ..., 9 s; b at 0.5, 1.5, ..., 9.5 s; in time order.
  std::vector<StreamMessage> in;
  for (int i = 0; i < 10; ++i) {
    in.push_back({"a", fromSeconds(i)});
    in.push_back({"b", fromSeconds(i + 0.5)});
  }
  const auto run = [&](const std::string& text) {
    return applyFaults(in, parseFaults(text).value(), 1);
  };
  // A gap removes a's messages at 3, 4 s.
  auto out = run("gap:a:3:2");
  EXPECT_EQ(out.size(), 18u);
  for (const auto& m : out) {
    EXPECT_FALSE(in[m.source].stream == "a" && m.stamp_ns >= fromSeconds(3) &&
                 m.stamp_ns < fromSeconds(5));
  }
  // A restart at 6 s replays 0-2 s (four messages) before the message at 6 s.
  out = run("restart:all:6:2");
  ASSERT_EQ(out.size(), 24u);
  EXPECT_EQ(out[12].stamp_ns, fromSeconds(0));  // after a 0..5.5 (12 messages)
  EXPECT_EQ(out[16].stamp_ns, fromSeconds(6));
  // A jump moves b's stamps from 5 s on; the order stays.
  out = run("jump:b:5:0:-100");
  EXPECT_EQ(out[11].stamp_ns, fromSeconds(5.5 - 100));
  EXPECT_EQ(out[9].stamp_ns, fromSeconds(4.5));
  // A clock 10% fast for 4 s from 2 s: a's stamp at 5 s is 0.3 s late, at 6 s right again.
  out = run("rate:a:2:4:0.1");
  EXPECT_EQ(out[10].stamp_ns, fromSeconds(5.3));
  EXPECT_EQ(out[12].stamp_ns, fromSeconds(6));
  // Shares: every message of a corrupted, repeated; swapped with its successor of the stream.
  out = run("corrupt:a:0:10:1");
  for (const auto& m : out) EXPECT_EQ(m.corrupt, in[m.source].stream == "a");
  EXPECT_EQ(run("repeat:b:0:10:1").size(), 30u);
  out = run("swap:a:0:2:1");
  EXPECT_EQ(out[0].source, 2u);  // a at 1 s first
  EXPECT_EQ(out[2].source, 0u);
}

TEST(FaultInjection, Explore) {
  const char* env = std::getenv("MVIS_FAULT_CASES");
  if (env == nullptr) GTEST_SKIP() << "set MVIS_FAULT_CASES=\"faults;faults;...\" to explore";
  std::stringstream cases(env);
  std::string c;
  while (std::getline(cases, c, ';')) {
    test::print(c, test::runWithFaults(rigRun(), c == "clean" ? "" : c, test::deterministic()));
  }
}

}  // namespace
}  // namespace mvis
