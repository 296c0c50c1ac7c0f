// Automorphisms of the unit disk: f(z) = e^{iθ} (z - a) / (1 - ā z), |a| < 1 (method-notes §4).
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <complex>

namespace facemorph {

using Complex = std::complex<double>;

inline Complex to_complex(const Vec2& p) { return {p.x(), p.y()}; }
inline Vec2 to_vec2(const Complex& z) { return {z.real(), z.imag()}; }

struct DiskMoebius {
  Complex a = 0;     // the point sent to the origin
  double theta = 0;  // rotation applied after

  Complex operator()(const Complex& z) const { return std::polar(1.0, theta) * (z - a) / (1.0 - std::conj(a) * z); }
  Vec2 operator()(const Vec2& p) const { return to_vec2((*this)(to_complex(p))); }

  // |f'(z)| = (1 - |a|²) / |1 - ā z|²: how f scales lengths at z.
  double stretch(const Complex& z) const { return (1.0 - std::norm(a)) / std::norm(1.0 - std::conj(a) * z); }

  DiskMoebius inverse() const {
    // f⁻¹(w) = (e^{-iθ} w + a) / (1 + ā e^{-iθ} w) = e^{i0}(w' + a)/(1 + ā w') with w' = e^{-iθ} w,
    // i.e. rotation by e^{-iθ}, then the map with parameter -a.
    const Complex b = -std::polar(1.0, theta) * a;  // f⁻¹(w) = e^{-iθ}(w - b)/(1 - b̄ w)
    return {b, -theta};
  }

  // The composition this ∘ other.
  DiskMoebius after(const DiskMoebius& other) const;

  // The automorphism sending `centre` to 0 and then `direction` onto the positive imaginary axis.
  static DiskMoebius normalizing(const Complex& centre, const Complex& direction);
};

}  // namespace facemorph
