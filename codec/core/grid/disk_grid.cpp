// The shared disk grid G, built by the exact rule of spec/method.md §4: integer arithmetic only,
// so every platform builds the same nodes and faces (and the same hash).
#include "codec/core/grid/disk_grid.hpp"

#include "format/error.hpp"

#include "codec/core/geometry/exact_delaunay.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <numbers>

namespace facemorph {

namespace {

__extension__ typedef __int128 Int128;

// Fixed point with 62 fraction bits: the rim's trigonometry is integer arithmetic, defined to
// the bit (spec/method.md §4), not whatever a platform's libm rounds to.
constexpr int kFractionBits = 62;
constexpr Int128 kOne = Int128{1} << kFractionBits;
constexpr Int128 kPi = static_cast<Int128>(0xC90FDAA22168C234ull);  // floor(π · 2^62)

// cos x and sin x for 0 <= x <= π/4 (x in Q62) by their Taylor series, each term truncated
// towards zero, summed until a term vanishes.
std::pair<Int128, Int128> cos_sin_q62(Int128 x) {
  Int128 cos_sum = 0, sin_sum = 0;
  Int128 term = kOne;  // x^k / k!, for k = 0, 1, 2, ...
  for (int k = 0; term != 0; ++k) {
    const bool negative = (k / 2) % 2 == 1;  // signs + + - - + + ...: cos 1 − x²/2 + ..., sin x − x³/6 + ...
    Int128& sum = k % 2 == 0 ? cos_sum : sin_sum;
    sum += negative ? -term : term;
    term = ((term * x) >> kFractionBits) / (k + 1);
  }
  return {cos_sum, sin_sum};
}

// (cos, sin) of 2π k / B in Q62: reduced by integer arithmetic to an angle in [0, π/4].
std::pair<Int128, Int128> unit_circle_point(int k, int b) {
  const int64_t quarter = 4 * static_cast<int64_t>(k) / b;      // quadrant
  const int64_t r = 4 * static_cast<int64_t>(k) - quarter * b;  // angle (π/2) r / B within it
  const bool mirrored = 2 * r > b;                              // past π/4: use π/2 − angle
  const int64_t numerator = mirrored ? b - r : r;
  const Int128 x = kPi * numerator / (2 * static_cast<Int128>(b));  // (π/2) numerator / B
  auto [c, s] = cos_sin_q62(x);
  if (mirrored) std::swap(c, s);
  switch (quarter) {
    case 0: return {c, s};
    case 1: return {-s, c};
    case 2: return {-c, -s};
    default: return {s, -c};
  }
}

// round(v / 2^62) with ties upwards: the rim's lattice coordinate.
int64_t round_q62(Int128 v) { return static_cast<int64_t>((v + (kOne >> 1)) >> kFractionBits); }

// FNV-1a, 64 bits, over little-endian integers.
class Fnv1a {
 public:
  template <typename T>
  void add(T value) {
    auto bits = static_cast<uint64_t>(value);
    for (size_t i = 0; i < sizeof(T); ++i) {
      hash_ ^= (bits >> (8 * i)) & 0xff;
      hash_ *= 0x100000001b3ull;
    }
  }
  uint64_t value() const { return hash_; }

 private:
  uint64_t hash_ = 0xcbf29ce484222325ull;
};

int rim_count_for(int m) { return std::max(8, static_cast<int>(round_q62(kPi * m))); }

// Integer square root: the largest r with r² <= v.
int64_t isqrt(int64_t v) {
  auto r = static_cast<int64_t>(std::sqrt(static_cast<double>(v)));
  while (r * r > v) --r;
  while ((r + 1) * (r + 1) <= v) ++r;
  return r;
}

void require_size(int n) {
  if (n < kMinGridSize || n > kMaxGridSize) {
    throw Error(ErrorCode::kInvalidArgument, "grid size N must be in [" + std::to_string(kMinGridSize) + ", " +
                                                 std::to_string(kMaxGridSize) + "], got " + std::to_string(n));
  }
}

// Checks, exactly, that the band faces fill the band: every band face counter-clockwise, every
// directed edge used once, the unpaired edges exactly the rim polygon's and the squares' boundary
// (reversed), and the band's area the polygon's less the squares'. With the squares (a valid
// triangulation by construction) that makes G a triangulation of the rim polygon.
void validate_band(const DiskGrid& grid, const std::vector<IntPoint>& lattice, const std::vector<Face>& band_faces,
                   const std::vector<std::pair<int32_t, int32_t>>& square_boundary, Int128 squares_twice_area) {
  auto fail = [&](const std::string& why) {
    throw Error(ErrorCode::kNumerical,
                "disk grid N = " + std::to_string(grid.n) + ": " + why + " (please report: the rule of spec/method.md §4 failed)");
  };
  Int128 twice_area = squares_twice_area;
  std::map<std::pair<int32_t, int32_t>, int> directed;
  for (const Face& f : band_faces) {
    const IntPoint &a = lattice[static_cast<size_t>(f[0])], &b = lattice[static_cast<size_t>(f[1])],
                   &c = lattice[static_cast<size_t>(f[2])];
    if (exact_orientation(a, b, c) <= 0) fail("a face is not counter-clockwise");
    twice_area += static_cast<Int128>(b.x - a.x) * (c.y - a.y) - static_cast<Int128>(b.y - a.y) * (c.x - a.x);
    for (int k = 0; k < 3; ++k) {
      if (++directed[{f[static_cast<size_t>(k)], f[static_cast<size_t>((k + 1) % 3)]}] > 1) fail("an edge is used twice in one direction");
    }
  }
  std::vector<std::pair<int32_t, int32_t>> expected;
  Int128 polygon = 0;
  for (int k = 0; k < grid.rim_count; ++k) {
    const int32_t u = grid.interior_count + k, v = grid.interior_count + (k + 1) % grid.rim_count;
    const IntPoint &a = lattice[static_cast<size_t>(u)], &b = lattice[static_cast<size_t>(v)];
    polygon += static_cast<Int128>(a.x) * b.y - static_cast<Int128>(a.y) * b.x;
    expected.emplace_back(u, v);
  }
  for (const auto& [u, v] : square_boundary) expected.emplace_back(v, u);
  std::vector<std::pair<int32_t, int32_t>> unpaired;
  for (const auto& [edge, count] : directed) {
    if (!directed.count({edge.second, edge.first})) unpaired.push_back(edge);
  }
  std::sort(expected.begin(), expected.end());
  if (unpaired != expected) fail("the band's boundary is not the rim and the squares' boundary");
  if (polygon != twice_area) fail("the faces do not cover the rim polygon exactly once");
}

}  // namespace

double DiskGrid::rim_angle(int k) const { return 2 * std::numbers::pi * k / rim_count; }

DiskGridShape disk_grid_shape(int n) {
  require_size(n);
  const int64_t m = n - 1;
  DiskGridShape shape;
  for (int64_t j = 0; j < n; ++j) {
    const int64_t b = 2 * j - m, room = (m - 1) * (m - 1) - b * b;
    if (room < 0) continue;
    // |2i − M| <= isqrt(room), with 2i − M of M's parity.
    const int64_t reach = isqrt(room);
    const int64_t lo = (m - reach + 1) / 2, hi = (m + reach) / 2;  // ceil((M − r)/2), floor((M + r)/2)
    shape.interior_count += static_cast<int>(hi - lo + 1);
  }
  shape.rim_count = rim_count_for(static_cast<int>(m));
  return shape;
}

DiskGrid make_disk_grid(int n) {
  require_size(n);
  DiskGrid grid;
  grid.n = n;
  const int64_t m = n - 1;
  const int64_t q = (int64_t{1} << 30) / m;  // lattice units per 1/M: rim coordinates <= 2^30
  grid.h = 2.0 / static_cast<double>(m);
  grid.node_at.assign(static_cast<size_t>(n) * static_cast<size_t>(n), -1);
  std::vector<IntPoint> lattice;  // every node in units of 1 / (Q M)
  const int64_t limit = (m - 1) * (m - 1);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int64_t a = 2 * i - m, b = 2 * j - m;
      if (a * a + b * b > limit) continue;
      grid.node_at[static_cast<size_t>(j) * static_cast<size_t>(n) + static_cast<size_t>(i)] = static_cast<int32_t>(grid.nodes.size());
      grid.nodes.emplace_back(static_cast<double>(a) / static_cast<double>(m), static_cast<double>(b) / static_cast<double>(m));
      grid.cell.push_back({i, j});
      lattice.push_back({a * q, b * q});
    }
  }
  grid.interior_count = static_cast<int>(grid.nodes.size());
  grid.rim_count = rim_count_for(static_cast<int>(m));
  const double scale = static_cast<double>(q * m);
  for (int k = 0; k < grid.rim_count; ++k) {
    const auto [c, s] = unit_circle_point(k, grid.rim_count);
    const IntPoint p{round_q62(c * (q * m)), round_q62(s * (q * m))};
    lattice.push_back(p);
    grid.nodes.emplace_back(static_cast<double>(p.x) / scale, static_cast<double>(p.y) / scale);
  }

  // Squares with four interior corners: split along the (i, j)-(i + 1, j + 1) diagonal.
  auto full = [&](int i, int j) {
    return grid.node(i, j) >= 0 && grid.node(i + 1, j) >= 0 && grid.node(i, j + 1) >= 0 && grid.node(i + 1, j + 1) >= 0;
  };
  std::vector<Face> square_faces;
  std::vector<std::pair<int32_t, int32_t>> square_boundary;  // the squares' union boundary, counter-clockwise
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      if (!full(i, j)) continue;
      const int32_t a = grid.node(i, j), b = grid.node(i + 1, j), c = grid.node(i + 1, j + 1), d = grid.node(i, j + 1);
      square_faces.push_back({a, b, c});
      square_faces.push_back({a, c, d});
      if (j == 0 || !full(i, j - 1)) square_boundary.emplace_back(a, b);
      if (i + 2 >= n || !full(i + 1, j)) square_boundary.emplace_back(b, c);
      if (j + 2 >= n || !full(i, j + 1)) square_boundary.emplace_back(c, d);
      if (i == 0 || !full(i - 1, j)) square_boundary.emplace_back(d, a);
    }
  }
  const Int128 squares_twice_area = static_cast<Int128>(square_faces.size()) * 4 * q * q;  // each half of a (2Q)² square
  // The band between the squares and the rim: the Delaunay triangulation of the rim nodes and the
  // interior nodes within six cells of the circle, keeping the faces outside the full squares (a
  // face whose centroid lies in a full square belongs to the squares). The global Delaunay
  // triangulation contains the squares, so this is its band (tests/decoder/grid_test.cpp checks).
  std::vector<int32_t> band;
  const int64_t deep = std::max<int64_t>(0, m - 1 - 12);
  for (int32_t v = 0; v < grid.interior_count; ++v) {
    const IntPoint& p = lattice[static_cast<size_t>(v)];
    if ((p.x / q) * (p.x / q) + (p.y / q) * (p.y / q) >= deep * deep) band.push_back(v);
  }
  for (int k = 0; k < grid.rim_count; ++k) band.push_back(grid.interior_count + k);
  std::vector<IntPoint> band_points;
  for (int32_t v : band) band_points.push_back(lattice[static_cast<size_t>(v)]);
  const ExactDelaunayResult delaunay = exact_delaunay(band_points);
  std::vector<Face> band_faces;
  if (delaunay.unresolved_ties > 0) {
    throw Error(ErrorCode::kNumerical,
                "disk grid N = " + std::to_string(n) + ": a cocircularity the perturbation does not break (please report)");
  }
  for (const Face& f : delaunay.faces) {
    int64_t sx = 0, sy = 0;
    for (int32_t v : f) {
      sx += band_points[static_cast<size_t>(v)].x;
      sy += band_points[static_cast<size_t>(v)].y;
    }
    // The centroid's cell: cell i spans x in [(2i − M) Q, (2i + 2 − M) Q].
    const int64_t ci = (sx + 3 * q * m) / (6 * q), cj = (sy + 3 * q * m) / (6 * q);
    if (ci >= 0 && cj >= 0 && ci + 1 < n && cj + 1 < n && full(static_cast<int>(ci), static_cast<int>(cj))) continue;
    band_faces.push_back({band[static_cast<size_t>(f[0])], band[static_cast<size_t>(f[1])], band[static_cast<size_t>(f[2])]});
  }
  validate_band(grid, lattice, band_faces, square_boundary, squares_twice_area);

  // Canonical order: each face starts at its smallest index (rotation keeps it counter-clockwise),
  // then the faces sorted. The squares come out of the row-major loop in that order already.
  for (Face& f : band_faces) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
  std::sort(band_faces.begin(), band_faces.end());
  grid.faces.resize(square_faces.size() + band_faces.size());
  std::merge(square_faces.begin(), square_faces.end(), band_faces.begin(), band_faces.end(), grid.faces.begin());

  Fnv1a hash;
  hash.add(static_cast<int32_t>(n));
  hash.add(static_cast<int32_t>(grid.rim_count));
  hash.add(static_cast<int32_t>(grid.node_count()));
  hash.add(static_cast<int32_t>(grid.faces.size()));
  for (const IntPoint& p : lattice) {
    hash.add(p.x);
    hash.add(p.y);
  }
  for (const Face& f : grid.faces) {
    for (int32_t v : f) hash.add(v);
  }
  grid.hash = hash.value();
  return grid;
}

uint64_t known_disk_grid_hash(int n) {
  static constexpr uint64_t kHashes[] = {
#include "codec/core/grid/disk_grid_hashes.inc"
  };
  static_assert(std::size(kHashes) == kKnownGridHashes - kMinGridSize + 1);
  return n >= kMinGridSize && n <= kKnownGridHashes ? kHashes[n - kMinGridSize] : 0;
}

}  // namespace facemorph
