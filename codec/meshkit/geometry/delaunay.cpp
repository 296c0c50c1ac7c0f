#include "codec/meshkit/geometry/delaunay.hpp"

#include "codec/core/geometry/bowyer_watson.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>

namespace facemorph {

double orient2d(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double l = (b.x() - a.x()) * (c.y() - a.y());
  const double r = (b.y() - a.y()) * (c.x() - a.x());
  const double det = l - r;
  const double bound = 3.4e-16 * (std::abs(l) + std::abs(r));
  if (std::abs(det) > bound) return det;
  using LD = long double;
  return static_cast<double>((LD(b.x()) - LD(a.x())) * (LD(c.y()) - LD(a.y())) - (LD(b.y()) - LD(a.y())) * (LD(c.x()) - LD(a.x())));
}

double incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  auto eval = [&](auto zero) {
    using T = decltype(zero);
    const T adx = T(a.x()) - T(d.x()), ady = T(a.y()) - T(d.y());
    const T bdx = T(b.x()) - T(d.x()), bdy = T(b.y()) - T(d.y());
    const T cdx = T(c.x()) - T(d.x()), cdy = T(c.y()) - T(d.y());
    const T alift = adx * adx + ady * ady, blift = bdx * bdx + bdy * bdy, clift = cdx * cdx + cdy * cdy;
    const T det = alift * (bdx * cdy - cdx * bdy) + blift * (cdx * ady - adx * cdy) + clift * (adx * bdy - bdx * ady);
    const T permanent = alift * (std::abs(bdx * cdy) + std::abs(cdx * bdy)) + blift * (std::abs(cdx * ady) + std::abs(adx * cdy)) +
                        clift * (std::abs(adx * bdy) + std::abs(bdx * ady));
    return std::make_pair(static_cast<double>(det), static_cast<double>(permanent));
  };
  const auto [det, permanent] = eval(0.0);
  if (std::abs(det) > 1.2e-15 * permanent) return det;
  return eval(0.0L).first;
}

namespace {

// The float predicates of the header.
struct FloatPredicates {
  static constexpr const char* kName = "Delaunay";
  static double orientation(const Vec2& a, const Vec2& b, const Vec2& c) { return orient2d(a, b, c); }
  static bool in_circle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& q) { return incircle(a, b, c, q) > 0; }
};

class Triangulator {
 public:
  explicit Triangulator(std::span<const Vec2> input) : points_(input.begin(), input.end()) {}

  std::vector<Face> run() {
    const size_t n = points_.size();
    if (n < 3) return {};
    Vec2 lo = points_[0], hi = points_[0];
    for (const Vec2& p : points_) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const Vec2 center = 0.5 * (lo + hi);
    const double extent = std::max((hi - lo).maxCoeff(), 1e-300);
    const double big = 1e3 * extent;
    points_.push_back(center + Vec2(-big, -big));
    points_.push_back(center + Vec2(big, -big));
    points_.push_back(center + Vec2(0, big));
    FloatPredicates predicates;
    bowyer_watson::Triangulation<Vec2, FloatPredicates> triangulation(points_, predicates);

    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::vector<uint64_t> key(n);
    for (size_t i = 0; i < n; ++i) {
      const Vec2 q = (points_[i] - lo) / extent * 65535.0;
      key[i] = bowyer_watson::hilbert_index(static_cast<uint32_t>(q.x()), static_cast<uint32_t>(q.y()));
    }
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
    for (uint32_t i : order) triangulation.insert(static_cast<int32_t>(i));  // false: an exact duplicate, left out

    std::vector<Face> faces = triangulation.faces();
    complete_hull(faces);
    return faces;
  }

 private:
  const Vec2& p(int32_t i) const { return points_[static_cast<size_t>(i)]; }

  // Removing the super triangle can leave the hull with reflex notches where a far super vertex
  // "saw" a hull edge; close each notch (a, b, c turning clockwise) with the triangle (a, c, b).
  void complete_hull(std::vector<Face>& faces) const {
    for (int round = 0; round < 64; ++round) {
      MeshBoundary boundary = boundary_of(faces);
      bool changed = false;
      for (const auto& loop : boundary) {
        const size_t m = loop.size();
        for (size_t i = 0; i < m && m > 3; ++i) {
          const int32_t a = loop[i], b = loop[(i + 1) % m], c = loop[(i + 2) % m];
          if (orient2d(p(a), p(b), p(c)) < 0) {
            faces.push_back({a, c, b});
            changed = true;
            break;  // the loop changed; recompute it
          }
        }
      }
      if (!changed) return;
    }
  }

  using MeshBoundary = std::vector<std::vector<int32_t>>;
  static MeshBoundary boundary_of(const std::vector<Face>& faces) {
    std::vector<std::pair<uint64_t, std::array<int32_t, 2>>> half;
    for (const Face& f : faces) {
      for (int k = 0; k < 3; ++k) half.push_back({undirected_edge_key(f[k], f[(k + 1) % 3]), {f[k], f[(k + 1) % 3]}});
    }
    std::sort(half.begin(), half.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    std::vector<std::array<int32_t, 2>> boundary;
    for (size_t i = 0; i < half.size();) {
      size_t j = i;
      while (j < half.size() && half[j].first == half[i].first) ++j;
      if (j - i == 1) boundary.push_back(half[i].second);
      i = j;
    }
    std::sort(boundary.begin(), boundary.end());
    MeshBoundary loops;
    std::vector<uint8_t> used(boundary.size(), 0);
    auto next_of = [&](int32_t v) {
      auto it = std::lower_bound(boundary.begin(), boundary.end(), std::array<int32_t, 2>{v, std::numeric_limits<int32_t>::min()});
      return it != boundary.end() && (*it)[0] == v ? static_cast<size_t>(it - boundary.begin()) : boundary.size();
    };
    for (size_t s = 0; s < boundary.size(); ++s) {
      if (used[s]) continue;
      std::vector<int32_t> loop;
      for (size_t e = s; e < boundary.size() && !used[e]; e = next_of(boundary[e][1])) {
        used[e] = 1;
        loop.push_back(boundary[e][0]);
      }
      loops.push_back(std::move(loop));
    }
    return loops;
  }

  std::vector<Vec2> points_;
};

}  // namespace

std::vector<Face> delaunay_triangulation(std::span<const Vec2> points) { return Triangulator(points).run(); }

}  // namespace facemorph
