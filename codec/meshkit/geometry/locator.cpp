#include "codec/meshkit/geometry/locator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace facemorph {

namespace {

// A depth (the least barycentric) far above the rounding of barycentric() (a few 1e-16 where the
// face is not near-degenerate): a face found this deep holds p, and a face outside p's box, whose
// true depth is below 0, would need a rounding error of 1e-12 to be computed deeper.
constexpr double kSureDepth = 1e-12;

}  // namespace

TriangleLocator::TriangleLocator(std::span<const Vec2> points, std::span<const Face> faces, double faces_per_bucket)
    : points_(points), faces_(faces) {
  Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Face& f : faces) {
    for (int32_t v : f) {
      lo = lo.cwiseMin(points[static_cast<size_t>(v)]);
      hi = hi.cwiseMax(points[static_cast<size_t>(v)]);
    }
  }
  if (faces.empty()) return;
  const Vec2 extent = (hi - lo).cwiseMax(1e-300);
  const double buckets = std::max(1.0, static_cast<double>(faces.size()) / faces_per_bucket);
  cell_ = std::sqrt(extent.x() * extent.y() / buckets);
  if (!(cell_ > 0)) cell_ = std::max(extent.x(), extent.y());
  nx_ = std::clamp(static_cast<int>(std::ceil(extent.x() / cell_)), 1, 1 << 14);
  ny_ = std::clamp(static_cast<int>(std::ceil(extent.y() / cell_)), 1, 1 << 14);
  cell_ = std::max(extent.x() / nx_, extent.y() / ny_);
  origin_ = lo;

  // Two passes (count, then fill): one contiguous array, no per-bucket vectors.
  auto span_of = [&](const Face& f, int& x0, int& x1, int& y0, int& y1) {
    Vec2 a = points[static_cast<size_t>(f[0])], b = a;
    for (int32_t v : f) {
      a = a.cwiseMin(points[static_cast<size_t>(v)]);
      b = b.cwiseMax(points[static_cast<size_t>(v)]);
    }
    x0 = std::clamp(static_cast<int>(std::floor((a.x() - origin_.x()) / cell_)), 0, nx_ - 1);
    x1 = std::clamp(static_cast<int>(std::floor((b.x() - origin_.x()) / cell_)), 0, nx_ - 1);
    y0 = std::clamp(static_cast<int>(std::floor((a.y() - origin_.y()) / cell_)), 0, ny_ - 1);
    y1 = std::clamp(static_cast<int>(std::floor((b.y() - origin_.y()) / cell_)), 0, ny_ - 1);
  };
  bucket_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (const Face& f : faces) {
    int x0, x1, y0, y1;
    span_of(f, x0, x1, y0, y1);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) ++bucket_start_[static_cast<size_t>(y * nx_ + x) + 1];
    }
  }
  for (size_t i = 1; i < bucket_start_.size(); ++i) bucket_start_[i] += bucket_start_[i - 1];
  bucket_faces_.resize(static_cast<size_t>(bucket_start_.back()));
  bucket_boxes_.resize(bucket_faces_.size());
  std::vector<int> fill(bucket_start_.begin(), bucket_start_.end() - 1);
  for (size_t f = 0; f < faces.size(); ++f) {
    int x0, x1, y0, y1;
    span_of(faces[f], x0, x1, y0, y1);
    const Box box = outward_box(points, faces[f]);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const auto slot = static_cast<size_t>(fill[static_cast<size_t>(y * nx_ + x)]++);
        bucket_faces_[slot] = static_cast<int>(f);
        bucket_boxes_[slot] = box;
      }
    }
  }
}

TriangleLocator::Box TriangleLocator::outward_box(std::span<const Vec2> points, const Face& face) {
  Vec2 lo = points[static_cast<size_t>(face[0])], hi = lo;
  for (int32_t v : face) {
    lo = lo.cwiseMin(points[static_cast<size_t>(v)]);
    hi = hi.cwiseMax(points[static_cast<size_t>(v)]);
  }
  // A double rounds to the nearest float, either side: one float step further out holds it (and
  // past the float range, the infinities; a NaN box holds nothing, and its face is measured only
  // by the scan of every face).
  constexpr float kInf = std::numeric_limits<float>::infinity(), kMax = std::numeric_limits<float>::max();
  const auto to_float = [&](double x) { return x > kMax ? kInf : x < -kMax ? -kInf : static_cast<float>(x); };
  const auto down = [&](double x) { return std::nextafter(to_float(x), -kInf); };
  const auto up = [&](double x) { return std::nextafter(to_float(x), kInf); };
  return {down(lo.x()), down(lo.y()), up(hi.x()), up(hi.y())};
}

Vec3 TriangleLocator::barycentric(int face, const Vec2& p) const {
  const Face& f = faces_[static_cast<size_t>(face)];
  const Vec2& a = points_[static_cast<size_t>(f[0])];
  const Vec2& b = points_[static_cast<size_t>(f[1])];
  const Vec2& c = points_[static_cast<size_t>(f[2])];
  // Signed sub-areas over the total (method-notes §6): exact for points on edges and vertices.
  auto area = [](const Vec2& u, const Vec2& v, const Vec2& w) {
    return (v.x() - u.x()) * (w.y() - u.y()) - (v.y() - u.y()) * (w.x() - u.x());
  };
  const double total = area(a, b, c);
  if (total == 0) return Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3);
  const double alpha = area(p, b, c) / total, beta = area(a, p, c) / total;
  return Vec3(alpha, beta, 1.0 - alpha - beta);
}

std::optional<SurfacePoint> TriangleLocator::locate(const Vec2& p, double tolerance) const {
  if (faces_.empty() || !p.allFinite()) return std::nullopt;
  // A point just outside the bucket grid may still lie within tolerance of a face on its edge.
  const int raw_x = static_cast<int>(std::floor((p.x() - origin_.x()) / cell_));
  const int raw_y = static_cast<int>(std::floor((p.y() - origin_.y()) / cell_));
  const int x = std::clamp(raw_x, 0, nx_ - 1), y = std::clamp(raw_y, 0, ny_ - 1);
  if (std::abs(raw_x - x) > 1 || std::abs(raw_y - y) > 1) return std::nullopt;
  const size_t bucket = static_cast<size_t>(y * nx_ + x);
  SurfacePoint best;
  double best_depth = -std::numeric_limits<double>::infinity();
  // The faces whose boxes hold p first. p lies strictly outside a face whose box does not hold it
  // (the face's depth is below 0), so where one of these holds p inside by more than rounding, it
  // is the deepest of the whole bucket, as the scan of every face below would find it (ties: the
  // earlier face, both ways; every face with p inside or on it has p in its box).
  const auto scan = [&](bool boxed) {
    for (int i = bucket_start_[bucket]; i < bucket_start_[bucket + 1]; ++i) {
      if (boxed && !bucket_boxes_[static_cast<size_t>(i)].holds(p)) continue;
      const int f = bucket_faces_[static_cast<size_t>(i)];
      const Vec3 bary = barycentric(f, p);
      const double depth = bary.minCoeff();
      if (depth > best_depth) {
        best_depth = depth;
        best = {f, bary};
      }
    }
  };
  scan(true);
  if (!(best_depth > kSureDepth)) {
    // On an edge, outside every face, or within rounding of it: every face of the bucket measured.
    best = {};
    best_depth = -std::numeric_limits<double>::infinity();
    scan(false);
  }
  if (best.face < 0 || best_depth < -tolerance) return std::nullopt;
  if (best_depth < 0) {
    best.bary = best.bary.cwiseMax(0.0);
    best.bary /= best.bary.sum();
  }
  return best;
}

}  // namespace facemorph
