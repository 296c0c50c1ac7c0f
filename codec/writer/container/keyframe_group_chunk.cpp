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
// equal cost. `levels`: the levels predictor's order where a KGLV chunk may use it on this array,
// else null; it is tried last, and its residuals are in its coding order.
struct ArrayChoice {
  CodedArray plain, best;  // best of the KGOP predictors; best with levels too (plain where levels is not allowed or costs more)
};
ArrayChoice best_prediction(std::span<const int32_t> codes, const format::LatticeNeighbours* lattice, uint16_t minor_version,
                            const format::LevelOrder* levels) {
  CodedArray best;
  best.bits = std::numeric_limits<double>::infinity();
  for (const format::SpatialPredictor predictor : allowed_predictors(lattice, minor_version)) {
    std::vector<int64_t> residuals = format::spatial_residuals(codes, predictor, lattice);
    const double bits = format::ranged_residual_bits(residuals, lattice);
    if (bits < best.bits) best = {predictor, std::move(residuals), bits};
  }
  if (levels != nullptr && !codes.empty()) {
    std::vector<int64_t> residuals = format::level_residuals(codes, *levels);
    const double bits = format::ranged_residual_bits(residuals, &levels->context);
    if (bits < best.bits) return {best, {format::SpatialPredictor::kLevels, std::move(residuals), bits}};
  }
  return {best, best};
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
// bits among those a file of `minor_version` has. The reference that costs less wins. Two answers:
// [0] for a KGOP chunk, [1] for a KGLV chunk (the levels predictor allowed too, from 2.6 on).
std::array<Prediction, 2> choose_prediction(const std::vector<std::vector<int32_t>>& codes, const std::vector<std::vector<int32_t>>* previous,
                                            const GridFacts& grid, uint16_t minor_version) {
  auto code_all = [&](bool from_previous) {
    std::array<std::vector<CodedArray>, 2> out;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      std::vector<int32_t> values = codes[a];
      if (from_previous) {
        for (size_t i = 0; i < values.size(); ++i) values[i] -= (*previous)[a][i];  // |codes| < 2^30: no overflow
      }
      const format::LatticeNeighbours* lattice = lattice_of(a, values.size(), grid);
      const bool levels = minor_version >= kLevelsMinorVersion && levels_allowed(lattice, grid);
      ArrayChoice choice = best_prediction(values, lattice, minor_version, levels ? &grid.interior_levels : nullptr);
      out[0].push_back(std::move(choice.plain));
      out[1].push_back(std::move(choice.best));
    }
    return out;
  };
  auto total_bits = [](const std::vector<CodedArray>& arrays) {
    double bits = 0;
    for (const CodedArray& a : arrays) bits += a.bits;
    return bits;
  };
  std::array<std::vector<CodedArray>, 2> intra = code_all(false);
  std::array<Prediction, 2> chosen{Prediction{false, std::move(intra[0])}, Prediction{false, std::move(intra[1])}};
  if (previous) {
    std::array<std::vector<CodedArray>, 2> predicted = code_all(true);
    for (size_t c = 0; c < 2; ++c) {
      if (total_bits(predicted[c]) < total_bits(chosen[c].arrays)) chosen[c] = {true, std::move(predicted[c])};
    }
  }
  return chosen;
}

// One of the two streams a group writer keeps (KGOP's coding, and KGLV's with the levels predictor).
struct GroupStream {
  format::RangedStreamWriter stream;
  GroupModels models;
  bool uses_levels = false;

  void add(const Prediction& prediction, bool levels_chunk, const std::vector<const format::LatticeNeighbours*>& lattices,
           const GridFacts& grid, bool first) {
    if (!first) stream.decision(models.reference, prediction.from_previous);
    std::vector<std::vector<int64_t>> residuals;
    std::vector<const format::LatticeNeighbours*> contexts;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      const CodedArray& coded = prediction.arrays[a];
      if (!coded.residuals.empty()) {
        const unsigned p = predictor_id(coded.predictor);
        stream.decision(models.predictor[a][0], (p >> 1) != 0);
        stream.decision(models.predictor[a][1 + (p >> 1)], (p & 1) != 0);
        if (levels_chunk && p == 3 && levels_allowed(lattices[a], grid))
          stream.decision(models.levels[a], coded.predictor == format::SpatialPredictor::kLevels);
      }
      uses_levels = uses_levels || coded.predictor == format::SpatialPredictor::kLevels;
      residuals.push_back(coded.residuals);
      contexts.push_back(context_lattice(coded.predictor, lattices[a], grid));
    }
    stream.residual_arrays(residuals, contexts, kRangeModelSets, models.residuals);
  }
};

}  // namespace

std::vector<double> keyframe_array_bits(const Keyframe& key, const Keyframe* previous, const FieldCoding& coding, const GridFacts& grid,
                                        uint16_t minor_version) {
  const std::vector<std::vector<int32_t>> codes = field_codes(key, coding);
  std::vector<std::vector<int32_t>> before;
  if (previous) before = field_codes(*previous, coding);
  const Prediction prediction = choose_prediction(codes, previous ? &before : nullptr, grid, minor_version)[1];
  std::vector<double> bits;
  for (const CodedArray& a : prediction.arrays) bits.push_back(a.residuals.empty() ? 0.0 : a.bits);
  return bits;
}

struct KeyframeGroupWriter::State {
  const FieldCoding& coding;
  const GridFacts& grid;
  uint16_t minor_version;
  ByteWriter w;
  // Both codings side by side, so the group's chunk is known only at its end without holding its
  // keyframes: KGOP's (every decoder of 2.x reads it) and, from 2.6 on, KGLV's.
  std::array<GroupStream, 2> streams;
  std::vector<std::vector<int32_t>> previous;              // the last keyframe's codes
  std::vector<const format::LatticeNeighbours*> lattices;  // the same for every keyframe (checked by the caller)
  size_t added = 0;
  std::string_view chunk_type = kKeyframeGroupChunk;
};

KeyframeGroupWriter::KeyframeGroupWriter(size_t first, const FieldCoding& coding, const GridFacts& grid, uint16_t minor_version)
    : state_(std::make_unique<State>(State{coding, grid, minor_version, {}, {}, {}, {}, 0, kKeyframeGroupChunk})) {
  state_->w.write(static_cast<uint32_t>(first));
}

KeyframeGroupWriter::~KeyframeGroupWriter() = default;

void KeyframeGroupWriter::add(const Keyframe& key) {
  State& s = *state_;
  std::vector<std::vector<int32_t>> codes = field_codes(key, s.coding);
  if (s.added == 0) s.lattices = lattices_of(lengths_of(codes), s.grid);
  const std::array<Prediction, 2> prediction = choose_prediction(codes, s.added > 0 ? &s.previous : nullptr, s.grid, s.minor_version);
  s.streams[0].add(prediction[0], false, s.lattices, s.grid, s.added == 0);
  if (s.minor_version >= kLevelsMinorVersion) s.streams[1].add(prediction[1], true, s.lattices, s.grid, s.added == 0);
  s.previous = std::move(codes);
  ++s.added;
}

std::vector<uint8_t> KeyframeGroupWriter::finish() {
  State& s = *state_;
  std::vector<uint8_t> plain = s.streams[0].stream.finish();
  if (s.minor_version >= kLevelsMinorVersion && s.streams[1].uses_levels) {
    // KGLV only where it is smaller: a group that gains nothing stays readable by a 2.5 decoder.
    std::vector<uint8_t> levels = s.streams[1].stream.finish();
    if (levels.size() < plain.size()) {
      s.chunk_type = kLevelsGroupChunk;
      plain = std::move(levels);
    }
  }
  s.w.bytes(plain);
  return s.w.take();
}

std::string_view KeyframeGroupWriter::chunk_type() const { return state_->chunk_type; }

}  // namespace facemorph::file_layout
