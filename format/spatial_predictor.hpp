// Spatial prediction of a keyframe's integer codes (spec/container.md §7.2): each code is predicted
// from codes of the same array decoded before it — its neighbours on G's lattice — and only the
// residual is coded (ranged_residuals.hpp). Smooth fields on a lattice leave residuals of a few
// units, which is what makes a keyframe cost a few bits per node instead of sixteen.
//
// This layer knows integers and neighbour tables only; what the arrays mean, and which lattice they
// lie on, is the container's business (codec/container/keyframe_group_chunk.cpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

// How a code is predicted from codes of the same array decoded before it (spec/container.md §7.2).
// 0–3 are the file's predictor ids on an array on G's lattice, fixed forever. kLinear is written
// as id 2 on an array that is a sequence only (the band, the rim), in a file of format 2.5 or later:
// the id is 2 bits and an array on no lattice has no use for 2 and 3 (the container maps them).
enum class SpatialPredictor : uint8_t {
  kNone = 0,      // 0
  kPrevious = 1,  // the previous code in array order (0 for the first)
  kGradient = 2,  // left + up − up-left on the lattice; with one of left or up only, that one; else as kPrevious
  kMedian = 3,    // LOCO-I's median edge detector over left, up, up-left; fallbacks as kGradient
  kLinear = 4,    // 2 × the previous − the one before it, along the array (for the second: the first; for the first: 0)
  kLevels = 5,    // coarse to fine on the lattice (level_predictor.hpp; format 2.6): id 3 and one more decision, in a KGLV chunk
};
inline constexpr uint8_t kSpatialPredictorCount = 4;  // the lattice's ids 0–3 (kLinear is a sequence's id 2)

// Whether `predictor` reads lattice neighbours (and so needs a LatticeNeighbours table).
constexpr bool uses_lattice(SpatialPredictor predictor) {
  return predictor == SpatialPredictor::kGradient || predictor == SpatialPredictor::kMedian;
}

// For each element of an array on a lattice, the element index of its left (i − 1, j), up
// (i, j − 1) and up-left (i − 1, j − 1) neighbours, or −1 where there is none. Every neighbour
// must come before the element in array order (checked by the coder: kInvalidArgument).
struct LatticeNeighbours {
  std::vector<int32_t> left, up, up_left;
  size_t size() const { return left.size(); }
};

// Residuals of `codes` under `predictor`. `lattice` is needed by kGradient and kMedian (then its
// size must be the array's, else kInvalidArgument), ignored otherwise. Arithmetic in 64 bits.
std::vector<int64_t> spatial_residuals(std::span<const int32_t> codes, SpatialPredictor predictor, const LatticeNeighbours* lattice);

// The inverse. Throws kCorrupt naming `source` when a code leaves int32's range.
std::vector<int32_t> codes_from_residuals(std::span<const int64_t> residuals, SpatialPredictor predictor, const LatticeNeighbours* lattice,
                                          const std::string& source);

}  // namespace facemorph::format
