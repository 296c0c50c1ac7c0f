// The field precision stage: the fields rounded as the file will store them, to a target set by
// the spline's predicted error (--field-error auto: stage_settings.cpp) or given (field_precision.hpp).
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/stages/choose_grid.hpp"

#include <algorithm>
#include <optional>

namespace facemorph {

FieldCoding round_fields(const FieldPrecisionOptions& precision, Sequence& sequence, EncodeReport& report) {
  return StoredSequence::around(sequence, SpillMode::kMemory,
                                [&](StoredSequence& stored) { return round_fields(precision, stored, report); });
}

namespace {

// The worst region's bound on the rounding (spec/method.md §5.3): the grid's floor at the keyframes'
// N, the larger of the resampled and the decoded 99th percentile as --grid auto read them, on the
// reference frame (every keyframe's budget at most 1% less it; a keyframe whose own resampled floor
// is larger, precision.keyframe_floors from the encoder, gets less), and the 1% target, raised as the
// grid's share of it was for a noisy capture. With --grid N given nothing was measured, and only the
// RMS target binds.
FieldPrecisionOptions with_worst_region(FieldPrecisionOptions precision, const EncodeReport& report, int grid_n) {
  std::optional<double> floor;
  for (const auto& [n, p99] : report.grid_floor_p99s) {
    if (n == grid_n) floor = p99;
  }
  for (const EncodeReport::DecodedFloor& d : report.grid_decoded_floors) {
    if (d.n == grid_n && floor) floor = std::max(*floor, d.p99);
  }
  if (!floor) return precision;
  precision.worst_floor = floor;
  precision.worst_target = kWorstRegionTarget * std::max(1.0, report.grid_worst_target / kGridWorstTarget);
  return precision;
}

}  // namespace

FieldCoding round_fields(const FieldPrecisionOptions& precision, StoredSequence& keys, EncodeReport& report) {
  const auto start = std::chrono::steady_clock::now();
  FieldCoding coding = choose_field_coding(keys, with_worst_region(precision, report, keys.shape().grid_n), &report.field_precision);
  report.seconds_precision = seconds_since(start);
  return coding;
}

}  // namespace facemorph
