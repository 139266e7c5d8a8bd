#include "mvis/sim/faults.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>

namespace mvis {

namespace {

struct KindName {
  FaultKind kind;
  const char* name;
  bool has_value;
};
constexpr KindName kKinds[] = {
    {FaultKind::kGap, "gap", false},        {FaultKind::kRestart, "restart", false},
    {FaultKind::kJump, "jump", true},       {FaultKind::kRate, "rate", true},
    {FaultKind::kCorrupt, "corrupt", true}, {FaultKind::kRepeat, "repeat", true},
    {FaultKind::kSwap, "swap", true},
};

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string part;
  std::istringstream in(s);
  while (std::getline(in, part, sep)) out.push_back(part);
  return out;
}

bool number(const std::string& s, double* out) {
  std::istringstream in(s);
  in >> *out;
  return !s.empty() && in && in.eof() && std::isfinite(*out);
}

// Uniform in [0, 1), the same on every platform.
double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

}  // namespace

StatusOr<std::vector<Fault>> parseFaults(const std::string& text) {
  std::vector<Fault> out;
  for (const std::string& entry : split(text, ',')) {
    if (entry.empty()) continue;
    const std::vector<std::string> f = split(entry, ':');
    const auto error = [&](const std::string& what) {
      return Status::Error("fault '" + entry + "': " + what +
                           " (kind:stream:at:length[:value], e.g. gap:imu0:20:0.3)");
    };
    const KindName* kind = nullptr;
    for (const auto& k : kKinds) {
      if (!f.empty() && f[0] == k.name) kind = &k;
    }
    if (kind == nullptr) {
      return error("unknown kind (gap, restart, jump, rate, corrupt, repeat, swap)");
    }
    if (f.size() != (kind->has_value ? 5u : 4u)) {
      return error(kind->has_value ? "needs five fields" : "needs four fields");
    }
    Fault fault;
    fault.kind = kind->kind;
    fault.stream = f[1];
    if (fault.stream.empty()) return error("no stream");
    if (!number(f[2], &fault.at_s) || fault.at_s < 0.0) return error("'at' is not a time >= 0");
    if (!number(f[3], &fault.length_s) || fault.length_s < 0.0) {
      return error("'length' is not a duration >= 0");
    }
    if (kind->has_value && !number(f[4], &fault.value)) return error("the value is not a number");
    if (fault.kind == FaultKind::kRestart && fault.stream != "all") {
      return error("a restart replays every stream: its stream is 'all'");
    }
    if (fault.kind == FaultKind::kRestart && fault.length_s > fault.at_s) {
      return error("a restart replays at most what came before it (length <= at)");
    }
    const bool share = fault.kind == FaultKind::kCorrupt || fault.kind == FaultKind::kRepeat ||
                       fault.kind == FaultKind::kSwap;
    if (share && !(fault.value >= 0.0 && fault.value <= 1.0)) {
      return error("the share is not within [0, 1]");
    }
    if (fault.kind == FaultKind::kRate && !(std::abs(fault.value) < 1.0)) {
      return error("the rate error is not within (-1, 1)");
    }
    out.push_back(fault);
  }
  if (out.empty()) return Status::Error("no fault given");
  return out;
}

std::string toString(const Fault& fault) {
  std::ostringstream s;
  for (const auto& k : kKinds) {
    if (k.kind != fault.kind) continue;
    s << k.name << ':' << fault.stream << ':' << fault.at_s << ':' << fault.length_s;
    if (k.has_value) s << ':' << fault.value;
  }
  return s.str();
}

std::vector<FaultedMessage> applyFaults(const std::vector<StreamMessage>& messages,
                                        const std::vector<Fault>& faults, std::uint64_t seed) {
  std::vector<FaultedMessage> out;
  out.reserve(messages.size());
  TimeNs t0 = std::numeric_limits<TimeNs>::max();
  for (std::size_t i = 0; i < messages.size(); ++i) {
    out.push_back({i, messages[i].stamp_ns, false});
    t0 = std::min(t0, messages[i].stamp_ns);
  }
  std::mt19937_64 rng(seed);
  // A message's time in the recording (its original stamp) [s from the first].
  const auto when = [&](const FaultedMessage& m) {
    return toSeconds(messages[m.source].stamp_ns - t0);
  };
  for (const Fault& f : faults) {
    const auto mine = [&](const FaultedMessage& m) {
      return f.stream == "all" || messages[m.source].stream == f.stream;
    };
    const auto inside = [&](const FaultedMessage& m) {
      const double t = when(m);
      return mine(m) && t >= f.at_s && t < f.at_s + f.length_s;
    };
    std::vector<FaultedMessage> next;
    next.reserve(out.size());
    switch (f.kind) {
      case FaultKind::kGap:
        for (const auto& m : out) {
          if (!inside(m)) next.push_back(m);
        }
        break;
      case FaultKind::kRestart: {
        bool replayed = false;
        for (const auto& m : out) {
          if (!replayed && when(m) >= f.at_s) {
            for (const auto& early : out) {
              if (when(early) < f.length_s) next.push_back(early);
            }
            replayed = true;
          }
          next.push_back(m);
        }
        break;
      }
      case FaultKind::kJump:
        next = out;
        for (auto& m : next) {
          if (mine(m) && when(m) >= f.at_s) m.stamp_ns += fromSeconds(f.value);
        }
        break;
      case FaultKind::kRate:
        next = out;
        for (auto& m : next) {
          if (inside(m)) m.stamp_ns += fromSeconds(f.value * (when(m) - f.at_s));
        }
        break;
      case FaultKind::kCorrupt:
        next = out;
        for (auto& m : next) {
          if (inside(m) && uniform(rng) < f.value) m.corrupt = true;
        }
        break;
      case FaultKind::kRepeat:
        for (const auto& m : out) {
          next.push_back(m);
          if (inside(m) && uniform(rng) < f.value) next.push_back(m);
        }
        break;
      case FaultKind::kSwap: {
        next = out;
        for (std::size_t i = 0; i < next.size(); ++i) {
          if (!inside(next[i]) || uniform(rng) >= f.value) continue;
          // The next message of the same stream comes first.
          for (std::size_t j = i + 1; j < next.size(); ++j) {
            if (messages[next[j].source].stream != messages[next[i].source].stream) continue;
            std::swap(next[i], next[j]);
            i = j;  // that pair is done
            break;
          }
        }
        break;
      }
    }
    out = std::move(next);
  }
  return out;
}

}  // namespace mvis
