// A group of keyframes, KGOP (spec/container.md §7): one intra period's fields in one range-coded
// stream. Each value is an integer multiple of the header's step for its array; the codes are
// predicted (from the previous keyframe of the group, and along G's lattice) and only the
// residuals coded, under adaptive models carried through the group, so every decoder reproduces the
// encoder's values to the bit.
#include "codec/decoder/container/chunk_readers.hpp"

#include "codec/core/container/keyframe_group_coding.hpp"
#include "format/ranged_residuals.hpp"

#include <cmath>
#include <limits>
#include <optional>
#include <span>

namespace facemorph::file_layout {

namespace {

using format::ByteReader;

// Array a's spatial predictor, read as id p in a file of `minor_version`, or kCorrupt where it is
// none this array can have there (§7.2).
format::SpatialPredictor checked_predictor(size_t a, uint8_t p, size_t length, const GridFacts& grid, uint16_t minor_version,
                                           const std::string& where) {
  const format::LatticeNeighbours* lattice = lattice_of(a, length, grid);
  const std::span<const format::SpatialPredictor> allowed = allowed_predictors(lattice, minor_version);
  if (p < allowed.size()) return allowed[p];
  const bool linear = lattice == nullptr && p == predictor_id(format::SpatialPredictor::kLinear);  // only to say why
  corrupt(where, "array " + std::to_string(a) + " has predictor " + std::to_string(p) + ", not one for that array" +
                     (linear ? " in a 2." + std::to_string(minor_version) + " file (linear along a sequence is 2.5's)" : ""));
}

// A decoded keyframe's arrays from its residuals: the spatial predictors undone, then the previous
// keyframe's `codes` added where it is coded from it. `codes` holds this keyframe's on return.
std::vector<std::vector<double>> arrays_from_residuals(const std::vector<std::vector<int64_t>>& residuals,
                                                       const std::vector<format::SpatialPredictor>& predictors, bool from_previous,
                                                       std::vector<std::vector<int32_t>>& codes, const FileHeader& h, const GridFacts& grid,
                                                       const std::string& where) {
  const std::vector<double>& steps = h.metadata.field_coding.steps;
  std::vector<std::vector<double>> arrays(kKeyframeArrays);
  std::vector<std::vector<int32_t>> these(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    these[a] = predictors[a] == format::SpatialPredictor::kLevels
                   ? format::codes_from_level_residuals(residuals[a], grid.interior_levels, where)
                   : format::codes_from_residuals(residuals[a], predictors[a], lattice_of(a, residuals[a].size(), grid), where);
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

struct KeyframeGroupReader::State {
  State(std::vector<uint8_t> bytes, std::string place, const FileHeader& header, uint32_t first_keyframe, uint32_t keyframes,
        uint16_t minor)
      : payload(std::move(bytes)), where(std::move(place)), h(header), first(first_keyframe), count(keyframes), minor_version(minor) {}
  std::vector<uint8_t> payload;  // the stream reads it where it lies
  std::string where;
  const FileHeader& h;
  uint32_t first = 0, count = 0, next = 0;
  uint16_t minor_version = 0;  // the file's: which predictor ids a sequence may have
  bool levels_chunk = false;   // KGLV (2.6): id 3 on an interior array is followed by the levels decision
  size_t stream_start = 0;
  std::optional<format::RangedStreamReader> stream;
  std::vector<size_t> expected;
  uint64_t values = 0;
  std::shared_ptr<const GridFacts> grid;
  std::vector<const format::LatticeNeighbours*> lattices;
  GroupModels models;
  std::vector<std::vector<int32_t>> codes;  // the last keyframe's
};

KeyframeGroupReader::KeyframeGroupReader(std::vector<uint8_t> payload, std::string where, const FileHeader& h, uint32_t first,
                                         uint32_t count, uint16_t minor_version, bool levels_chunk)
    : state_(std::make_unique<State>(std::move(payload), std::move(where), h, first, count, minor_version)) {
  State& s = *state_;
  s.levels_chunk = levels_chunk;
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
  if (j >= s.count)
    throw Error(ErrorCode::kInternal,
                s.where + ": keyframe " + std::to_string(s.first + j) + " past the group's " + std::to_string(s.count));
  const std::string keyframe_where = s.where + " (keyframe " + std::to_string(s.first + j) + ")";
  if (work != nullptr)
    work->charge(s.values * WorkMeter::kPerValue,
                 "decoding keyframe " + std::to_string(s.first + j) + "'s " + std::to_string(s.values) + " values");
  // From here on a failure leaves the stream where no later keyframe can be read: the caller drops
  // the reader (a fault of the file fails the whole group).
  const GridFacts& grid = *s.grid;
  format::RangedStreamReader& stream = *s.stream;
  const uint64_t decisions_before = stream.decisions();
  const bool from_previous = j > 0 && stream.decision(s.models.reference);
  std::vector<format::SpatialPredictor> predictors(kKeyframeArrays, format::SpatialPredictor::kNone);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (s.expected[a] == 0) continue;
    const bool high = stream.decision(s.models.predictor[a][0]);
    const bool low = stream.decision(s.models.predictor[a][high ? 2 : 1]);
    predictors[a] = checked_predictor(a, static_cast<uint8_t>(2 * high + low), s.expected[a], grid, s.minor_version, keyframe_where);
    if (s.levels_chunk && high && low && levels_allowed(s.lattices[a], grid) && stream.decision(s.models.levels[a]))
      predictors[a] = format::SpatialPredictor::kLevels;
  }
  std::vector<const format::LatticeNeighbours*> contexts;
  for (size_t a = 0; a < kKeyframeArrays; ++a) contexts.push_back(context_lattice(predictors[a], s.lattices[a], grid));
  const std::vector<std::vector<int64_t>> residuals = stream.residual_arrays(s.expected, contexts, kRangeModelSets, s.models.residuals);
  // The values' unit, charged before, covers small residuals; large ones read many more decisions,
  // known only now (spec/container.md §10.3): counted, so the call stops before its next step.
  if (work != nullptr) work->spend(WorkMeter::decision_units(stream.decisions() - decisions_before, s.values));
  Keyframe key;
  assign_keyframe_arrays(key, arrays_from_residuals(residuals, predictors, from_previous, s.codes, s.h, grid, keyframe_where),
                         s.h.shape.representation, s.h.shape.grid_n, s.h.fixed_nodes);
  try {
    validate_fields(key.fields);
  } catch (const Error& e) {
    corrupt(keyframe_where, e.what());
  }
  // The hole levels are blended and cut along their zero level (hole_cut.cpp): a level that is
  // not finite, or so large that a blend of them overflows, is the file's fault and named here.
  for (size_t v = 0; v < key.hole_level.size(); ++v) {
    if (!(std::abs(key.hole_level[v]) <= kMaxHoleLevel)) {
      corrupt(keyframe_where,
              "hole level " + std::to_string(key.hole_level[v]) + " at node " + std::to_string(v) + " (at most 16 in magnitude)");
    }
  }
  end = s.stream_start + stream.position();
  ++s.next;
  return key;
}

void KeyframeGroupReader::expect_end() const { state_->stream->expect_end(); }

}  // namespace facemorph::file_layout
