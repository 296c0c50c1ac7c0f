#include "codec/encoder/conformal/moebius.hpp"

#include <numbers>

namespace facemorph {

DiskMoebius DiskMoebius::after(const DiskMoebius& other) const {
  // Both are e^{iθ}(z - a)/(1 - ā z). Compose as 2x2 matrices [[e^{iθ}, -e^{iθ} a], [-ā, 1]] and read
  // the result back in the same normal form.
  auto matrix = [](const DiskMoebius& m) {
    const Complex r = std::polar(1.0, m.theta);
    return std::array<Complex, 4>{r, -r * m.a, -std::conj(m.a), 1.0};
  };
  const auto p = matrix(*this), q = matrix(other);
  const Complex A = p[0] * q[0] + p[1] * q[2], B = p[0] * q[1] + p[1] * q[3];
  const Complex D = p[2] * q[1] + p[3] * q[3];
  // (A z + B) / (C z + D) = (A/D) (z + B/A) / (1 + (C/D) z): a = -B/A, e^{iθ} = A/D.
  DiskMoebius out;
  out.a = -B / A;
  out.theta = std::arg(A / D);
  return out;
}

DiskMoebius DiskMoebius::normalizing(const Complex& centre, const Complex& direction) {
  DiskMoebius m{centre, 0.0};
  const Complex d = m(direction);
  if (std::abs(d) > 0) m.theta = std::numbers::pi / 2 - std::arg(d);
  return m;
}

}  // namespace facemorph
