// Residual frames, RSDW (spec/container.md §7.4, format 2.3), as the writer codes them; the reader
// is codec/decoder/container/residual_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include <cmath>
#include <optional>

namespace facemorph::file_layout {

using format::ByteWriter;

std::vector<uint8_t> write_residuals(const SequenceOutline& o) {
  const std::vector<ResidualFrame>& residuals = o.residuals;
  const auto fail = [](size_t r, const std::string& what) {
    throw Error(ErrorCode::kInvalidArgument, "residual frame " + std::to_string(r) + ": " + what);
  };
  if (residuals.empty() || residuals.size() > kMaxResiduals) throw Error(ErrorCode::kInvalidArgument, "residual frames: 1 to 2^24 of them");
  validate_residuals(o.times, residuals);
  // The coarsest step 2^-e that holds every correction exactly.
  int e = 0;
  for (; e <= kMaxResidualStepExponent; ++e) {
    bool exact = true;
    for (const ResidualFrame& f : residuals) {
      for (double d : f.delta) exact = exact && std::ldexp(d, e) == std::nearbyint(std::ldexp(d, e));
    }
    if (exact) break;
  }
  if (e > kMaxResidualStepExponent) throw Error(ErrorCode::kInvalidArgument, "residual frames: corrections are not multiples of 2^-30");
  ByteWriter w;
  w.write(static_cast<uint32_t>(residuals.size()));
  w.write(static_cast<uint8_t>(e));
  int64_t previous = 0;
  for (size_t r = 0; r < residuals.size(); ++r) {
    const ResidualFrame& f = residuals[r];
    if (!write_item_time(w, f.time, o, previous))
      fail(r, "its time is not a 64th of a frame period after the previous one's (residuals_on_file_times)");
    int64_t sum = 0;
    for (size_t m = 0; m + 1 < f.delta.size(); ++m) {
      const auto code = static_cast<int64_t>(std::ldexp(f.delta[m], e));
      sum += code;
      write_varint(w, code);
    }
    if (static_cast<int64_t>(std::ldexp(f.delta.back(), e)) != -sum) fail(r, "its corrections do not sum to 0 exactly");
  }
  return w.take();
}

bool write_item_time(ByteWriter& w, double time, const SequenceOutline& o, int64_t& previous) {
  const std::optional<int64_t> change = item_time_change(time, o, previous);
  if (change) write_varint(w, *change);
  return change.has_value();
}

std::optional<int64_t> item_time_change(double time, const SequenceOutline& o, int64_t& previous) {
  const int64_t q = residual_time_code(time, o.first_time, o.fps);
  if (residual_time(q, o.first_time, o.fps) != time || q <= previous || q >= kMaxTimeCode) return std::nullopt;
  const int64_t change = q - previous;
  previous = q;
  return change;
}

}  // namespace facemorph::file_layout
