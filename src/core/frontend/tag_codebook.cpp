#include "tag_codebook.h"

#include "mvis/frontend/tag_detector.h"

namespace mvis {

StatusOr<TagCodebook> TagCodebook::create(const std::string& family) {
  auto probe = tagFamilyPatterns(family, 0);
  if (!probe.ok()) return probe.status();
  const int total = probe.value().total_width;
  const int w = probe.value().width_at_border;
  if ((w - 2) * (w - 2) > 64 || total != w + 2) {
    return Status::Error("tag family " + family + " keeps data bits outside its border");
  }
  auto patterns = tagFamilyPatterns(family, -1);
  if (!patterns.ok()) return patterns.status();
  TagCodebook book;
  book.data_width_ = w - 2;
  for (const auto& cells : patterns.value().cells) {
    std::uint64_t word = 0;
    bool classic = true;
    for (int r = 0; r < total; ++r) {
      for (int c = 0; c < total; ++c) {
        const bool is_black = cells[r * total + c] < 128;
        const bool ring = r == 0 || c == 0 || r == total - 1 || c == total - 1;
        const bool border = !ring && (r == 1 || c == 1 || r == total - 2 || c == total - 2);
        if ((ring && is_black) || (border && !is_black)) classic = false;
        if (!ring && !border && is_black) {
          word |= std::uint64_t{1} << ((r - 2) * (w - 2) + (c - 2));
        }
      }
    }
    if (!classic) {
      return Status::Error("tag family " + family + " has no plain black border");
    }
    book.words_.push_back(word);
  }
  // The reading of code w with its top-left at quad corner r is the word that rotate(., r)
  // turns into w: rotate(., 4 - r) of w.
  for (std::size_t id = 0; id < book.words_.size(); ++id) {
    for (int rotation = 0; rotation < 4; ++rotation) {
      book.readings_.emplace(book.rotate(book.words_[id], (4 - rotation) & 3),
                             static_cast<int>(id) * 4 + rotation);
    }
  }
  return book;
}

bool TagCodebook::black(int id, int border, int row, int col) const {
  const int w = data_width_ + 2 * border;
  if (row < 0 || col < 0 || row >= w || col >= w) return false;  // the white ring
  if (row < border || col < border || row >= w - border || col >= w - border) return true;
  return (words_[id] >> ((row - border) * data_width_ + (col - border))) & 1u;
}

std::uint64_t TagCodebook::rotate(std::uint64_t observed, int rotation) const {
  // Upright cell (r, c) with the top-left at quad corner s + 1 lies at grid cell
  // (c, W - 1 - r) of the reading with the top-left at corner s; applied `rotation` times.
  std::uint64_t word = observed;
  for (int s = 0; s < (rotation & 3); ++s) {
    std::uint64_t next = 0;
    const int d = data_width_;
    for (int r = 0; r < d; ++r) {
      for (int c = 0; c < d; ++c) {
        if ((word >> (c * d + (d - 1 - r))) & 1u) {
          next |= std::uint64_t{1} << (r * d + c);
        }
      }
    }
    word = next;
  }
  return word;
}

std::optional<DecodedWord> TagCodebook::decode(std::uint64_t observed, int max_hamming) const {
  // The reading itself, then every reading one bit away, then two (the families' codes are at
  // least 5 bits apart, so the first hit is the only one within 2 bits).
  const auto found = [&](std::uint64_t word, int distance) -> std::optional<DecodedWord> {
    const auto it = readings_.find(word);
    if (it == readings_.end()) return std::nullopt;
    return DecodedWord{it->second / 4, it->second % 4, distance};
  };
  if (auto hit = found(observed, 0)) return hit;
  const int bits = data_width_ * data_width_;
  if (max_hamming >= 1) {
    for (int i = 0; i < bits; ++i) {
      if (auto hit = found(observed ^ (std::uint64_t{1} << i), 1)) return hit;
    }
  }
  if (max_hamming >= 2) {
    for (int i = 0; i < bits; ++i) {
      for (int j = i + 1; j < bits; ++j) {
        if (auto hit = found(observed ^ (std::uint64_t{1} << i) ^ (std::uint64_t{1} << j), 2)) {
          return hit;
        }
      }
    }
  }
  return std::nullopt;
}

}  // namespace mvis
