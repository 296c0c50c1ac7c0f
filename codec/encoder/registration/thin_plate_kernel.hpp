// The thin-plate kernel G(r) = r² log r = ½ r² log r², with a logarithm of its own: the encode
// evaluates it about a billion times (every frame sampled at G's nodes through its registration,
// once per candidate N), and glibc's std::log, one call a value, was 8.5% of an ICT encode's CPU.
// This one is plain arithmetic the compiler vectorises, and the same operations in the same order
// on every CPU: no FMA, no tables, no library call. (glibc picks a variant of its own by CPU, FMA
// or not, so its last bits may differ between machines; this kernel's cannot.)
#pragma once

#include <bit>
#include <cstdint>

namespace facemorph {

// log x for a finite normal x > 0 (the kernel's r² >= 1e-300), within 1 unit in the last place
// (registration_test.cpp, ThinPlate.TheKernelsLogarithmIsWithinOneUnitInTheLastPlace). Elsewhere
// it returns a finite value without meaning: callers either mask it away (r² < 1e-300) or
// multiply it by the non-finite x.
//
// x = 2^k m with m in [√½, √2), f = m - 1 exact; log(1+f) = 2 atanh s with s = f / (2 + f), |s| <=
// 0.1716, so s² <= 0.0295 and ten terms of 2 atanh's series leave under 2^-55 of relative error.
// fdlibm's arrangement, f - (½f² - s(½f² + R)), keeps f's own bits out of the rounded series; ln 2 is
// split so that k ln 2's high part is exact (32 bits, |k| < 2^20).
inline double thin_plate_log(double x) {
  constexpr uint64_t kMantissa = 0x000FFFFFFFFFFFFFull;
  constexpr uint64_t kOne = 0x3FF0000000000000ull;      // 1.0's exponent field
  constexpr uint64_t kTwoTo52 = 0x4330000000000000ull;  // 2^52's: its mantissa holds an integer exactly
  constexpr double kSqrt2 = 1.4142135623730951;         // √2 rounded: the split point needs no more
  constexpr double kLn2High = 0x1.62e42fefp-1;          // ln 2's first 32 bits
  constexpr double kLn2Low = 0x1.473de6af278edp-34;     // ln 2 - kLn2High
  // Integer additions and shifts alone up to m and k: a floating-point comparison may trap
  // (-ftrapping-math, the default), so the compiler would not vectorise a loop that selects by one,
  // and x86 before SSE 4.2 has no 64-bit integer comparison in vectors.
  const uint64_t bits = std::bit_cast<uint64_t>(x);
  const uint64_t mantissa = bits & kMantissa;
  // m0 = 1.mantissa > √2: the mantissa's carry into bit 52 when it passes √2's.
  const uint64_t high = (mantissa + (kMantissa - (std::bit_cast<uint64_t>(kSqrt2) & kMantissa))) >> 52;
  // m = m0 / 2^high by its exponent field; k = the unbiased exponent + high, read as a double by the
  // 2^52 trick (x86 converts int64 to double in vectors only with AVX-512).
  const double m = std::bit_cast<double>((mantissa | kOne) - (high << 52));
  const double k = std::bit_cast<double>(((bits >> 52) + high) | kTwoTo52) - (0x1p52 + 1023.0);
  const double f = m - 1.0;  // exact (Sterbenz: m in [½, 2])
  const double s = f / (2.0 + f);
  const double z = s * s;
  // R = 2 (z/3 + z²/5 + ... + z⁹/19), Horner from the smallest term.
  double r = 2.0 / 19;
  r = r * z + 2.0 / 17;
  r = r * z + 2.0 / 15;
  r = r * z + 2.0 / 13;
  r = r * z + 2.0 / 11;
  r = r * z + 2.0 / 9;
  r = r * z + 2.0 / 7;
  r = r * z + 2.0 / 5;
  r = r * z + 2.0 / 3;
  r = r * z;
  const double half_f2 = 0.5 * f * f;
  return k * kLn2High - ((half_f2 - (s * (half_f2 + r) + k * kLn2Low)) - f);
}

// `value`, or 0 where r² < 1e-300: at the centre G and its gradient vanish, where their formulas give
// 0·(-inf). Masked by integer arithmetic, for the reasons above: r² >= 0 orders as its bits, so
// r² < 1e-300 borrows into the sign bit of their difference.
inline double zero_at_centre(double value, double r2) {
  const uint64_t below = (std::bit_cast<uint64_t>(r2) - std::bit_cast<uint64_t>(1e-300)) >> 63;
  return std::bit_cast<double>(std::bit_cast<uint64_t>(value) & (below - 1));  // below: 0; else all bits kept
}

// G(r) from r², computed either way and masked, so that loops over it vectorise.
inline double thin_plate_kernel(double r2) { return zero_at_centre(0.5 * r2 * thin_plate_log(r2), r2); }

}  // namespace facemorph
