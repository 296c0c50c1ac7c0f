#include "format/quantize.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph::format {

Quantized16 quantize16(std::span<const double> values) {
  Quantized16 q;
  if (values.empty()) return q;
  q.lo = q.hi = values[0];
  for (double v : values) {
    if (!std::isfinite(v)) throw Error(ErrorCode::kInvalidArgument, "cannot quantise a non-finite value");
    q.lo = std::min(q.lo, v);
    q.hi = std::max(q.hi, v);
  }
  q.codes.resize(values.size());
  const double scale = q.hi > q.lo ? 65535.0 / (q.hi - q.lo) : 0.0;
  for (size_t i = 0; i < values.size(); ++i) {
    q.codes[i] = static_cast<uint16_t>(std::clamp(std::lround((values[i] - q.lo) * scale), 0L, 65535L));
  }
  return q;
}

std::vector<double> dequantize16(const Quantized16& q) {
  std::vector<double> out(q.codes.size());
  const double step = q.step();
  for (size_t i = 0; i < out.size(); ++i) out[i] = q.lo + q.codes[i] * step;
  return out;
}

}  // namespace facemorph::format
