// Time stamps as signed 64-bit nanoseconds.
//
// Absolute stamps (about 1.7e18 ns today) never pass through floating point: a double at
// 1.7e9 s resolves only about 0.24 us. Differences of stamps are small and may become seconds.
#pragma once

#include <cmath>
#include <cstdint>

namespace mvis {

using TimeNs = std::int64_t;  // nanoseconds, in the clock named where it is used

constexpr TimeNs kNsPerSecond = 1000000000;

// Seconds of a (small) duration in nanoseconds.
inline double toSeconds(TimeNs duration_ns) { return static_cast<double>(duration_ns) * 1e-9; }

// Nanoseconds of a duration in seconds, rounded to the nearest nanosecond.
inline TimeNs fromSeconds(double duration_s) { return std::llround(duration_s * 1e9); }

// Stamp from the (sec, nsec) pair ROS and most drivers use.
inline TimeNs fromSecNsec(std::int64_t sec, std::int64_t nsec) { return sec * kNsPerSecond + nsec; }

}  // namespace mvis
