#include "codec/meshkit/geometry/distance.hpp"

#include "codec/core/util/parallel.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

namespace facemorph {

namespace {

// The nearest point to p of the segment from vertex i to vertex j of triangle `v` (one point where
// they coincide), as barycentric coordinates of the triangle.
Vec3 closest_on_edge(const Vec3& p, const std::array<const Vec3*, 3>& v, int i, int j) {
  const Vec3 edge = *v[static_cast<size_t>(j)] - *v[static_cast<size_t>(i)];
  const double length2 = edge.squaredNorm();
  const double t = length2 > 0 ? std::clamp((p - *v[static_cast<size_t>(i)]).dot(edge) / length2, 0.0, 1.0) : 0.0;
  Vec3 bary = Vec3::Zero();
  bary[i] = 1 - t;
  bary[j] = t;
  return bary;
}

// A triangle whose area is under this share of the parallelogram its edges ab, ac would span at a
// right angle (sin of the angle at a under 1e-10) is taken as collapsed: there the rounding of the
// face region's denominator (|ab x ac|², of order 1e-16 |ab|²|ac|²) is no longer small beside it,
// and at 0 the face region's coordinates are 0/0.
constexpr double kCollapsedSine2 = 1e-20;

}  // namespace

Vec3 closest_point_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  if (!(ab.cross(ac).squaredNorm() > kCollapsedSine2 * ab.squaredNorm() * ac.squaredNorm())) {
    // Collapsed: the longest edge holds the other two (the third vertex lies on it).
    const std::array<const Vec3*, 3> v{&a, &b, &c};
    const double lab = ab.squaredNorm(), lac = ac.squaredNorm(), lbc = (c - b).squaredNorm();
    if (lab >= lac && lab >= lbc) return closest_on_edge(p, v, 0, 1);
    if (lac >= lbc) return closest_on_edge(p, v, 0, 2);
    return closest_on_edge(p, v, 1, 2);
  }
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double t = d1 / (d1 - d3);
    return {1 - t, t, 0};
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double t = d2 / (d2 - d6);
    return {1 - t, 0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double denominator = va + vb + vc;
  const double v = vb / denominator, w = vc / denominator;
  return {1 - v - w, v, w};
}

PointToMesh::PointToMesh(const TriangleMesh& mesh) : mesh_(mesh) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Vec3& p : mesh.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (mesh.faces.empty()) return;
  const Vec3 extent = (hi - lo).cwiseMax(1e-12 * std::max(1.0, (hi - lo).norm()));
  cell_ = std::cbrt(extent.prod() / std::max<double>(1.0, static_cast<double>(mesh.faces.size()) / 2));
  nx_ = std::clamp(static_cast<int>(std::ceil(extent.x() / cell_)), 1, 512);
  ny_ = std::clamp(static_cast<int>(std::ceil(extent.y() / cell_)), 1, 512);
  nz_ = std::clamp(static_cast<int>(std::ceil(extent.z() / cell_)), 1, 512);
  cell_ = std::max({extent.x() / nx_, extent.y() / ny_, extent.z() / nz_});
  origin_ = lo;
  slack_ = 1e-9 * (std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff()) + cell_);
  boxes_.resize(mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    Box& box = boxes_[f];
    box.lo = box.hi = mesh.positions[static_cast<size_t>(mesh.faces[f][0])];
    for (const int32_t v : mesh.faces[f]) {
      box.lo = box.lo.cwiseMin(mesh.positions[static_cast<size_t>(v)]);
      box.hi = box.hi.cwiseMax(mesh.positions[static_cast<size_t>(v)]);
    }
  }
  // The cells a face's box overlaps.
  auto range = [&](size_t f, std::array<int, 6>& r) {
    const int n[3] = {nx_, ny_, nz_};
    for (int k = 0; k < 3; ++k) {
      r[static_cast<size_t>(k)] = std::clamp(static_cast<int>(std::floor((boxes_[f].lo[k] - origin_[k]) / cell_)), 0, n[k] - 1);
      r[static_cast<size_t>(k + 3)] = std::clamp(static_cast<int>(std::floor((boxes_[f].hi[k] - origin_[k]) / cell_)), 0, n[k] - 1);
    }
  };
  start_.assign(static_cast<size_t>(nx_) * ny_ * nz_ + 1, 0);
  std::array<int, 6> r;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    range(f, r);
    for (int z = r[2]; z <= r[5]; ++z)
      for (int y = r[1]; y <= r[4]; ++y)
        for (int x = r[0]; x <= r[3]; ++x) ++start_[static_cast<size_t>((z * ny_ + y) * nx_ + x) + 1];
  }
  for (size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
  faces_.resize(static_cast<size_t>(start_.back()));
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    range(f, r);
    for (int z = r[2]; z <= r[5]; ++z)
      for (int y = r[1]; y <= r[4]; ++y)
        for (int x = r[0]; x <= r[3]; ++x)
          faces_[static_cast<size_t>(fill[static_cast<size_t>((z * ny_ + y) * nx_ + x)]++)] = static_cast<int>(f);
  }
}

double PointToMesh::distance(const Vec3& p) const {
  double squared = 0;
  nearest(p, squared);
  return std::sqrt(squared);
}

double PointToMesh::distance_below(const Vec3& p, double bound) const {
  double squared = 0;
  nearest(p, squared, bound);
  return std::sqrt(squared);
}

SurfacePoint PointToMesh::closest(const Vec3& p, double* distance) const {
  double squared = 0;
  const SurfacePoint point = nearest(p, squared);
  if (distance) *distance = std::sqrt(squared);
  return point;
}

SurfacePoint PointToMesh::closest_from(const Vec3& p, int hint, double* distance) const {
  double squared = 0;
  const SurfacePoint point = nearest(p, squared, std::numeric_limits<double>::infinity(), nullptr, false, hint);
  if (distance) *distance = std::sqrt(squared);
  return point;
}

SurfacePoint PointToMesh::closest_squared(const Vec3& p, double& squared, const std::vector<char>* skip_face, double bound, int hint) const {
  return nearest(p, squared, bound, skip_face, true, hint);
}

SurfacePoint PointToMesh::nearest(const Vec3& p, double& best, double bound, const std::vector<char>* skip_face, bool skip_past_bound,
                                   int hint) const {
  SurfacePoint point;
  best = std::numeric_limits<double>::infinity();
  if (mesh_.faces.empty()) return point;
  const int n[3] = {nx_, ny_, nz_};
  int c[3];
  for (int k = 0; k < 3; ++k) c[k] = std::clamp(static_cast<int>(std::floor((p[k] - origin_[k]) / cell_)), 0, n[k] - 1);
  // Outside the grid the nearest cell is still c; its distance bounds how far shells must go.
  const int max_shell = std::max({nx_, ny_, nz_});
  // The squared distance past which a box holds nothing as near as `best`: a face's nearest point to
  // p lies in its box and in a cell the face is listed in, so the face that wins (ties included) is
  // never skipped, and the search finds what a search without skips finds.
  // Where the caller needs nothing `bound` or farther (closest_squared), no box past it (and the
  // slack) is measured either: a face nearer than `bound` is still found, ties included.
  double limit = std::numeric_limits<double>::infinity();
  if (skip_past_bound && bound < std::numeric_limits<double>::infinity()) limit = (bound + slack_) * (bound + slack_);
  const auto box_squared = [&p](const Vec3& lo, const Vec3& hi) { return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).squaredNorm(); };
  // The face's squared distance; the nearest so far where it is nearer (or as near, of a lower index).
  const auto measure = [&](int face) {
    const Face& f = mesh_.faces[static_cast<size_t>(face)];
    const Vec3& v0 = mesh_.positions[static_cast<size_t>(f[0])];
    const Vec3& v1 = mesh_.positions[static_cast<size_t>(f[1])];
    const Vec3& v2 = mesh_.positions[static_cast<size_t>(f[2])];
    const Vec3 bary = closest_point_barycentric(p, v0, v1, v2);
    const double squared = (bary[0] * v0 + bary[1] * v1 + bary[2] * v2 - p).squaredNorm();
    // Buckets are visited out of face order (and share faces): the index breaks ties. A hint
    // measured first is measured again in its cells and changes nothing there.
    if (squared < best || (squared == best && face < point.face)) {
      best = squared;
      point = {face, bary};
      limit = std::min(limit, (std::sqrt(best) + slack_) * (std::sqrt(best) + slack_));
    }
  };
  const auto visit = [&](int x, int y, int z) {
    const size_t bucket = static_cast<size_t>((z * ny_ + y) * nx_ + x);
    if (start_[bucket] == start_[bucket + 1]) return;
    const Vec3 cell_lo = origin_ + Vec3(x, y, z) * cell_;
    if (box_squared(cell_lo, cell_lo + Vec3::Constant(cell_)) > limit) return;
    for (int i = start_[bucket]; i < start_[bucket + 1]; ++i) {
      const int face = faces_[static_cast<size_t>(i)];
      if (skip_face && (*skip_face)[static_cast<size_t>(face)]) continue;
      if (box_squared(boxes_[static_cast<size_t>(face)].lo, boxes_[static_cast<size_t>(face)].hi) > limit) continue;
      measure(face);
    }
  };
  if (hint >= 0 && static_cast<size_t>(hint) < mesh_.faces.size() && !(skip_face && (*skip_face)[static_cast<size_t>(hint)])) measure(hint);
  for (int shell = 0; shell <= max_shell; ++shell) {
    // The cells of this shell alone (Chebyshev distance `shell` from c), in z, y, x order: its two
    // z faces whole, between them the two y rows whole and the two x ends of the others (a shell
    // is O(shell²) cells; scanning its cube and skipping the inside was O(shell³)).
    const int x0 = std::max(c[0] - shell, 0), x1 = std::min(c[0] + shell, nx_ - 1);
    const int y0 = std::max(c[1] - shell, 0), y1 = std::min(c[1] + shell, ny_ - 1);
    const int z0 = std::max(c[2] - shell, 0), z1 = std::min(c[2] + shell, nz_ - 1);
    for (int z = z0; z <= z1; ++z) {
      const bool z_face = std::abs(z - c[2]) == shell;
      for (int y = y0; y <= y1; ++y) {
        if (z_face || std::abs(y - c[1]) == shell) {
          for (int x = x0; x <= x1; ++x) visit(x, y, z);
        } else {
          if (c[0] - shell >= 0) visit(c[0] - shell, y, z);
          if (shell > 0 && c[0] + shell < nx_) visit(c[0] + shell, y, z);
        }
      }
    }
    // Every point in cells beyond this shell is at least `shell * cell` away from p's cell.
    const Vec3 cell_lo = origin_ + Vec3(c[0], c[1], c[2]) * cell_;
    const double margin = std::min((p - cell_lo).minCoeff(), (cell_lo + Vec3::Constant(cell_) - p).minCoeff());
    const double reach = shell * cell_ + std::max(margin, 0.0);  // no margin when p is outside the grid
    // Strictly within: a face at exactly `reach` may lie in the next shell, and of equally near faces
    // the lowest index must win (as a scan over every face gives).
    if (best < std::numeric_limits<double>::infinity() && std::sqrt(best) < reach) break;
    if (reach >= bound) break;  // whatever lies beyond is at least `bound` away
  }
  return point;
}

double bounding_box_diagonal(std::span<const Vec3> points) {
  if (points.empty()) return 0;
  Vec3 lo = points.front(), hi = lo;
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).norm();
}

SurfaceDistance surface_distance(const TriangleMesh& reference, const TriangleMesh& test, int threads) {
  SurfaceDistance d;
  d.diagonal = bounding_box_diagonal(reference.positions);
  // The two locators built side by side (each a pass over its mesh's faces).
  std::optional<PointToMesh> to_reference, to_test;
  parallel_for(2, threads, [&](int k) { k == 0 ? to_reference.emplace(reference) : to_test.emplace(test); });
  double sum = 0;
  std::vector<double> distances;
  auto accumulate = [&](const std::vector<Vec3>& points, const PointToMesh& other, const TriangleMesh& owner) {
    std::vector<uint8_t> used(points.size(), 0);
    for (const Face& f : owner.faces) {
      for (int32_t v : f) used[static_cast<size_t>(v)] = 1;
    }
    std::vector<size_t> queried;
    for (size_t i = 0; i < points.size(); ++i)
      if (used[i]) queried.push_back(i);
    // The points in up to `threads` runs of consecutive ones, side by side. In each run every search
    // starts from the previous vertex's nearest face (closest_from: the same distance to the bit,
    // whatever the hint): neighbours in a mesh's vertex order are mostly neighbours on the surface,
    // so the first bound is near the nearest and most boxes are skipped unmeasured. The distances are
    // then summed in the points' order, so that any number of runs gives the same figures to the bit.
    std::vector<double> e(queried.size());
    parallel_runs(queried.size(), threads, [&](size_t, size_t first, size_t last) {
      int hint = -1;
      for (size_t q = first; q < last; ++q) hint = other.closest_from(points[queried[q]], hint, &e[q]).face;
    });
    for (const double distance : e) {
      sum += distance * distance;
      d.max = std::max(d.max, distance);
      distances.push_back(distance);
    }
  };
  accumulate(test.positions, *to_reference, test);
  const auto from_reference = static_cast<std::ptrdiff_t>(distances.size());
  accumulate(reference.positions, *to_test, reference);
  const size_t count = distances.size();
  d.rms = count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  std::vector<double> one_way(distances.begin(), distances.begin() + from_reference);
  d.p99_test_to_reference = nearest_rank_p99(one_way);
  one_way.assign(distances.begin() + from_reference, distances.end());
  d.p99_reference_to_test = nearest_rank_p99(one_way);
  d.p99 = nearest_rank_p99(distances);
  return d;
}

double nearest_rank_p99(std::vector<double>& values) {
  if (values.empty()) return 0;
  const size_t rank = (99 * values.size() + 99) / 100 - 1;  // ceil(0.99 n), 0-based
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(rank), values.end());
  return values[rank];
}

}  // namespace facemorph
