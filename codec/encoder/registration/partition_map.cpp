// The partition mesh and Φ, the piecewise-affine map taking each partition triangle V to the triangle
// of its images f̄(V) (paper §5, method-notes §6 "Barycentric coordinates").
#include "codec/encoder/registration/partition_map.hpp"
#include "codec/core/geometry/elementary.hpp"

#include "codec/encoder/registration/registration_internal.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>

namespace facemorph {
namespace {

// The radial map of the gap between the chord (va, vb) and the circle onto the gap between the chord
// (wa, wb) and the circle: w's ray crosses the chord at c = va + u (vb - va); w sits a fraction t of
// the way from c out to the circle; its image is the point a fraction t of the way from
// c' = wa + u (wb - wa) out to the circle along the ray through c'. Continuous with the affine map of
// the chord's triangle (both are linear in u on the chord) and the circle onto the circle.
Vec2 gap_map(const Vec2& va, const Vec2& vb, const Vec2& wa, const Vec2& wb, const Vec2& w, Eigen::Matrix2d* jacobian) {
  const double A = cross2(va, w), B = cross2(w, vb), den = A + B;
  const double u = den > 0 ? std::clamp(A / den, 0.0, 1.0) : 0.5;
  const Vec2 d = vb - va, c = va + u * d;
  const double rho = c.norm(), r = w.norm();
  const bool at_circle = !(1 - rho > 1e-15);  // w's ray meets the chord at a vertex on the circle
  const double t = at_circle ? 0 : (r - rho) / (1 - rho);
  const Vec2 e = wb - wa, c2 = wa + u * e;
  const double rho2 = c2.norm();
  const Vec2 n2 = c2 / rho2;
  const double R = rho2 + t * (1 - rho2);
  if (jacobian) {
    // Chain rule through u(w), t(w) and c'(u): see the definitions above.
    const Vec2 grad_a(-va.y(), va.x()), grad_b(vb.y(), -vb.x());
    const Vec2 grad_u = den > 0 ? Vec2((B * grad_a - A * grad_b) / (den * den)) : Vec2::Zero();
    const Vec2 grad_rho = (c.dot(d) / rho) * grad_u;
    const Vec2 grad_t = at_circle ? Vec2::Zero() : Vec2((w / r - grad_rho + t * grad_rho) / (1 - rho));
    const Vec2 grad_rho2 = (c2.dot(e) / rho2) * grad_u;
    const Vec2 grad_R = (1 - t) * grad_rho2 + (1 - rho2) * grad_t;
    const Vec2 dn2 = (e - n2 * n2.dot(e)) / rho2;  // dn'/du
    *jacobian = n2 * grad_R.transpose() + R * dn2 * grad_u.transpose();
  }
  return R * n2;
}

std::string point_text(const Vec2& p) {
  std::ostringstream out;
  out << "(" << p.x() << ", " << p.y() << ")";
  return out.str();
}

}  // namespace

// ---- The partition mesh ----

namespace {

[[noreturn]] void bad_partition(const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "partition mesh: " + what); }

// The faces, once their indices are known to be in range: the locator is built from them next.
std::vector<Face> indexed(std::vector<Face> faces, const std::vector<Vec2>& vertices) {
  const size_t n = vertices.size();
  if (n < 3 || faces.empty()) bad_partition("needs at least 3 vertices and a face");
  for (size_t i = 0; i < n; ++i) {
    if (!vertices[i].allFinite() || vertices[i].norm() > 1 + 1e-9)
      bad_partition("vertex " + std::to_string(i) + " is outside the unit disk or not finite");
  }
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int v : faces[f]) {
      if (v < 0 || static_cast<size_t>(v) >= n) bad_partition("face " + std::to_string(f) + " has a vertex index out of range");
    }
  }
  return faces;
}

}  // namespace

PartitionMesh::PartitionMesh(std::vector<Vec2> vertices, std::vector<Face> faces)
    : vertices_(std::move(vertices)), faces_(indexed(std::move(faces), vertices_)), locator_(vertices_, faces_) {
  auto bad = bad_partition;
  const size_t n = vertices_.size();
  for (size_t f = 0; f < faces_.size(); ++f) {
    const Face& face = faces_[f];
    if (!(orient2d(vertices_[static_cast<size_t>(face[0])], vertices_[static_cast<size_t>(face[1])],
                   vertices_[static_cast<size_t>(face[2])]) > 0)) {
      bad("face " + std::to_string(f) + " is not counter-clockwise with a positive area");
    }
  }
  const MeshTopology topology(faces_, static_cast<int>(n));
  if (!topology.is_manifold() || topology.boundary_loops().size() != 1 || topology.euler_characteristic() != 1 ||
      topology.referenced_vertex_count() != static_cast<int>(n)) {
    bad("the faces do not triangulate one disk over every vertex");
  }
  // The boundary, from the vertex of smallest angle on: its angles must increase round the origin by
  // gaps under π, so that every ray from the origin leaves the polygon through exactly one chord.
  const std::vector<int>& loop = topology.boundary_loops().front();
  const size_t m = loop.size();
  size_t first = 0;
  for (size_t k = 1; k < m; ++k) {
    if (circle_angle(vertices_[static_cast<size_t>(loop[k])]) < circle_angle(vertices_[static_cast<size_t>(loop[first])])) first = k;
  }
  for (size_t k = 0; k < m; ++k) {
    boundary_.push_back(loop[(first + k) % m]);
    boundary_angle_.push_back(circle_angle(vertices_[static_cast<size_t>(boundary_.back())]));
  }
  for (size_t k = 0; k < m; ++k) {
    const double gap = k + 1 < m ? boundary_angle_[k + 1] - boundary_angle_[k] : boundary_angle_[0] + kTwoPi - boundary_angle_[k];
    if (!(gap > 0 && gap < std::numbers::pi))
      bad("the boundary does not go round the origin (at vertex " + std::to_string(boundary_[k]) + ")");
  }
}

int PartitionMesh::chord(const Vec2& w) const {
  const double theta = circle_angle(w);
  const auto it = std::upper_bound(boundary_angle_.begin(), boundary_angle_.end(), theta);
  return it == boundary_angle_.begin() ? static_cast<int>(boundary_.size()) - 1 : static_cast<int>(it - boundary_angle_.begin()) - 1;
}

// ---- Φ ----

Vec2 PiecewiseAffineMap::evaluate(const Vec2& w, Eigen::Matrix2d* jacobian) const {
  if (!w.allFinite()) {
    if (jacobian) jacobian->setConstant(std::numeric_limits<double>::quiet_NaN());
    return Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  const PartitionMesh& mesh = *partition;
  if (const std::optional<SurfacePoint> hit = mesh.locate(w)) {
    const Face& f = mesh.faces()[static_cast<size_t>(hit->face)];
    if (jacobian) *jacobian = jacobians[static_cast<size_t>(hit->face)];
    return hit->bary[0] * images[static_cast<size_t>(f[0])] + hit->bary[1] * images[static_cast<size_t>(f[1])] +
           hit->bary[2] * images[static_cast<size_t>(f[2])];
  }
  const std::vector<int>& boundary = mesh.boundary();
  const size_t k = static_cast<size_t>(mesh.chord(w));
  const size_t a = static_cast<size_t>(boundary[k]), b = static_cast<size_t>(boundary[(k + 1) % boundary.size()]);
  return gap_map(mesh.vertices()[a], mesh.vertices()[b], images[a], images[b], w, jacobian);
}

namespace {

// The exact check of Φ: every image triangle positive (> 1e-12 × its source area), the boundary's
// images strictly counter-clockwise and once round. Then Φ is a homeomorphism of the polygon onto
// the image polygon (the Tutte / Floater argument, notes §5).
BijectionCheck check_images(const PiecewiseAffineMap& phi, const DiskMoebius& m) {
  const PartitionMesh& mesh = *phi.partition;
  const std::vector<Vec2>& V = mesh.vertices();
  const std::vector<Vec2>& W = phi.images;
  BijectionCheck check;
  check.min_jacobian = check.min_area_ratio = std::numeric_limits<double>::infinity();
  for (const Face& f : mesh.faces()) {
    const size_t i = static_cast<size_t>(f[0]), j = static_cast<size_t>(f[1]), k = static_cast<size_t>(f[2]);
    const double source = orient2d(V[i], V[j], V[k]), image = orient2d(W[i], W[j], W[k]);
    ++check.grid_points;
    if (!(image > 1e-12 * source)) ++check.folded_points;
    const double det = std::isfinite(image) ? image / source : -std::numeric_limits<double>::infinity();
    const Vec2 centroid = (V[i] + V[j] + V[k]) / 3;
    const double stretch = m.stretch(to_complex(centroid));
    check.min_jacobian = std::min(check.min_jacobian, det);
    if (det / (stretch * stretch) < check.min_area_ratio) {
      check.min_area_ratio = det / (stretch * stretch);
      check.worst_point = centroid;
    }
  }
  const std::vector<int>& boundary = mesh.boundary();
  check.boundary_samples = static_cast<int>(boundary.size());
  double turn = 0;
  for (size_t k = 0; k < boundary.size(); ++k) {
    const Vec2& a = W[static_cast<size_t>(boundary[k])];
    const Vec2& b = W[static_cast<size_t>(boundary[(k + 1) % boundary.size()])];
    const double step = turning_angle(a, b);
    if (!(step > 0)) ++check.boundary_order_breaks;
    turn += step;
    check.max_boundary_radius_error = std::max(check.max_boundary_radius_error, std::abs(a.norm() - 1));
  }
  if (!(std::abs(turn - kTwoPi) < std::numbers::pi)) ++check.boundary_order_breaks;
  return check;
}

std::string describe(const BijectionCheck& c) {
  std::ostringstream out;
  if (c.folded_points > 0) {
    out << "folds: " << c.folded_points << " of " << c.grid_points
        << " partition triangles are not positive (worst near w = " << point_text(c.worst_point) << ", area ratio " << c.min_jacobian
        << ")";
  }
  if (c.boundary_order_breaks > 0) {
    out << (out.tellp() > 0 ? "; " : "") << "the circle's images are out of order at " << c.boundary_order_breaks << " of "
        << c.boundary_samples << " boundary vertices";
  }
  return out.str();
}

std::string joined(const std::string& first, const std::string& second) { return first.empty() ? second : first + "; " + second; }

}  // namespace

DiskRegistration partition_registration(const GeodesicFrame& frame, const DiskRegistration& base, std::vector<Vec2> images,
                                        bool allow_fallback) {
  if (!frame.partition)
    throw Error(ErrorCode::kInvalidArgument, "registration: the geodesic frame has no partition mesh (make_geodesic_frame builds it)");
  const PartitionMesh& mesh = *frame.partition;
  const std::vector<Vec2>& V = mesh.vertices();
  if (images.size() != V.size()) {
    throw Error(ErrorCode::kInvalidArgument,
                "registration: " + std::to_string(images.size()) + " images for " + std::to_string(V.size()) + " partition vertices");
  }
  for (size_t i = 0; i < images.size(); ++i) {
    if (!images[i].allFinite())
      throw Error(ErrorCode::kInvalidArgument, "registration: the image of partition vertex " + std::to_string(i) + " is not finite");
  }
  auto phi = std::make_shared<PiecewiseAffineMap>();
  phi->partition = frame.partition;
  phi->images = std::move(images);
  phi->jacobians.reserve(mesh.faces().size());
  for (const Face& f : mesh.faces()) {
    const size_t i = static_cast<size_t>(f[0]), j = static_cast<size_t>(f[1]), k = static_cast<size_t>(f[2]);
    Eigen::Matrix2d source, image;
    source << V[j] - V[i], V[k] - V[i];
    image << phi->images[j] - phi->images[i], phi->images[k] - phi->images[i];
    phi->jacobians.push_back(image * source.inverse());
  }
  const BijectionCheck check = check_images(*phi, base.moebius);
  DiskRegistration f = base;
  f.method = RegistrationMethod::kFrame;
  if (!check.ok() && allow_fallback) {
    f.fallback = RegistrationFallback::kGmfInsteadOfFrame;
    f.fallback_reason = joined(base.fallback_reason, "Φ " + describe(check) + ": the GMF itself");
    return f;
  }
  f.partition_map = std::move(phi);
  f.check = check;
  if (!check.ok()) f.fallback_reason = joined(base.fallback_reason, "Φ " + describe(check) + " (fallback disabled)");
  return f;
}

DiskRegistration register_through_partition(const GeodesicFrame& frame, const DiskRegistration& base, std::vector<Vec2> images,
                                            const DiskLandmarks& landmarks, bool allow_fallback) {
  check_landmarks(landmarks);  // named errors before any work
  DiskRegistration f = partition_registration(frame, base, std::move(images), allow_fallback);
  f.energy = matching_energy(f, landmarks);
  return f;
}

}  // namespace facemorph
