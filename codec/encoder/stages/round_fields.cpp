// The field precision stage: the fields rounded as the file will store them, to a target set by
// the spline's predicted error (--field-error auto: stage_settings.cpp) or given (field_precision.hpp).
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/encoder/encode/field_precision.hpp"

namespace facemorph {

FieldCoding round_fields(const FieldPrecisionOptions& precision, Sequence& sequence, EncodeReport& report) {
  return StoredSequence::around(sequence, SpillMode::kMemory,
                                [&](StoredSequence& stored) { return round_fields(precision, stored, report); });
}

FieldCoding round_fields(const FieldPrecisionOptions& precision, StoredSequence& keys, EncodeReport& report) {
  const auto start = std::chrono::steady_clock::now();
  FieldCoding coding = choose_field_coding(keys, precision, &report.field_precision);
  report.seconds_precision = seconds_since(start);
  return coding;
}

}  // namespace facemorph
