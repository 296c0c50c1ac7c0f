#include "facemorph/meshkit/delaunay.hpp"

#include "facemorph/error.hpp"
#include "facemorph/meshkit/topology.hpp"

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
  return static_cast<double>((LD(b.x()) - LD(a.x())) * (LD(c.y()) - LD(a.y())) -
                             (LD(b.y()) - LD(a.y())) * (LD(c.x()) - LD(a.x())));
}

double incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  auto eval = [&](auto zero) {
    using T = decltype(zero);
    const T adx = T(a.x()) - T(d.x()), ady = T(a.y()) - T(d.y());
    const T bdx = T(b.x()) - T(d.x()), bdy = T(b.y()) - T(d.y());
    const T cdx = T(c.x()) - T(d.x()), cdy = T(c.y()) - T(d.y());
    const T alift = adx * adx + ady * ady, blift = bdx * bdx + bdy * bdy, clift = cdx * cdx + cdy * cdy;
    const T det = alift * (bdx * cdy - cdx * bdy) + blift * (cdx * ady - adx * cdy) + clift * (adx * bdy - bdx * ady);
    const T permanent = alift * (std::abs(bdx * cdy) + std::abs(cdx * bdy)) +
                        blift * (std::abs(cdx * ady) + std::abs(adx * cdy)) +
                        clift * (std::abs(adx * bdy) + std::abs(bdx * ady));
    return std::make_pair(static_cast<double>(det), static_cast<double>(permanent));
  };
  const auto [det, permanent] = eval(0.0);
  if (std::abs(det) > 1.2e-15 * permanent) return det;
  return eval(0.0L).first;
}

namespace {

// Position along a Hilbert curve of order 16; inserting in this order keeps point-location walks short.
uint64_t hilbert_index(uint32_t x, uint32_t y) {
  uint64_t d = 0;
  for (uint32_t s = 1u << 15; s > 0; s >>= 1) {
    const uint32_t rx = (x & s) > 0, ry = (y & s) > 0;
    d += uint64_t{s} * s * ((3 * rx) ^ ry);
    if (ry == 0) {
      if (rx == 1) {
        x = s - 1 - (x & (s - 1)) + (x & ~(s - 1));
        y = s - 1 - (y & (s - 1)) + (y & ~(s - 1));
      }
      std::swap(x, y);
    }
  }
  return d;
}

struct Triangle {
  std::array<int32_t, 3> v;
  std::array<int32_t, 3> n;  // n[k]: neighbour across the edge opposite v[k]; -1 none
  bool alive;
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
    super_ = static_cast<int32_t>(n);
    points_.push_back(center + Vec2(-big, -big));
    points_.push_back(center + Vec2(big, -big));
    points_.push_back(center + Vec2(0, big));
    triangles_.push_back({{super_, super_ + 1, super_ + 2}, {-1, -1, -1}, true});

    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::vector<uint64_t> key(n);
    for (size_t i = 0; i < n; ++i) {
      const Vec2 q = (points_[i] - lo) / extent * 65535.0;
      key[i] = hilbert_index(static_cast<uint32_t>(q.x()), static_cast<uint32_t>(q.y()));
    }
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
    stamp_.assign(triangles_.size(), 0);
    for (uint32_t i : order) insert(static_cast<int32_t>(i));

    std::vector<Face> faces;
    for (const Triangle& t : triangles_) {
      if (!t.alive || t.v[0] >= super_ || t.v[1] >= super_ || t.v[2] >= super_) continue;
      faces.push_back({t.v[0], t.v[1], t.v[2]});
    }
    complete_hull(faces);
    return faces;
  }

 private:
  const Vec2& p(int32_t i) const { return points_[static_cast<size_t>(i)]; }

  int32_t locate(const Vec2& q) const {
    int32_t t = last_;
    for (size_t steps = 0; steps < 4 * triangles_.size() + 16; ++steps) {
      const Triangle& tri = triangles_[static_cast<size_t>(t)];
      int32_t next = -1;
      for (int k = 0; k < 3; ++k) {
        const int k1 = (k + 1 + static_cast<int>(steps % 3)) % 3;  // rotate the test order: no cycling
        if (orient2d(p(tri.v[(k1 + 1) % 3]), p(tri.v[(k1 + 2) % 3]), q) < 0) {
          next = tri.n[k1];
          break;
        }
      }
      if (next < 0) return t;
      t = next;
    }
    throw Error(ErrorCode::kNumerical, "Delaunay: point location did not terminate");
  }

  void insert(int32_t index) {
    const Vec2& q = p(index);
    const int32_t start = locate(q);
    for (int32_t v : triangles_[static_cast<size_t>(start)].v) {
      if (p(v) == q) return;  // exact duplicate: left out
    }
    ++epoch_;
    cavity_.assign(1, start);
    stamp_[static_cast<size_t>(start)] = epoch_;
    for (size_t i = 0; i < cavity_.size(); ++i) {
      const Triangle& t = triangles_[static_cast<size_t>(cavity_[i])];
      for (int32_t nb : t.n) {
        if (nb < 0 || stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        const Triangle& u = triangles_[static_cast<size_t>(nb)];
        if (incircle(p(u.v[0]), p(u.v[1]), p(u.v[2]), q) > 0) {
          stamp_[static_cast<size_t>(nb)] = epoch_;
          cavity_.push_back(nb);
        }
      }
    }
    // Boundary edges of the cavity, each becoming a new triangle (a, b, q).
    rims_.clear();
    for (int32_t c : cavity_) {
      const Triangle& t = triangles_[static_cast<size_t>(c)];
      for (int k = 0; k < 3; ++k) {
        const int32_t nb = t.n[k];
        if (nb >= 0 && stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        const int32_t a = t.v[(k + 1) % 3], b = t.v[(k + 2) % 3];
        if (orient2d(p(a), p(b), q) <= 0) {
          throw Error(ErrorCode::kNumerical, "Delaunay: degenerate cavity at point " + std::to_string(index));
        }
        int32_t slot = -1;
        if (nb >= 0) {
          for (int m = 0; m < 3; ++m) {
            if (triangles_[static_cast<size_t>(nb)].n[m] == c) slot = m;
          }
        }
        rims_.push_back({a, b, nb, slot});
      }
    }
    for (int32_t c : cavity_) {
      triangles_[static_cast<size_t>(c)].alive = false;
      free_.push_back(c);
    }
    created_.clear();
    for (const Rim& rim : rims_) {
      int32_t id;
      if (!free_.empty()) {
        id = free_.back();
        free_.pop_back();
      } else {
        id = static_cast<int32_t>(triangles_.size());
        triangles_.push_back({});
        stamp_.push_back(0);
      }
      triangles_[static_cast<size_t>(id)] = {{rim.a, rim.b, index}, {-1, -1, rim.outside}, true};
      if (rim.outside >= 0) triangles_[static_cast<size_t>(rim.outside)].n[static_cast<size_t>(rim.outside_slot)] = id;
      created_.push_back(id);
    }
    // Link the fan: triangle (a, b, q) meets (b, c, q) across edge (b, q), opposite its vertex a.
    for (int32_t id : created_) {
      Triangle& t = triangles_[static_cast<size_t>(id)];
      for (int32_t other : created_) {
        const Triangle& u = triangles_[static_cast<size_t>(other)];
        if (u.v[0] == t.v[1]) t.n[0] = other;  // u starts where t ends
        if (u.v[1] == t.v[0]) t.n[1] = other;  // u ends where t starts
      }
    }
    last_ = created_.front();
  }

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

  // A cavity boundary edge (a, b) and the triangle outside it (and the slot pointing back).
  struct Rim {
    int32_t a, b, outside, outside_slot;
  };

  std::vector<Vec2> points_;
  std::vector<Triangle> triangles_;
  std::vector<uint32_t> stamp_;  // stamp_[t] == epoch_: t is in the current cavity
  uint32_t epoch_ = 0;
  std::vector<int32_t> cavity_, free_, created_;
  std::vector<Rim> rims_;
  int32_t super_ = 0;
  int32_t last_ = 0;
};

}  // namespace

std::vector<Face> delaunay_triangulation(std::span<const Vec2> points) { return Triangulator(points).run(); }

}  // namespace facemorph
