// Residuals of predicted keyframes range-coded (field codings 2-4, spec/container.md §7.4, §7.5): each
// residual becomes a few yes/no decisions — zero?, sign, then "larger than 1, 2, …" and an
// Exp-Golomb escape — coded under adaptive models chosen by the size of the residuals already coded
// beside it. Smooth fields leave runs of small residuals where their neighbours are small, and large
// ones cluster at features; the context turns that into fewer bits than one order-0 table could.
#pragma once

#include "format/range_coder.hpp"
#include "format/spatial_predictor.hpp"

#include <array>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

// Every residual's magnitude must be at most this (2^34): codes are below 2^30 and predictions of
// three of them below 2^32, so every residual of valid codes is.
inline constexpr int64_t kMaxRangedResidual = int64_t{1} << 34;

// One set of adaptive models (spec/container.md §7.4): 6 zero, 9 sign, 6 × 8 larger, 12 escape.
struct ResidualModels {
  std::array<BitModel, 6> zero;
  std::array<BitModel, 9> sign;
  std::array<std::array<BitModel, 8>, 6> larger;
  std::array<BitModel, 12> escape;
};

// Models for a signed integer of any size below 2^kMaxNumberBits (field coding 4's pose): its bit
// length n as six decisions down a binary tree of models (most significant first), then the sign
// and the n - 1 bits below its top as direct bits (spec/container.md §7.5).
inline constexpr int kMaxNumberBits = 42;
struct NumberModels {
  std::array<BitModel, 64> length;  // node 1 is the root, node m's children 2m and 2m + 1
};

// One range-coded stream that holds several things in order: decisions, numbers and arrays of
// residuals (field coding 4: a group of keyframes, each with its reference, predictors, pose and
// fields). Each call codes its part; finish() ends the stream.
class RangedStreamWriter {
 public:
  void decision(BitModel& model, bool bit);
  // kInvalidArgument for |value| ≥ 2^kMaxNumberBits.
  void number(NumberModels& models, int64_t value);
  // As encode_ranged_residuals, onto this stream, with `models` carried.
  void residual_arrays(std::span<const std::vector<int64_t>> arrays, std::span<const LatticeNeighbours* const> lattices,
                       std::span<const uint8_t> model_sets, std::vector<ResidualModels>& models);
  // One residual r (|r| ≤ kMaxRangedResidual, else kInvalidArgument) under `models`, its context
  // from the two values a and b the caller chose (spec/container.md §7.3: there the neighbours').
  void residual(ResidualModels& models, int64_t a, int64_t b, int64_t r);
  std::vector<uint8_t> finish() { return coder_.finish(); }

 private:
  RangeEncoder coder_;
};

// The reader of a RangedStreamWriter's stream: the same calls in the same order. Every error is
// kCorrupt naming `source`.
class RangedStreamReader {
 public:
  RangedStreamReader(std::span<const uint8_t> bytes, std::string source);
  bool decision(BitModel& model);
  int64_t number(NumberModels& models);
  int64_t residual(ResidualModels& models, int64_t a, int64_t b);
  std::vector<std::vector<int64_t>> residual_arrays(std::span<const size_t> lengths, std::span<const LatticeNeighbours* const> lattices,
                                                    std::span<const uint8_t> model_sets, std::vector<ResidualModels>& models);
  // Bytes read so far: what a part of the stream cost, to within the coder's few bytes of lag.
  size_t position() const { return coder_.position(); }
  // Decisions and direct bits read so far (RangeDecoder::decisions): the decoding's work.
  uint64_t decisions() const { return coder_.decisions(); }
  // kCorrupt unless the stream ends exactly here.
  void expect_end() const { coder_.expect_end(); }

 private:
  RangeDecoder coder_;
  std::string source_;
  size_t bytes_ = 0;  // the stream's size, which bounds how many residuals it can hold
  size_t residuals_read_ = 0;
};

// The arrays' residuals in order. `lattices[k]`: array k's lattice neighbours when it lies on G's
// lattice (then its size must be the array's), null when it is a plain sequence. `model_sets[k]`:
// the array whose models array k continues to adapt (k itself, or an earlier array of the same
// kind: the three components of a vector field learn together). `models`: one set per array (only
// the sets model_sets names are used), which the stream starts from and leaves as it ended (field
// coding 3 carries them from one predicted keyframe to the next); null or empty: fresh models.
// kInvalidArgument for a residual beyond kMaxRangedResidual or tables that do not match.
std::vector<uint8_t> encode_ranged_residuals(std::span<const std::vector<int64_t>> arrays,
                                             std::span<const LatticeNeighbours* const> lattices, std::span<const uint8_t> model_sets,
                                             std::vector<ResidualModels>* models = nullptr);

// The inverse (with the same `models` as the encoder had): `lengths[k]` residuals for array k, which must use the whole stream. Throws
// kCorrupt naming `source` when the stream ends early, has bytes left, or decodes a residual out of range.
std::vector<std::vector<int64_t>> decode_ranged_residuals(std::span<const uint8_t> bytes, std::span<const size_t> lengths,
                                                          std::span<const LatticeNeighbours* const> lattices,
                                                          std::span<const uint8_t> model_sets, const std::string& source,
                                                          std::vector<ResidualModels>* models = nullptr);

// The bits the range coder would spend on one array with fresh models (less the stream's end): how
// the encoder chooses predictors and references without coding every candidate.
double ranged_residual_bits(std::span<const int64_t> residuals, const LatticeNeighbours* lattice);

}  // namespace facemorph::format
