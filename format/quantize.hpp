// 16-bit fixed-point quantisation of a field over its own range (spec/method.md §5.3).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace facemorph::format {

struct Quantized16 {
  double lo = 0, hi = 0;  // the range: code 0 is lo, code 65535 is hi
  std::vector<uint16_t> codes;
  double step() const { return (hi - lo) / 65535.0; }
};

// Non-finite values are an error (kInvalidArgument): a field must be finite to be stored.
Quantized16 quantize16(std::span<const double> values);
std::vector<double> dequantize16(const Quantized16& q);

}  // namespace facemorph::format
