// Residual frames, RSDW (spec/container.md §7.4, format 2.3): corrections of the spline's blend at
// frames between keyframes (residual_weights.hpp). A few bytes a frame: each time as its change in
// 64ths of a frame period, each correction but the last as an integer multiple of 2^-e (the last is
// minus their sum, so they sum to 0 exactly), all zigzag varints; the chunk is zstd-compressed where
// that is smaller.
#include "codec/decoder/container/chunk_readers.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph::file_layout {

using format::ByteReader;

std::vector<ResidualFrame> read_residuals(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                          const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version) {
  ByteReader r(payload, source + ": residual frames");
  // Each residual takes at least two bytes (its time's change and one correction).
  const uint32_t count = read_item_count(r, "the residual count", "residual frames", kMaxResiduals, 2);
  if (uint64_t{count} * kResidualMemoryBytes > max_memory_bytes) {
    over_limit(r.source(), std::to_string(count) + " residual frames need " + std::to_string(uint64_t{count} * kResidualMemoryBytes) +
                               " bytes, more than max_memory_bytes (" + std::to_string(max_memory_bytes) + ")");
  }
  const int e = r.read<uint8_t>("the step exponent");
  if (e > kMaxResidualStepExponent)
    corrupt(r.source(), "step exponent " + std::to_string(e) + " beyond " + std::to_string(kMaxResidualStepExponent));
  const int64_t bound = max_code(e);
  const int keys = static_cast<int>(key_times.size());
  std::vector<ResidualFrame> residuals(count);
  int64_t q = 0;
  for (uint32_t n = 0; n < count; ++n) {
    const ItemName name{"residual frame", n};
    const ItemTime time = read_item_time(r, "a residual time's change", name, shape, key_times, q);
    ResidualFrame& f = residuals[n];
    f.time = time.time;
    const KeyWindow window = residual_window(time.interval, keys);
    f.delta.resize(static_cast<size_t>(window.count));
    int64_t sum = 0;
    for (int m = 0; m + 1 < window.count; ++m) {
      const int64_t code = read_varint(r, "a residual correction");
      if (code < -bound || code > bound) corrupt(r.source(), name.str() + ": a correction beyond ±" + std::to_string(kMaxResidualDelta));
      sum += code;
      f.delta[static_cast<size_t>(m)] = std::ldexp(static_cast<double>(code), -e);
    }
    if (sum < -bound || sum > bound)
      corrupt(r.source(), name.str() + ": its last correction (minus the others' sum) beyond ±" + std::to_string(kMaxResidualDelta));
    f.delta.back() = std::ldexp(static_cast<double>(-sum), -e);
  }
  // Later minor versions may append here; this reader skips them (a bounded number of bytes).
  check_appended_bytes(r.remaining(), minor_version, r.source());
  try {
    validate_residuals(key_times, residuals);  // what the decoder relies on, each already checked above
  } catch (const Error& error) {
    corrupt(r.source(), error.what());
  }
  return residuals;
}

uint32_t read_item_count(ByteReader& r, const char* count_name, const char* items, uint32_t max, size_t min_bytes) {
  const uint32_t count = r.read<uint32_t>(count_name);
  if (count == 0 || count > max || count > r.remaining() / min_bytes) {
    corrupt(r.source(), "states " + std::to_string(count) + " " + items + "; its " + std::to_string(r.remaining()) + " bytes hold 1 to " +
                            std::to_string(std::min<uint64_t>(max, r.remaining() / min_bytes)));
  }
  return count;
}

ItemTime read_item_time(ByteReader& r, const char* change_name, ItemName name, const Sequence& shape,
                        const std::vector<double>& key_times, int64_t& q) {
  return item_time(read_varint(r, change_name), r.source(), name, shape, key_times, q);
}

ItemTime item_time(int64_t change, const std::string& source, ItemName name, const Sequence& shape,
                   const std::vector<double>& key_times, int64_t& q) {
  if (change < 1 || change >= kMaxTimeCode - q)
    corrupt(source, name.str() + ": its time does not come after the previous one's (change " + std::to_string(change) + ")");
  q += change;
  ItemTime t;
  t.time = residual_time(q, shape.first_time, shape.fps);
  t.interval = residual_interval(key_times, t.time);
  if (t.interval < 0) corrupt(source, name.str() + ": its time " + std::to_string(t.time) + " s is not strictly between two keyframes");
  return t;
}

}  // namespace facemorph::file_layout
