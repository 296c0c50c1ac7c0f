// Measures of a disk map: conformal factor per vertex, angle and quasi-conformal distortion.
#include "codec/core/geometry/differential.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/conformal/untangle.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace facemorph {

Eigen::VectorXd conformal_factor(const DiskMap& map) {
  const auto n = static_cast<Eigen::Index>(map.surface.positions.size());
  Eigen::VectorXd surface_area = Eigen::VectorXd::Zero(n), disk_area = Eigen::VectorXd::Zero(n);
  for (const Face& f : map.surface.faces) {
    const double a3 = triangle_area(map.surface.positions[static_cast<size_t>(f[0])], map.surface.positions[static_cast<size_t>(f[1])],
                                    map.surface.positions[static_cast<size_t>(f[2])]);
    const double a2 = std::abs(
        signed_area(map.disk[static_cast<size_t>(f[0])], map.disk[static_cast<size_t>(f[1])], map.disk[static_cast<size_t>(f[2])]));
    for (int32_t v : f) {
      surface_area[v] += a3;
      disk_area[v] += a2;
    }
  }
  return (surface_area.array() / disk_area.array().max(1e-300)).sqrt();
}

Distortion measure_distortion(const DiskMap& map) {
  const auto& faces = map.surface.faces;
  const auto surface_angles = corner_angles(map.surface.positions, faces);
  Distortion d;
  d.checkerboard_histogram.assign(91, 0.0);
  std::vector<double> errors;
  errors.reserve(3 * faces.size());
  double area_sum = 0, mu_sum = 0, within = 0;
  for (size_t f = 0; f < faces.size(); ++f) {
    const Vec2 w[3] = {map.disk[static_cast<size_t>(faces[f][0])], map.disk[static_cast<size_t>(faces[f][1])],
                       map.disk[static_cast<size_t>(faces[f][2])]};
    const Vec3 s[3] = {map.surface.positions[static_cast<size_t>(faces[f][0])], map.surface.positions[static_cast<size_t>(faces[f][1])],
                       map.surface.positions[static_cast<size_t>(faces[f][2])]};
    d.flipped += signed_area(w[0], w[1], w[2]) <= 0;
    for (int k = 0; k < 3; ++k) {
      const Vec2 e1 = w[(k + 1) % 3] - w[k], e2 = w[(k + 2) % 3] - w[k];
      const double disk_angle = plane_angle(e1, e2);
      errors.push_back(std::abs(disk_angle - surface_angles[f][k]) * 180 / std::numbers::pi);
    }
    // Beltrami coefficient (method-notes §2.7): the surface triangle laid flat in C, then f: z -> w.
    const Vec3 u = s[1] - s[0], v = s[2] - s[0];
    const double area3 = 0.5 * u.cross(v).norm();
    if (area3 <= 0) continue;
    const double ux = u.norm();
    const Complex z1(ux, 0), z2(u.dot(v) / ux, 2 * area3 / ux);
    const Complex e1 = to_complex(w[1] - w[0]), e2 = to_complex(w[2] - w[0]);
    const Complex det = z1 * std::conj(z2) - z2 * std::conj(z1);
    const Complex fz = (e1 * std::conj(z2) - e2 * std::conj(z1)) / det;
    const Complex fzbar = (z1 * e2 - z2 * e1) / det;
    const double mu = std::abs(fzbar / fz);
    mu_sum += mu * area3;
    area_sum += area3;
    d.mu_max = std::max(d.mu_max, mu);
    // Pulled-back checkerboard: the images on the surface of the disk's u and v directions.
    Eigen::Matrix2d W;
    W << (w[1] - w[0]).x(), (w[2] - w[0]).x(), (w[1] - w[0]).y(), (w[2] - w[0]).y();
    if (std::abs(W.determinant()) < 1e-300) continue;
    Eigen::Matrix<double, 3, 2> S;
    S << u, v;
    const Eigen::Matrix<double, 3, 2> J = S * W.inverse();
    const double angle = std::atan2(J.col(0).cross(J.col(1)).norm(), J.col(0).dot(J.col(1))) * 180 / std::numbers::pi;
    const int bin = std::clamp(static_cast<int>(std::lround(angle - 45)), 0, 90);
    d.checkerboard_histogram[static_cast<size_t>(bin)] += area3;
    if (std::abs(angle - 90) <= 1) within += area3;
  }
  if (area_sum > 0) {
    d.mu_mean = mu_sum / area_sum;
    d.checkerboard_within_1_degree = within / area_sum;
    for (double& h : d.checkerboard_histogram) h /= area_sum;
  }
  if (!errors.empty()) {
    double sum = 0;
    for (double e : errors) sum += e;
    d.mean_degrees = sum / static_cast<double>(errors.size());
    std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() * 95 / 100), errors.end());
    d.p95_degrees = errors[errors.size() * 95 / 100];
    d.max_degrees = *std::max_element(errors.begin(), errors.end());
  }
  return d;
}

}  // namespace facemorph
