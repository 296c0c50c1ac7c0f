// A group of keyframes, KGOP (spec/container.md §7), as the writer codes it: each array under the
// spatial predictor, and from the reference, that leaves the fewest bits. The reader is
// codec/decoder/container/keyframe_group_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include "codec/core/container/keyframe_group_coding.hpp"
#include "format/byte_writer.hpp"
#include "format/ranged_residuals.hpp"

#include <cmath>
#include <limits>

namespace facemorph::file_layout {

using format::ByteWriter;

namespace {

struct CodedArray {
  format::SpatialPredictor predictor = format::SpatialPredictor::kNone;
  std::vector<int64_t> residuals;
  double bits = 0;
};

// The spatial predictor that leaves the fewest bits under the range coder's own cost (fresh models)
// among those the file's `minor_version` allows the array (allowed_predictors, §7.2), the first of
// equal cost.
CodedArray best_prediction(std::span<const int32_t> codes, const format::LatticeNeighbours* lattice, uint16_t minor_version) {
  CodedArray best;
  best.bits = std::numeric_limits<double>::infinity();
  for (const format::SpatialPredictor predictor : allowed_predictors(lattice, minor_version)) {
    std::vector<int64_t> residuals = format::spatial_residuals(codes, predictor, lattice);
    const double bits = format::ranged_residual_bits(residuals, lattice);
    if (bits < best.bits) best = {predictor, std::move(residuals), bits};
  }
  return best;
}

// A keyframe's arrays as integer multiples of the coding's steps.
std::vector<std::vector<int32_t>> field_codes(const Keyframe& key, const FieldCoding& coding) {
  const std::vector<std::vector<double>> arrays = keyframe_arrays(key);
  std::vector<std::vector<int32_t>> codes(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    for (double v : arrays[a]) codes[a].push_back(field_code(v, coding.steps[a]));
  }
  return codes;
}

// How a keyframe's codes are predicted: from nothing or the previous keyframe's, and each array
// under its own spatial predictor, with the residuals that leaves.
struct Prediction {
  bool from_previous = false;
  std::vector<CodedArray> arrays;
};

// `codes`: this keyframe's integer codes, array by array; `previous`: the previous keyframe's, or
// null where this keyframe is the group's first. Intra and predicted alike: each array's codes, or
// their change since the previous keyframe, under the spatial predictor that leaves the fewest
// bits among those a file of `minor_version` has. The reference that costs less wins.
Prediction choose_prediction(const std::vector<std::vector<int32_t>>& codes, const std::vector<std::vector<int32_t>>* previous,
                             const GridFacts& grid, uint16_t minor_version) {
  auto code_all = [&](bool from_previous) {
    std::vector<CodedArray> out;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      std::vector<int32_t> values = codes[a];
      if (from_previous) {
        for (size_t i = 0; i < values.size(); ++i) values[i] -= (*previous)[a][i];  // |codes| < 2^30: no overflow
      }
      out.push_back(best_prediction(values, lattice_of(a, values.size(), grid), minor_version));
    }
    return out;
  };
  auto total_bits = [](const std::vector<CodedArray>& arrays) {
    double bits = 0;
    for (const CodedArray& a : arrays) bits += a.bits;
    return bits;
  };
  Prediction chosen{false, code_all(false)};
  if (previous) {
    std::vector<CodedArray> predicted = code_all(true);
    if (total_bits(predicted) < total_bits(chosen.arrays)) chosen = {true, std::move(predicted)};
  }
  return chosen;
}

}  // namespace

std::vector<double> keyframe_array_bits(const Keyframe& key, const Keyframe* previous, const FieldCoding& coding, const GridFacts& grid,
                                        uint16_t minor_version) {
  const std::vector<std::vector<int32_t>> codes = field_codes(key, coding);
  std::vector<std::vector<int32_t>> before;
  if (previous) before = field_codes(*previous, coding);
  const Prediction prediction = choose_prediction(codes, previous ? &before : nullptr, grid, minor_version);
  std::vector<double> bits;
  for (const CodedArray& a : prediction.arrays) bits.push_back(a.residuals.empty() ? 0.0 : a.bits);
  return bits;
}

struct KeyframeGroupWriter::State {
  const FieldCoding& coding;
  const GridFacts& grid;
  uint16_t minor_version;
  ByteWriter w;
  format::RangedStreamWriter stream;
  GroupModels models;
  std::vector<std::vector<int32_t>> previous;              // the last keyframe's codes
  std::vector<const format::LatticeNeighbours*> lattices;  // the same for every keyframe (checked by the caller)
  size_t added = 0;
};

KeyframeGroupWriter::KeyframeGroupWriter(size_t first, const FieldCoding& coding, const GridFacts& grid, uint16_t minor_version)
    : state_(std::make_unique<State>(State{coding, grid, minor_version, {}, {}, {}, {}, {}, 0})) {
  state_->w.write(static_cast<uint32_t>(first));
}

KeyframeGroupWriter::~KeyframeGroupWriter() = default;

void KeyframeGroupWriter::add(const Keyframe& key) {
  State& s = *state_;
  std::vector<std::vector<int32_t>> codes = field_codes(key, s.coding);
  if (s.added == 0) s.lattices = lattices_of(lengths_of(codes), s.grid);
  Prediction prediction = choose_prediction(codes, s.added > 0 ? &s.previous : nullptr, s.grid, s.minor_version);
  if (s.added > 0) s.stream.decision(s.models.reference, prediction.from_previous);
  std::vector<std::vector<int64_t>> residuals;
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (!codes[a].empty()) {
      const unsigned p = predictor_id(prediction.arrays[a].predictor);
      s.stream.decision(s.models.predictor[a][0], (p >> 1) != 0);
      s.stream.decision(s.models.predictor[a][1 + (p >> 1)], (p & 1) != 0);
    }
    residuals.push_back(std::move(prediction.arrays[a].residuals));
  }
  s.stream.residual_arrays(residuals, s.lattices, kRangeModelSets, s.models.residuals);
  s.previous = std::move(codes);
  ++s.added;
}

std::vector<uint8_t> KeyframeGroupWriter::finish() {
  State& s = *state_;
  s.w.bytes(s.stream.finish());
  return s.w.take();
}

}  // namespace facemorph::file_layout
