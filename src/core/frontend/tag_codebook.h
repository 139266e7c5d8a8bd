// The codes of one tag family as bit words, for mvis's own decoder (tag_reading.h).
//
// A tag's "word" is its data: the D x D cells inside its black border, read row by row from the
// top-left cell of the upright tag, one bit per cell, 1 for black. Families whose data lies
// inside a plain black border (tag36h11, tag25h9, tag16h5: D = 6, 5, 4) have such words; the
// others (circle and standard families, with bits outside the border) are left to libapriltag.
//
// The border is one cell wide as libapriltag prints tags, two cells as Kalibr prints its
// AprilGrids (its tag size is then the edge of a 10-cell square for tag36h11): the detected
// square is W = D + 2 * border cells across.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "mvis/common/status.h"

namespace mvis {

struct DecodedWord {
  int id = -1;
  int rotation = 0;  // quarter turns: the upright top-left cell is the observed corner `rotation`
  int hamming = 0;   // bits that differ from the code
};

class TagCodebook {
 public:
  // Fails for an unknown family or one whose layout has no word (see above).
  static StatusOr<TagCodebook> create(const std::string& family);

  int dataWidth() const { return data_width_; }  // D
  int numTags() const { return static_cast<int>(words_.size()); }

  // Cell (row, col) of tag `id` with a border `border` cells wide: row 0 at the top of the
  // upright tag's detected square of D + 2 * border cells; rows and columns -1 and D + 2 * border
  // are the white ring around it. True for black.
  bool black(int id, int border, int row, int col) const;

  // The best code for a D x D data grid read from an image with corner 0 of the quad at the
  // grid's top-left (bit row * D + col, 1 black), trying the four quarter turns; nullopt when
  // no code is within `max_hamming` bits.
  std::optional<DecodedWord> decode(std::uint64_t observed, int max_hamming) const;

  // The grid read with corner `rotation` of the quad taken as the top-left.
  std::uint64_t rotate(std::uint64_t observed, int rotation) const;

 private:
  int data_width_ = 0;
  std::vector<std::uint64_t> words_;  // per id, upright
  // Every code in its four quarter turns, as read with corner 0 of the quad at the top-left:
  // id * 4 + rotation.
  std::unordered_map<std::uint64_t, int> readings_;
};

}  // namespace mvis
