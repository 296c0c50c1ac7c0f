// A group of keyframes, KGOP (spec/container.md §7): one intra period's fields in one range-coded
// stream. Each value is an integer multiple of the header's step for its array; the codes are
// predicted (from the previous keyframe of the group, and along G's lattice) and only the
// residuals coded, under adaptive models carried through the group, so every decoder reproduces the
// encoder's values to the bit.
#include "codec/core/container/file_layout.hpp"

#include "format/byte_writer.hpp"
#include "format/ranged_residuals.hpp"

#include <cmath>
#include <limits>
#include <optional>

namespace facemorph::file_layout {

namespace {

using format::ByteReader;
using format::ByteWriter;

// Which arrays lie on G's lattice (spatial predictors 2 and 3 allowed): the per-node fields and
// positions on the interior nodes, the hole level on every node. The band vectors and the rim are
// sequences only.
const format::LatticeNeighbours* lattice_of(size_t array, size_t length, const GridFacts& grid) {
  const format::LatticeNeighbours* lattice = nullptr;
  if (array <= 3 || (array >= 7 && array <= 9)) lattice = &grid.interior;
  if (array == kScalarArrayCount) lattice = &grid.all_nodes;
  return lattice && lattice->size() == length ? lattice : nullptr;  // an empty array has none
}

// lattice_of for every array of a keyframe, given their lengths.
std::vector<const format::LatticeNeighbours*> lattices_of(const std::vector<size_t>& lengths, const GridFacts& grid) {
  std::vector<const format::LatticeNeighbours*> lattices;
  for (size_t a = 0; a < lengths.size(); ++a) lattices.push_back(lattice_of(a, lengths[a], grid));
  return lattices;
}

template <typename T>
std::vector<size_t> lengths_of(const std::vector<std::vector<T>>& arrays) {
  std::vector<size_t> lengths;
  for (const std::vector<T>& a : arrays) lengths.push_back(a.size());
  return lengths;
}

// The models each array's residuals adapt under (§7.3): its own, except that b continues a's and
// the second and third components of a vector field the first's.
constexpr std::array<uint8_t, kKeyframeArrays> kRangeModelSets = {0, 1, 2, 2, 4, 4, 4, 7, 7, 7, 10, 10, 10, 13};

// The models a group's stream adapts, fresh at its start and carried through its keyframes.
struct GroupModels {
  format::BitModel reference;                                              // 1: from the previous keyframe
  std::array<std::array<format::BitModel, 3>, kKeyframeArrays> predictor;  // the high bit's, then the low bit's under each high bit
  std::vector<format::ResidualModels> residuals;
};

struct CodedArray {
  format::SpatialPredictor predictor = format::SpatialPredictor::kNone;
  std::vector<int64_t> residuals;
  double bits = 0;
};

// The spatial predictor that leaves the fewest bits under the range coder's own cost (fresh models).
CodedArray best_prediction(std::span<const int32_t> codes, const format::LatticeNeighbours* lattice) {
  CodedArray best;
  best.bits = std::numeric_limits<double>::infinity();
  for (uint8_t p = 0; p < format::kSpatialPredictorCount; ++p) {
    const auto predictor = static_cast<format::SpatialPredictor>(p);
    if (format::uses_lattice(predictor) && lattice == nullptr) continue;
    std::vector<int64_t> residuals = format::spatial_residuals(codes, predictor, lattice);
    const double bits = format::ranged_residual_bits(residuals, lattice);
    if (bits < best.bits) best = {predictor, std::move(residuals), bits};
  }
  return best;
}

// Array a's spatial predictor p as read, or kCorrupt where it is none this array can have.
format::SpatialPredictor checked_predictor(size_t a, uint8_t p, size_t length, const GridFacts& grid, const std::string& where) {
  const auto predictor = static_cast<format::SpatialPredictor>(p);
  if (p >= format::kSpatialPredictorCount || (format::uses_lattice(predictor) && lattice_of(a, length, grid) == nullptr)) {
    corrupt(where, "array " + std::to_string(a) + " has predictor " + std::to_string(p) + ", not one for that array");
  }
  return predictor;
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
// bits. The reference that costs less wins.
Prediction choose_prediction(const std::vector<std::vector<int32_t>>& codes, const std::vector<std::vector<int32_t>>* previous, const GridFacts& grid) {
  auto code_all = [&](bool from_previous) {
    std::vector<CodedArray> out;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      std::vector<int32_t> values = codes[a];
      if (from_previous) {
        for (size_t i = 0; i < values.size(); ++i) values[i] -= (*previous)[a][i];  // |codes| < 2^30: no overflow
      }
      out.push_back(best_prediction(values, lattice_of(a, values.size(), grid)));
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

// A decoded keyframe's arrays from its residuals: the spatial predictors undone, then the previous
// keyframe's `codes` added where it is coded from it. `codes` holds this keyframe's on return.
std::vector<std::vector<double>> arrays_from_residuals(const std::vector<std::vector<int64_t>>& residuals, const std::vector<format::SpatialPredictor>& predictors,
                                                       bool from_previous, std::vector<std::vector<int32_t>>& codes, const FileHeader& h,
                                                       const GridFacts& grid, const std::string& where) {
  const std::vector<double>& steps = h.metadata.field_coding.steps;
  std::vector<std::vector<double>> arrays(kKeyframeArrays);
  std::vector<std::vector<int32_t>> these(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    these[a] = format::codes_from_residuals(residuals[a], predictors[a], lattice_of(a, residuals[a].size(), grid), where);
    for (size_t i = 0; i < these[a].size(); ++i) {
      const int64_t code = from_previous ? int64_t{these[a][i]} + codes[a][i] : int64_t{these[a][i]};
      if (code <= -kMaxFieldCode || code >= kMaxFieldCode) corrupt(where, "a field code beyond 2^30");
      these[a][i] = static_cast<int32_t>(code);
    }
    arrays[a].resize(these[a].size());
    for (size_t i = 0; i < these[a].size(); ++i) arrays[a][i] = steps[a] * these[a][i];
  }
  codes = std::move(these);
  return arrays;
}

}  // namespace

std::vector<std::vector<double>> keyframe_arrays(const Keyframe& key) {
  std::vector<std::vector<double>> arrays = scalar_arrays(key.fields);
  arrays.push_back(key.hole_level);
  return arrays;
}

void assign_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, Representation representation, int grid_n,
                            std::vector<int32_t> fixed_nodes) {
  key.hole_level = std::move(arrays[kScalarArrayCount]);
  arrays.resize(kScalarArrayCount);
  key.fields = fields_from_scalar_arrays(representation, grid_n, std::move(fixed_nodes), arrays);
}

int32_t field_code(double value, double step) {
  const double code = std::nearbyint(value / step);
  if (!(std::abs(code) < static_cast<double>(kMaxFieldCode))) {
    throw Error(ErrorCode::kInvalidArgument, "a field value " + std::to_string(value) + " lies more than 2^30 steps of " + std::to_string(step) + " from 0");
  }
  return static_cast<int32_t>(code);
}

void check_field_coding(const FieldCoding& coding) {
  if (coding.steps.size() != kKeyframeArrays) throw Error(ErrorCode::kInvalidArgument, "field coding: one step per keyframe array needed");
  for (double step : coding.steps) {
    if (!(step > 0) || !std::isfinite(step)) throw Error(ErrorCode::kInvalidArgument, "field coding: a step that is not finite and positive");
  }
  if (coding.intra_period < 1 || static_cast<uint32_t>(coding.intra_period) > kMaxIntraPeriod) {
    throw Error(ErrorCode::kInvalidArgument, "field coding: intra period outside [1, 2^20]");
  }
  if (!(coding.rotation_step > 0 && coding.translation_step > 0 && std::isfinite(coding.rotation_step) && std::isfinite(coding.translation_step))) {
    throw Error(ErrorCode::kInvalidArgument, "field coding: pose steps that are not finite and positive (set_default_pose_steps)");
  }
}

struct KeyframeGroupWriter::State {
  const FieldCoding& coding;
  const GridFacts& grid;
  ByteWriter w;
  format::RangedStreamWriter stream;
  GroupModels models;
  std::vector<std::vector<int32_t>> previous;             // the last keyframe's codes
  std::vector<const format::LatticeNeighbours*> lattices;  // the same for every keyframe (checked by the caller)
  size_t added = 0;
};

KeyframeGroupWriter::KeyframeGroupWriter(size_t first, const FieldCoding& coding, const GridFacts& grid)
    : state_(std::make_unique<State>(State{coding, grid, {}, {}, {}, {}, {}, 0})) {
  state_->w.write(static_cast<uint32_t>(first));
}

KeyframeGroupWriter::~KeyframeGroupWriter() = default;

void KeyframeGroupWriter::add(const Keyframe& key) {
  State& s = *state_;
  std::vector<std::vector<int32_t>> codes = field_codes(key, s.coding);
  if (s.added == 0) s.lattices = lattices_of(lengths_of(codes), s.grid);
  Prediction prediction = choose_prediction(codes, s.added > 0 ? &s.previous : nullptr, s.grid);
  if (s.added > 0) s.stream.decision(s.models.reference, prediction.from_previous);
  std::vector<std::vector<int64_t>> residuals;
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (!codes[a].empty()) {
      const auto p = static_cast<unsigned>(prediction.arrays[a].predictor);
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

struct KeyframeGroupReader::State {
  State(std::vector<uint8_t> bytes, std::string place, const FileHeader& header, uint32_t first_keyframe, uint32_t keyframes)
      : payload(std::move(bytes)), where(std::move(place)), h(header), first(first_keyframe), count(keyframes) {}
  std::vector<uint8_t> payload;  // the stream reads it where it lies
  std::string where;
  const FileHeader& h;
  uint32_t first = 0, count = 0, next = 0;
  size_t stream_start = 0;
  std::optional<format::RangedStreamReader> stream;
  std::vector<size_t> expected;
  uint64_t values = 0;
  std::shared_ptr<const GridFacts> grid;
  std::vector<const format::LatticeNeighbours*> lattices;
  GroupModels models;
  std::vector<std::vector<int32_t>> codes;  // the last keyframe's
};

KeyframeGroupReader::KeyframeGroupReader(std::vector<uint8_t> payload, std::string where, const FileHeader& h, uint32_t first, uint32_t count)
    : state_(std::make_unique<State>(std::move(payload), std::move(where), h, first, count)) {
  State& s = *state_;
  ByteReader r(s.payload, s.where);
  if (r.read<uint32_t>("the first keyframe number") != first) corrupt(s.where, "holds another group of keyframes than the index says");
  s.stream_start = s.payload.size() - r.remaining();
  s.stream.emplace(r.bytes(r.remaining(), "the stream"), s.where);
  s.expected = expected_lengths(h);
  for (size_t length : s.expected) s.values += length;
  s.grid = grid_facts(h.shape.grid_n);
  s.lattices = lattices_of(s.expected, *s.grid);
}

KeyframeGroupReader::~KeyframeGroupReader() = default;

uint32_t KeyframeGroupReader::next() const { return state_->next; }

Keyframe KeyframeGroupReader::read(WorkMeter* work, uint64_t& end) {
  State& s = *state_;
  const uint32_t j = s.next;
  if (j >= s.count) throw Error(ErrorCode::kInternal, s.where + ": keyframe " + std::to_string(s.first + j) + " past the group's " + std::to_string(s.count));
  const std::string keyframe_where = s.where + " (keyframe " + std::to_string(s.first + j) + ")";
  if (work != nullptr) work->charge(s.values * WorkMeter::kPerValue, "decoding keyframe " + std::to_string(s.first + j) + "'s " + std::to_string(s.values) + " values");
  // From here on a failure leaves the stream where no later keyframe can be read: the caller drops
  // the reader (a fault of the file fails the whole group).
  const GridFacts& grid = *s.grid;
  format::RangedStreamReader& stream = *s.stream;
  const bool from_previous = j > 0 && stream.decision(s.models.reference);
  std::vector<format::SpatialPredictor> predictors(kKeyframeArrays, format::SpatialPredictor::kNone);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (s.expected[a] == 0) continue;
    const bool high = stream.decision(s.models.predictor[a][0]);
    const bool low = stream.decision(s.models.predictor[a][high ? 2 : 1]);
    predictors[a] = checked_predictor(a, static_cast<uint8_t>(2 * high + low), s.expected[a], grid, keyframe_where);
  }
  const std::vector<std::vector<int64_t>> residuals = stream.residual_arrays(s.expected, s.lattices, kRangeModelSets, s.models.residuals);
  Keyframe key;
  assign_keyframe_arrays(key, arrays_from_residuals(residuals, predictors, from_previous, s.codes, s.h, grid, keyframe_where), s.h.shape.representation,
                         s.h.shape.grid_n, s.h.fixed_nodes);
  try {
    validate_fields(key.fields);
  } catch (const Error& e) {
    corrupt(keyframe_where, e.what());
  }
  // The hole levels are blended and cut along their zero level (hole_cut.cpp): a level that is
  // not finite, or so large that a blend of them overflows, is the file's fault and named here.
  for (size_t v = 0; v < key.hole_level.size(); ++v) {
    if (!(std::abs(key.hole_level[v]) <= kMaxHoleLevel)) {
      corrupt(keyframe_where, "hole level " + std::to_string(key.hole_level[v]) + " at node " + std::to_string(v) + " (at most 16 in magnitude)");
    }
  }
  end = s.stream_start + stream.position();
  ++s.next;
  return key;
}

void KeyframeGroupReader::expect_end() const { state_->stream->expect_end(); }

}  // namespace facemorph::file_layout
