// The levels predictor (spec/container.md §7.2, format 2.6): an array on a square lattice coded
// coarse to fine. The nodes on every 8th row and column first, predicted along their own coarse
// lattice (gradient); then, three times with the spacing s halved (4, 2, 1), the nodes at odd
// multiples of s both ways from the mean of their four diagonal neighbours at ±s, then the nodes
// at an odd multiple of s one way from the mean of their four axis neighbours at ±s, all decoded
// by then. A mean of decoded neighbours carries less of their rounding noise than one neighbour
// or L + U − UL: ICT's positions at 2k vertices cost 15% fewer bits (spec/method.md §7.20.2).
//
// The residuals are coded in that order (the coding order), each under the context of the two
// residuals of its own class at the class's spacing to the left and above (§7.3's rule on a
// table in coding order), so a coarse residual never sets a fine one's models.
#pragma once

#include "format/spatial_predictor.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

inline constexpr int kLevelCount = 3;                      // fine levels below the coarse lattice
inline constexpr int kCoarseSpacing = 1 << kLevelCount;    // the coarse lattice: every 8th row and column

// An array's coding order under the levels predictor, built once per lattice.
struct LevelOrder {
  std::vector<int32_t> element;                  // coding position → array element
  std::vector<std::array<int32_t, 4>> from;      // the elements its prediction reads, −1 where absent
  std::vector<uint8_t> gradient;                 // 1: a coarse node (from = left, up, up-left); 0: a mean
  LatticeNeighbours context;                     // in coding positions: the same class's left and up (§7.3)
  size_t size() const { return element.size(); }
};

// The order for an array whose element e lies at lattice point cells[e] = (i, j), with
// index_at[j * width + i] the element at (i, j) or −1. kInvalidArgument where the two disagree.
LevelOrder level_order(std::span<const std::array<int32_t, 2>> cells, std::span<const int32_t> index_at, int width);

// Residuals of `codes` (array order) in coding order; kInvalidArgument where the sizes differ.
std::vector<int64_t> level_residuals(std::span<const int32_t> codes, const LevelOrder& order);

// The inverse: codes in array order from residuals in coding order. Throws kCorrupt naming
// `source` when a code leaves int32's range.
std::vector<int32_t> codes_from_level_residuals(std::span<const int64_t> residuals, const LevelOrder& order, const std::string& source);

}  // namespace facemorph::format
