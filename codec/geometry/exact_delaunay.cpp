#include "codec/geometry/exact_delaunay.hpp"

#include "facemorph/error.hpp"

#include <algorithm>
#include <array>
#include <numeric>

namespace facemorph {

namespace {

__extension__ typedef __int128 Int128;
__extension__ typedef unsigned __int128 UInt128;

// A signed 256-bit integer (two's complement in two 128-bit halves): just enough arithmetic to sum
// the three 2^142-sized products of the in-circle determinant exactly.
struct Int256 {
  UInt128 lo = 0, hi = 0;

  static Int256 product(Int128 a, Int128 b) {
    const bool negative = (a < 0) != (b < 0);
    const UInt128 ua = a < 0 ? -static_cast<UInt128>(a) : static_cast<UInt128>(a);
    const UInt128 ub = b < 0 ? -static_cast<UInt128>(b) : static_cast<UInt128>(b);
    const auto a0 = static_cast<uint64_t>(ua), a1 = static_cast<uint64_t>(ua >> 64);
    const auto b0 = static_cast<uint64_t>(ub), b1 = static_cast<uint64_t>(ub >> 64);
    const UInt128 p00 = static_cast<UInt128>(a0) * b0, p01 = static_cast<UInt128>(a0) * b1;
    const UInt128 p10 = static_cast<UInt128>(a1) * b0, p11 = static_cast<UInt128>(a1) * b1;
    const UInt128 middle = (p00 >> 64) + static_cast<uint64_t>(p01) + static_cast<uint64_t>(p10);
    Int256 r;
    r.lo = (middle << 64) | static_cast<uint64_t>(p00);
    r.hi = p11 + (p01 >> 64) + (p10 >> 64) + (middle >> 64);
    if (negative) {
      r.lo = ~r.lo + 1;
      r.hi = ~r.hi + (r.lo == 0 ? 1 : 0);
    }
    return r;
  }

  Int256& operator+=(const Int256& other) {
    const UInt128 sum = lo + other.lo;
    hi += other.hi + (sum < lo ? 1 : 0);
    lo = sum;
    return *this;
  }

  int sign() const {
    if (hi >> 127) return -1;
    return (hi | lo) != 0 ? 1 : 0;
  }
};

// The in-circle determinant Σ lift(a − d) · minor_a for one lifting, from the points relative to
// d. Adding an affine function of (x, y) to a lifting does not change the determinant, so relative
// coordinates give the determinant of the absolute lifting.
template <typename Lift>
int lifted_determinant_sign(const std::array<int64_t, 6>& rel, const std::array<Int128, 3>& minor, Lift&& lift) {
  Int256 det;
  for (int k = 0; k < 3; ++k) det += Int256::product(lift(rel[static_cast<size_t>(2 * k)], rel[static_cast<size_t>(2 * k + 1)]), minor[static_cast<size_t>(k)]);
  return det.sign();
}

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
};

class ExactTriangulator {
 public:
  explicit ExactTriangulator(std::span<const IntPoint> input) : points_(input.begin(), input.end()) {}

  ExactDelaunayResult run() {
    ExactDelaunayResult result;
    const size_t n = points_.size();
    for (const IntPoint& p : points_) {
      if (p.x < -kExactCoordinateLimit || p.x > kExactCoordinateLimit || p.y < -kExactCoordinateLimit || p.y > kExactCoordinateLimit) {
        throw Error(ErrorCode::kInvalidArgument, "exact_delaunay: coordinate beyond 2^30");
      }
    }
    if (n < 3) return result;
    // A super triangle 8x beyond the coordinate limit: far outside every circumcircle of three
    // input points that are not nearly collinear.
    constexpr int64_t kFar = kExactCoordinateLimit * 8;
    super_ = static_cast<int32_t>(n);
    points_.push_back({-kFar, -kFar});
    points_.push_back({kFar, -kFar});
    points_.push_back({0, kFar});
    triangles_.push_back({{super_, super_ + 1, super_ + 2}, {-1, -1, -1}});
    alive_.push_back(1);
    stamp_.push_back(0);

    std::vector<uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    std::vector<uint64_t> key(n);
    for (size_t i = 0; i < n; ++i) {
      const auto x = static_cast<uint32_t>((points_[i].x + kExactCoordinateLimit) >> 15);
      const auto y = static_cast<uint32_t>((points_[i].y + kExactCoordinateLimit) >> 15);
      key[i] = hilbert_index(x, y);
    }
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
    for (uint32_t i : order) insert(static_cast<int32_t>(i));

    for (size_t t = 0; t < triangles_.size(); ++t) {
      const auto& v = triangles_[t].v;
      if (alive_[t] && v[0] < super_ && v[1] < super_ && v[2] < super_) result.faces.push_back({v[0], v[1], v[2]});
    }
    result.unresolved_ties = unresolved_ties_;
    return result;
  }

 private:
  const IntPoint& p(int32_t i) const { return points_[static_cast<size_t>(i)]; }

  int32_t locate(const IntPoint& q) const {
    int32_t t = last_;
    for (size_t steps = 0; steps < 4 * triangles_.size() + 16; ++steps) {
      const Triangle& tri = triangles_[static_cast<size_t>(t)];
      int32_t next = -1;
      for (int k = 0; k < 3; ++k) {
        const int k1 = (k + 1 + static_cast<int>(steps % 3)) % 3;  // rotate the test order: no cycling
        if (exact_orientation(p(tri.v[static_cast<size_t>((k1 + 1) % 3)]), p(tri.v[static_cast<size_t>((k1 + 2) % 3)]), q) < 0) {
          next = tri.n[static_cast<size_t>(k1)];
          break;
        }
      }
      if (next < 0) return t;
      t = next;
    }
    throw Error(ErrorCode::kNumerical, "exact_delaunay: point location did not terminate");
  }

  bool in_circumcircle(const Triangle& t, const IntPoint& q) {
    const int s = perturbed_incircle(p(t.v[0]), p(t.v[1]), p(t.v[2]), q);
    if (s == 0) ++unresolved_ties_;
    return s > 0;
  }

  void insert(int32_t index) {
    const IntPoint& q = p(index);
    const int32_t start = locate(q);
    for (int32_t v : triangles_[static_cast<size_t>(start)].v) {
      if (p(v) == q) throw Error(ErrorCode::kInvalidArgument, "exact_delaunay: repeated point");
    }
    ++epoch_;
    cavity_.assign(1, start);
    stamp_[static_cast<size_t>(start)] = epoch_;
    for (size_t i = 0; i < cavity_.size(); ++i) {
      const Triangle t = triangles_[static_cast<size_t>(cavity_[i])];
      for (int32_t nb : t.n) {
        if (nb < 0 || stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        if (in_circumcircle(triangles_[static_cast<size_t>(nb)], q)) {
          stamp_[static_cast<size_t>(nb)] = epoch_;
          cavity_.push_back(nb);
        }
      }
    }
    // The cavity's boundary edges, each becoming a new triangle (a, b, q).
    rims_.clear();
    for (int32_t c : cavity_) {
      const Triangle& t = triangles_[static_cast<size_t>(c)];
      for (int k = 0; k < 3; ++k) {
        const int32_t nb = t.n[static_cast<size_t>(k)];
        if (nb >= 0 && stamp_[static_cast<size_t>(nb)] == epoch_) continue;
        const int32_t a = t.v[static_cast<size_t>((k + 1) % 3)], b = t.v[static_cast<size_t>((k + 2) % 3)];
        if (exact_orientation(p(a), p(b), q) <= 0) throw Error(ErrorCode::kNumerical, "exact_delaunay: the cavity is not star-shaped");
        int32_t slot = -1;
        if (nb >= 0) {
          for (int m = 0; m < 3; ++m) {
            if (triangles_[static_cast<size_t>(nb)].n[static_cast<size_t>(m)] == c) slot = m;
          }
        }
        rims_.push_back({a, b, nb, slot});
      }
    }
    for (int32_t c : cavity_) {
      alive_[static_cast<size_t>(c)] = 0;
      free_.push_back(c);
    }
    created_.clear();
    for (const CavityEdge& rim : rims_) {
      int32_t id;
      if (!free_.empty()) {
        id = free_.back();
        free_.pop_back();
      } else {
        id = static_cast<int32_t>(triangles_.size());
        triangles_.push_back({});
        alive_.push_back(0);
        stamp_.push_back(0);
      }
      triangles_[static_cast<size_t>(id)] = {{rim.a, rim.b, index}, {-1, -1, rim.outside}};
      alive_[static_cast<size_t>(id)] = 1;
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

  // A cavity boundary edge (a, b) and the triangle outside it (and the slot pointing back).
  struct CavityEdge {
    int32_t a, b, outside, outside_slot;
  };

  std::vector<IntPoint> points_;
  std::vector<Triangle> triangles_;
  std::vector<uint8_t> alive_;
  std::vector<uint32_t> stamp_;  // stamp_[t] == epoch_: t is in the current cavity
  uint32_t epoch_ = 0;
  std::vector<int32_t> cavity_, free_, created_;
  std::vector<CavityEdge> rims_;
  int32_t super_ = 0;
  int32_t last_ = 0;
  int unresolved_ties_ = 0;
};

}  // namespace

int exact_orientation(const IntPoint& a, const IntPoint& b, const IntPoint& c) {
  const Int128 det = static_cast<Int128>(b.x - a.x) * (c.y - a.y) - static_cast<Int128>(b.y - a.y) * (c.x - a.x);
  return det > 0 ? 1 : det < 0 ? -1 : 0;
}

int perturbed_incircle(const IntPoint& a, const IntPoint& b, const IntPoint& c, const IntPoint& d) {
  const std::array<int64_t, 6> rel = {a.x - d.x, a.y - d.y, b.x - d.x, b.y - d.y, c.x - d.x, c.y - d.y};
  const auto [adx, ady, bdx, bdy, cdx, cdy] = rel;
  const std::array<Int128, 3> minor = {static_cast<Int128>(bdx) * cdy - static_cast<Int128>(cdx) * bdy,
                                       static_cast<Int128>(cdx) * ady - static_cast<Int128>(adx) * cdy,
                                       static_cast<Int128>(adx) * bdy - static_cast<Int128>(bdx) * ady};
  if (const int s = lifted_determinant_sign(rel, minor, [](int64_t x, int64_t y) { return static_cast<Int128>(x) * x + static_cast<Int128>(y) * y; })) {
    return s;
  }
  if (const int s = lifted_determinant_sign(rel, minor, [](int64_t x, int64_t y) { return -static_cast<Int128>(x) * y; })) return s;
  return lifted_determinant_sign(rel, minor, [](int64_t x, int64_t y) { return static_cast<Int128>(x) * x - static_cast<Int128>(y) * y; });
}

ExactDelaunayResult exact_delaunay(std::span<const IntPoint> points) { return ExactTriangulator(points).run(); }

}  // namespace facemorph
