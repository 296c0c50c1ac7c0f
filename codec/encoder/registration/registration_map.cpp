// Evaluating a registration f = (id + d_k) ∘ ... ∘ (id + d_1) ∘ m, or Φ interpolating it on a
// partition mesh: the smooth map, its Jacobian, and the map of the closed disk (circle onto circle,
// interior clamped inside).
#include "codec/encoder/registration/registration.hpp"

#include "codec/encoder/registration/partition_map.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace facemorph {

namespace {

// m'(w) = e^{iθ}(1 - |a|²)/(1 - ā w)² as the real matrix of multiplication by it: Dm(w).
Eigen::Matrix2d moebius_jacobian(const DiskMoebius& m, const Vec2& w) {
  const Complex den = 1.0 - std::conj(m.a) * to_complex(w);
  const Complex c = std::polar(1.0, m.theta) * (1.0 - std::norm(m.a)) / (den * den);
  Eigen::Matrix2d J;
  J << c.real(), -c.imag(), c.imag(), c.real();
  return J;
}

void check_in_disk(const Vec2& w) {
  if (!(w.norm() <= 1 + 1e-9)) {
    throw Error(ErrorCode::kInvalidArgument, "registration: point (" + std::to_string(w.x()) + ", " + std::to_string(w.y()) +
                                                 ") is outside the unit disk or not finite");
  }
}

// f(w) from the smooth map's image y (map's contract).
Vec2 onto_closed_disk(const Vec2& w, Vec2 y, int* clamped) {
  const double s = y.norm();
  // The circle's correspondence is a homeomorphism of the circle (check_bijection); the radial
  // projection keeps it and makes f(circle) exactly the circle, as the rim of the grid G needs.
  if (w.norm() >= 1 - 1e-12) return s > 0 ? Vec2(y / s) : y;
  // Between boundary samples the spline may bulge a little past the circle.
  if (s > 1 - 1e-12) {
    if (clamped) ++*clamped;
    y *= (1 - 1e-12) / s;
  }
  return y;
}

}  // namespace

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
  // As smooth_points does it, a block of one: the same bits.
  *jacobian = moebius_jacobian(moebius, w);
  for (const ThinPlateDisplacement& step : steps) step.displace_with_jacobians({&x.x(), 1}, {&x.y(), 1}, {jacobian, 1});
  return x;
}

void DiskRegistration::smooth_points(std::span<const Vec2> w, std::span<Vec2> images, std::span<Eigen::Matrix2d> jacobians) const {
  if (images.size() != w.size() || (!jacobians.empty() && jacobians.size() != w.size())) {
    throw Error(ErrorCode::kInternal, "registration: unequal point, image and Jacobian blocks");
  }
  if (partition_map) {
    for (size_t p = 0; p < w.size(); ++p) images[p] = partition_map->evaluate(w[p], jacobians.empty() ? nullptr : &jacobians[p]);
    return;
  }
  // The GMF's steps a block of points at a time (ThinPlateDisplacement::displace): each point
  // through the same operations as smooth_base's.
  constexpr size_t kBlock = 1024;
  std::vector<double> x, y;
  for (size_t first = 0; first < w.size(); first += kBlock) {
    const size_t n = std::min(kBlock, w.size() - first);
    x.resize(n);
    y.resize(n);
    for (size_t p = 0; p < n; ++p) {
      const Vec2 m = moebius(w[first + p]);
      x[p] = m.x();
      y[p] = m.y();
    }
    if (jacobians.empty()) {
      for (const ThinPlateDisplacement& step : steps) step.displace(x, y);
    } else {
      const std::span<Eigen::Matrix2d> block = jacobians.subspan(first, n);
      for (size_t p = 0; p < n; ++p) block[p] = moebius_jacobian(moebius, w[first + p]);
      for (const ThinPlateDisplacement& step : steps) step.displace_with_jacobians(x, y, block);
    }
    for (size_t p = 0; p < n; ++p) images[first + p] = Vec2(x[p], y[p]);
  }
}

Eigen::Matrix2d DiskRegistration::jacobian(const Vec2& w) const {
  Eigen::Matrix2d J;
  smooth(w, &J);
  return J;
}

Vec2 DiskRegistration::map(const Vec2& w, int* clamped) const {
  check_in_disk(w);
  return onto_closed_disk(w, smooth(w), clamped);
}

void DiskRegistration::map_points(std::span<Vec2> points, int* clamped) const {
  for (const Vec2& w : points) check_in_disk(w);
  std::vector<Vec2> images(points.size());
  smooth_points(points, images, {});
  for (size_t p = 0; p < points.size(); ++p) points[p] = onto_closed_disk(points[p], images[p], clamped);
}

}  // namespace facemorph
