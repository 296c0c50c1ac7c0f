// Evaluating a registration f = (id + d_k) ∘ ... ∘ (id + d_1) ∘ m, or Φ interpolating it on a
// partition mesh: the smooth map, its Jacobian, and the map of the closed disk (circle onto circle,
// interior clamped inside).
#include "codec/encoder/registration/registration.hpp"

#include "codec/encoder/registration/partition_map.hpp"
#include "format/error.hpp"

#include <cmath>
#include <string>

namespace facemorph {

Vec2 DiskRegistration::smooth(const Vec2& w, Eigen::Matrix2d* jacobian) const {
  if (partition_map) return partition_map->evaluate(w, jacobian);
  return smooth_base(w, jacobian);
}

Vec2 DiskRegistration::smooth_base(const Vec2& w, Eigen::Matrix2d* jacobian) const {
  Vec2 x = moebius(w);
  if (!jacobian) {
    for (const ThinPlateDisplacement& step : steps) x += step(x);
    return x;
  }
  // m'(z) = e^{iθ}(1 - |a|²)/(1 - ā z)² as the real matrix of multiplication by it, then the chain
  // rule through each step: D[(id + d) ∘ g] = (I + ∇d(g)) Dg.
  const Complex den = 1.0 - std::conj(moebius.a) * to_complex(w);
  const Complex c = std::polar(1.0, moebius.theta) * (1.0 - std::norm(moebius.a)) / (den * den);
  Eigen::Matrix2d& J = *jacobian;
  J << c.real(), -c.imag(), c.imag(), c.real();
  Eigen::Matrix2d gradient;
  for (const ThinPlateDisplacement& step : steps) {
    const Vec2 d = step.value_and_gradient(x, gradient);
    J = (Eigen::Matrix2d::Identity() + gradient) * J;
    x += d;
  }
  return x;
}

Eigen::Matrix2d DiskRegistration::jacobian(const Vec2& w) const {
  Eigen::Matrix2d J;
  smooth(w, &J);
  return J;
}

Vec2 DiskRegistration::map(const Vec2& w, int* clamped) const {
  const double r = w.norm();
  if (!(r <= 1 + 1e-9)) {
    throw Error(ErrorCode::kInvalidArgument, "registration: point (" + std::to_string(w.x()) + ", " + std::to_string(w.y()) +
                                                 ") is outside the unit disk or not finite");
  }
  Vec2 y = smooth(w);
  const double s = y.norm();
  // The circle's correspondence is a homeomorphism of the circle (check_bijection); the radial
  // projection keeps it and makes f(circle) exactly the circle, as the rim of the grid G needs.
  if (r >= 1 - 1e-12) return s > 0 ? Vec2(y / s) : y;
  // Between boundary samples the spline may bulge a little past the circle.
  if (s > 1 - 1e-12) {
    if (clamped) ++*clamped;
    y *= (1 - 1e-12) / s;
  }
  return y;
}

}  // namespace facemorph
