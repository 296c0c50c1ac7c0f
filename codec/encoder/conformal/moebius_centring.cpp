// Möbius centring of a symmetric spherical map: Newton on the automorphism parameter a.
#include "codec/encoder/conformal/moebius_centring.hpp"

#include "codec/encoder/conformal/moebius.hpp"

#include <cmath>
#include <complex>
#include <numeric>
#include <vector>

namespace facemorph {
namespace {

// Stereographic coordinates of a southern-hemisphere point, and back.
Complex to_plane(const Eigen::RowVector3d& p) { return Complex(p.x(), p.y()) / (1.0 - p.z()); }
Eigen::RowVector3d to_sphere(const Complex& w) {
  const double r2 = std::norm(w);
  return Eigen::RowVector3d(2 * w.real(), 2 * w.imag(), r2 - 1) / (1 + r2);
}

}  // namespace

void centre_by_moebius(Eigen::MatrixXd& p, const Eigen::VectorXd& areas, const DoubleCover& cover) {
  const int n = cover.disk_vertices;
  std::vector<Complex> w(static_cast<size_t>(n));
  std::vector<double> weight(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    w[static_cast<size_t>(i)] = to_plane(p.row(i));
    const int mi = cover.mirror[static_cast<size_t>(i)];
    weight[static_cast<size_t>(i)] = areas[i] + (mi != i ? areas[mi] : 0.0);
  }
  // Centroid (x + iy) of the image after the automorphism with parameter a (copy 2 has the same x, y).
  auto centroid = [&](const Complex& a) {
    Complex sum = 0;
    for (int i = 0; i < n; ++i) {
      const Complex z = (w[static_cast<size_t>(i)] - a) / (1.0 - std::conj(a) * w[static_cast<size_t>(i)]);
      sum += weight[static_cast<size_t>(i)] * 2.0 * z / (1 + std::norm(z));
    }
    return sum;
  };
  const double total = std::accumulate(weight.begin(), weight.end(), 0.0);
  Complex a = 0;
  for (int iteration = 0; iteration < 8; ++iteration) {
    const Complex f = centroid(a);
    if (std::abs(f) < 1e-13 * total) break;
    // Newton on R²: the Jacobian by central differences.
    const double h = 1e-7;
    const Complex dx = (centroid(a + Complex(h, 0)) - centroid(a - Complex(h, 0))) / (2 * h);
    const Complex dy = (centroid(a + Complex(0, h)) - centroid(a - Complex(0, h))) / (2 * h);
    Eigen::Matrix2d J;
    J << dx.real(), dy.real(), dx.imag(), dy.imag();
    const Eigen::Vector2d step = J.fullPivLu().solve(Eigen::Vector2d(f.real(), f.imag()));
    Complex next = a - Complex(step.x(), step.y());
    if (!(std::abs(next) < 0.9)) break;  // a wild step: keep what we have
    a = next;
  }
  if (a == Complex(0)) return;
  for (int i = 0; i < n; ++i) {
    const Complex z = (w[static_cast<size_t>(i)] - a) / (1.0 - std::conj(a) * w[static_cast<size_t>(i)]);
    Eigen::RowVector3d q = to_sphere(z);
    const int mi = cover.mirror[static_cast<size_t>(i)];
    if (mi == i) q.z() = 0;
    p.row(i) = q.normalized();
    if (mi != i) p.row(mi) << q.x(), q.y(), -q.z();
  }
}

}  // namespace facemorph
