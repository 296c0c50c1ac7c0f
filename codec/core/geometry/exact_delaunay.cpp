#include "codec/core/geometry/exact_delaunay.hpp"

#include "codec/core/geometry/bowyer_watson.hpp"
#include "format/error.hpp"

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
  for (int k = 0; k < 3; ++k)
    det += Int256::product(lift(rel[static_cast<size_t>(2 * k)], rel[static_cast<size_t>(2 * k + 1)]), minor[static_cast<size_t>(k)]);
  return det.sign();
}

// The exact predicates of the header, counting the in-circle tests no perturbation term decided.
struct ExactPredicates {
  static constexpr const char* kName = "exact_delaunay";
  int unresolved_ties = 0;

  static int orientation(const IntPoint& a, const IntPoint& b, const IntPoint& c) { return exact_orientation(a, b, c); }
  bool in_circle(const IntPoint& a, const IntPoint& b, const IntPoint& c, const IntPoint& q) {
    const int s = perturbed_incircle(a, b, c, q);
    if (s == 0) ++unresolved_ties;
    return s > 0;
  }
};

ExactDelaunayResult triangulate(std::span<const IntPoint> input) {
  ExactDelaunayResult result;
  const size_t n = input.size();
  for (const IntPoint& p : input) {
    if (p.x < -kExactCoordinateLimit || p.x > kExactCoordinateLimit || p.y < -kExactCoordinateLimit || p.y > kExactCoordinateLimit) {
      throw Error(ErrorCode::kInvalidArgument, "exact_delaunay: coordinate beyond 2^30");
    }
  }
  if (n < 3) return result;
  // A super triangle 8x beyond the coordinate limit: far outside every circumcircle of three
  // input points that are not nearly collinear.
  constexpr int64_t kFar = kExactCoordinateLimit * 8;
  std::vector<IntPoint> points(input.begin(), input.end());
  points.push_back({-kFar, -kFar});
  points.push_back({kFar, -kFar});
  points.push_back({0, kFar});
  ExactPredicates predicates;
  bowyer_watson::Triangulation<IntPoint, ExactPredicates> triangulation(points, predicates);

  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::vector<uint64_t> key(n);
  for (size_t i = 0; i < n; ++i) {
    const auto x = static_cast<uint32_t>((points[i].x + kExactCoordinateLimit) >> 15);
    const auto y = static_cast<uint32_t>((points[i].y + kExactCoordinateLimit) >> 15);
    key[i] = bowyer_watson::hilbert_index(x, y);
  }
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
  for (uint32_t i : order) {
    if (!triangulation.insert(static_cast<int32_t>(i))) throw Error(ErrorCode::kInvalidArgument, "exact_delaunay: repeated point");
  }
  result.faces = triangulation.faces();
  result.unresolved_ties = predicates.unresolved_ties;
  return result;
}

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
  if (const int s = lifted_determinant_sign(rel, minor,
                                            [](int64_t x, int64_t y) { return static_cast<Int128>(x) * x + static_cast<Int128>(y) * y; })) {
    return s;
  }
  if (const int s = lifted_determinant_sign(rel, minor, [](int64_t x, int64_t y) { return -static_cast<Int128>(x) * y; })) return s;
  return lifted_determinant_sign(rel, minor, [](int64_t x, int64_t y) { return static_cast<Int128>(x) * x - static_cast<Int128>(y) * y; });
}

ExactDelaunayResult exact_delaunay(std::span<const IntPoint> points) { return triangulate(points); }

}  // namespace facemorph
