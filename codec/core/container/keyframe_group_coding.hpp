// What the KGOP chunk's writer and reader share (spec/container.md §7.2, §7.3): which arrays lie on
// G's lattice and the models their residuals adapt under. Private to the two
// (codec/writer/container/keyframe_group_chunk.cpp, codec/decoder/container/keyframe_group_chunk.cpp).
#pragma once

#include "codec/core/container/file_layout.hpp"
#include "format/ranged_residuals.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace facemorph::file_layout {

// Which arrays lie on G's lattice (spatial predictors 2 and 3 allowed): the per-node fields and
// positions on the interior nodes, the hole level on every node. The band vectors and the rim are
// sequences only.
inline const format::LatticeNeighbours* lattice_of(size_t array, size_t length, const GridFacts& grid) {
  const format::LatticeNeighbours* lattice = nullptr;
  if (array <= 3 || (array >= 7 && array <= 9)) lattice = &grid.interior;
  if (array == kScalarArrayCount) lattice = &grid.all_nodes;
  return lattice && lattice->size() == length ? lattice : nullptr;  // an empty array has none
}

// Predictor ids in the file (§7.2) are 2 bits. On a sequence (an array on no lattice) ids 2 and 3
// are free, and from format 2.5 on id 2 is format::SpatialPredictor::kLinear; in an older file it is
// corrupt, as 3 always is there.
inline constexpr uint16_t kLinearSequenceMinorVersion = 5;
inline uint8_t predictor_id(format::SpatialPredictor predictor) {
  if (predictor == format::SpatialPredictor::kLevels) return 3;  // then the levels decision (KGLV)
  return predictor == format::SpatialPredictor::kLinear ? uint8_t{2} : static_cast<uint8_t>(predictor);
}

// The one statement of which predictors an array may have in a file of `minor_version` (§7.2),
// indexed by their ids: on a lattice (`lattice` not null) none, previous, gradient, median; on a
// sequence none, previous, and from 2.5 on linear. The writer chooses among these and the reader
// refuses any other id, so the two cannot disagree. The writer tries them in this order and keeps
// the first of equal cost: the order is part of the bytes it writes.
inline std::span<const format::SpatialPredictor> allowed_predictors(const format::LatticeNeighbours* lattice, uint16_t minor_version) {
  using format::SpatialPredictor;
  static constexpr std::array<SpatialPredictor, 4> kOnLattice = {SpatialPredictor::kNone, SpatialPredictor::kPrevious,
                                                                 SpatialPredictor::kGradient, SpatialPredictor::kMedian};
  static constexpr std::array<SpatialPredictor, 3> kOnSequence = {SpatialPredictor::kNone, SpatialPredictor::kPrevious,
                                                                  SpatialPredictor::kLinear};
  if (lattice != nullptr) return kOnLattice;
  return std::span<const SpatialPredictor>(kOnSequence).first(minor_version >= kLinearSequenceMinorVersion ? 3 : 2);
}

// The levels predictor (format 2.6) on the arrays of the interior lattice (not the hole level, whose
// rim nodes lie on no lattice), only in a KGLV chunk: there, id 3 on such an array is followed by one
// decision under GroupModels::levels, 1 for levels, 0 for median.
inline bool levels_allowed(const format::LatticeNeighbours* lattice, const GridFacts& grid) { return lattice == &grid.interior; }

// The table the residuals' contexts read (§7.3): the lattice's, or in the levels predictor's coding order its own.
inline const format::LatticeNeighbours* context_lattice(format::SpatialPredictor predictor, const format::LatticeNeighbours* lattice,
                                                        const GridFacts& grid) {
  return predictor == format::SpatialPredictor::kLevels ? &grid.interior_levels.context : lattice;
}

// lattice_of for every array of a keyframe, given their lengths.
inline std::vector<const format::LatticeNeighbours*> lattices_of(const std::vector<size_t>& lengths, const GridFacts& grid) {
  std::vector<const format::LatticeNeighbours*> lattices;
  for (size_t a = 0; a < lengths.size(); ++a) lattices.push_back(lattice_of(a, lengths[a], grid));
  return lattices;
}

template <typename T>
inline std::vector<size_t> lengths_of(const std::vector<std::vector<T>>& arrays) {
  std::vector<size_t> lengths;
  for (const std::vector<T>& a : arrays) lengths.push_back(a.size());
  return lengths;
}

// The models each array's residuals adapt under (§7.3): its own, except that b continues a's and
// the second and third components of a vector field the first's.
inline constexpr std::array<uint8_t, kKeyframeArrays> kRangeModelSets = {0, 1, 2, 2, 4, 4, 4, 7, 7, 7, 10, 10, 10, 13};

// The models a group's stream adapts, fresh at its start and carried through its keyframes.
struct GroupModels {
  format::BitModel reference;                                              // 1: from the previous keyframe
  std::array<std::array<format::BitModel, 3>, kKeyframeArrays> predictor;  // the high bit's, then the low bit's under each high bit
  std::vector<format::ResidualModels> residuals;
  std::array<format::BitModel, kKeyframeArrays> levels;  // KGLV: after id 3 on an interior array, 1 for levels
};

}  // namespace facemorph::file_layout
