// Seeded mutation for the fuzz tests: how many cases (MVIS_FUZZ_CASES overrides the test's
// default, scripts/fuzz runs 100,000), and byte-level mutations of text.
#pragma once

#include <cstdlib>
#include <random>
#include <string>
#include <vector>

namespace mvis::fuzz {

inline int cases(int default_cases) {
  const char* value = std::getenv("MVIS_FUZZ_CASES");
  return value ? std::max(1, std::atoi(value)) : default_cases;
}

// 1-4 mutations of `text`: a byte replaced (printable or not), a span deleted, a line
// duplicated, a number-like token replaced by a hostile one, random bytes inserted, a cut.
inline std::string mutate(std::string text, std::mt19937& rng) {
  static const std::vector<std::string> kHostile = {"nan",
                                                    ".nan",
                                                    "inf",
                                                    "-.inf",
                                                    "1e400",
                                                    "-1e308",
                                                    "0",
                                                    "-0",
                                                    "",
                                                    "[]",
                                                    "{}",
                                                    "'x'",
                                                    "~",
                                                    "[1, 2",
                                                    "{a: b}",
                                                    "- - -",
                                                    "&anchor",
                                                    "*alias",
                                                    "!!binary",
                                                    "0x7fffffff",
                                                    "-2147483649",
                                                    "1e-320",
                                                    "\"\\u0000\"",
                                                    "[nan, nan, nan, nan]",
                                                    "[[1,0,0,0],[0,1,0,0]]"};
  const auto pick = [&](std::size_t n) {
    return n == 0 ? std::size_t{0} : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng);
  };
  const int count = 1 + static_cast<int>(pick(4));
  for (int m = 0; m < count && !text.empty(); ++m) {
    const std::size_t at = pick(text.size());
    switch (pick(6)) {
      case 0:
        text[at] = static_cast<char>(pick(256));
        break;
      case 1:
        text.erase(at, 1 + pick(20));
        break;
      case 2: {
        const std::size_t start =
            text.rfind('\n', at) == std::string::npos ? 0 : text.rfind('\n', at) + 1;
        const std::size_t end = text.find('\n', at);
        text.insert(start, text.substr(start, end == std::string::npos ? std::string::npos
                                                                       : end - start + 1));
        break;
      }
      case 3: {
        // The number (or word) around `at`, replaced.
        std::size_t start = at, end = at;
        const auto word = [](char c) {
          return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '+';
        };
        while (start > 0 && word(text[start - 1])) --start;
        while (end < text.size() && word(text[end])) ++end;
        text.replace(start, end - start, kHostile[pick(kHostile.size())]);
        break;
      }
      case 4: {
        std::string noise(1 + pick(8), ' ');
        for (auto& c : noise) c = static_cast<char>(pick(256));
        text.insert(at, noise);
        break;
      }
      default:
        text.resize(at);
        break;
    }
  }
  return text;
}

}  // namespace mvis::fuzz
