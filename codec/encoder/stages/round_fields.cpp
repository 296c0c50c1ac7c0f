// The field precision stage: the fields rounded as the file will store them, to a target set by
// the spline's predicted error (--field-error auto) or given (field_precision.hpp).
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/encoder/encode/field_precision.hpp"

#include <algorithm>

namespace facemorph {

namespace {

// --field-error auto, the fields' rounding target: two fifths of the spline's mean predicted error,
// where rounding error and more keyframes buy held-out error at about the same price in bytes
// (spec/method.md §5.3). The rounding's node displacement is mostly along the surface and reaches the point-to-surface error at
// about half its size, so it may be larger than a quadrature rule on displacements would allow.
double auto_field_error(const KeyframeSelection& chosen) {
  constexpr double kShare = 0.4, kLowest = 5e-5, kHighest = 2e-3;
  const double mean = mean_predicted_error(chosen);
  return mean == 0 ? 1e-4 : std::clamp(kShare * mean, kLowest, kHighest);
}

}  // namespace

FieldCoding round_fields(const FieldPrecisionOptions& precision, Sequence& sequence, EncodeReport& report) {
  return StoredSequence::around(sequence, SpillMode::kMemory,
                                [&](StoredSequence& stored) { return round_fields(precision, stored, report); });
}

FieldPrecisionOptions field_precision_options(const EncodeOptions& options, const KeyframeSelection& chosen) {
  FieldPrecisionOptions precision = options.field_precision;
  precision.spill = options.spill_keyframes;
  precision.threads = options.threads;
  if (options.auto_field_error) precision.target_error = auto_field_error(chosen);
  return precision;
}

FieldCoding round_fields(const FieldPrecisionOptions& precision, StoredSequence& keys, EncodeReport& report) {
  const auto start = std::chrono::steady_clock::now();
  FieldCoding coding = choose_field_coding(keys, precision, &report.field_precision);
  report.seconds_precision = seconds_since(start);
  return coding;
}

}  // namespace facemorph
