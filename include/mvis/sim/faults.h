// Faults injected into a recording: the bad data that real rigs produce (lost readings, clocks
// that jump, drift or restart, bags replayed from the start, corrupt or repeated messages), one
// class at a time or together, to test that the estimator is never left confidently wrong.
//
// A recording is a list of messages in arrival order, each of a named stream (a sensor's name or
// a bag topic) with its stamp; applyFaults says which messages come out, in which order, with
// which stamps, and which are to be corrupted. It knows nothing of what the messages hold, so the
// same faults apply to a simulated run in a test and to any recorded bag (mvis_faults).
//
// Times in a fault (`at`, `length`) are seconds from the recording's first stamp. The classes,
// as written on a command line ("kind:stream:at:length[:value]", stream "all" for every one):
//   gap:S:AT:LEN          S's messages within [AT, AT + LEN) are lost (a sensor silent, a hole)
//   restart:all:AT:LEN    at AT the first LEN s are replayed with their original stamps, then the
//                         rest follows (rosbag play --loop, a logger restart): time jumps back
//                         by AT - LEN s, later forward again
//   jump:S:AT:0:DT        from AT on, S's stamps are DT s later (DT < 0: earlier); on every
//                         stream a forward jump of the whole clock, on one a sensor that
//                         restarts with new stamps
//   rate:S:AT:LEN:EPS     S's clock runs at 1 + EPS of the real rate for LEN s, then is set right
//                         (its stamps drift by up to EPS * LEN s, then jump back)
//   corrupt:S:AT:LEN:P    a share P of S's messages within the span is marked corrupt (the caller
//                         makes them non-finite or garbled)
//   repeat:S:AT:LEN:P     a share P of S's messages within the span is delivered twice
//   swap:S:AT:LEN:P       a share P of S's messages within the span swaps places with the next
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mvis/common/status.h"
#include "mvis/common/time.h"

namespace mvis {

enum class FaultKind { kGap, kRestart, kJump, kRate, kCorrupt, kRepeat, kSwap };

struct Fault {
  FaultKind kind = FaultKind::kGap;
  std::string stream = "all";  // a stream's name, or "all"
  double at_s = 0.0;           // from the recording's first stamp [s]
  double length_s = 0.0;       // [s]
  double value = 0.0;          // jump: DT [s]; rate: EPS; corrupt, repeat, swap: share P
};

// "gap:imu0:20:0.3,restart:all:45:10" (see above); errors name the entry and what is wrong.
StatusOr<std::vector<Fault>> parseFaults(const std::string& text);
std::string toString(const Fault& fault);

struct StreamMessage {
  std::string stream;
  TimeNs stamp_ns = 0;
};

struct FaultedMessage {
  std::size_t source = 0;  // index into the input
  TimeNs stamp_ns = 0;     // its new stamp
  bool corrupt = false;
};

// The input (in arrival order) with the faults applied, in the new arrival order. `seed` picks
// the messages that a share P selects. Faults apply in the order given.
std::vector<FaultedMessage> applyFaults(const std::vector<StreamMessage>& messages,
                                        const std::vector<Fault>& faults, std::uint64_t seed);

}  // namespace mvis
