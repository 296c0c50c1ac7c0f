#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/exact_delaunay.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

namespace facemorph {
namespace {

using testing::kPi;

// The nodes of G on its integer lattice (spec/method.md §4): units of 1 / (Q M), Q = floor(2^30 / M).
std::vector<IntPoint> lattice_of(const DiskGrid& g) {
  const int64_t m = g.n - 1, q = (int64_t{1} << 30) / m;
  std::vector<IntPoint> out;
  for (const Vec2& w : g.nodes)
    out.push_back({std::llround(w.x() * static_cast<double>(q * m)), std::llround(w.y() * static_cast<double>(q * m))});
  return out;
}

std::vector<Face> canonical(std::vector<Face> faces) {
  for (Face& f : faces) std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
  std::sort(faces.begin(), faces.end());
  return faces;
}

TEST(DiskGrid, IsACartesianInteriorWithARimOnTheCircleAndNoSlivers) {
  for (int n : {5, 17, 64, 65, 257}) {
    const DiskGrid g = make_disk_grid(n);
    const int m = n - 1;
    EXPECT_DOUBLE_EQ(g.h, 2.0 / m);
    EXPECT_EQ(g.rim_count, std::max(8, static_cast<int>(std::lround(kPi * m))));
    int expected_interior = 0;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const Vec2 w(static_cast<double>(2 * i - m) / m, static_cast<double>(2 * j - m) / m);
        const int32_t node = g.node(i, j);
        if (w.norm() <= 1 - 0.5 * g.h + 1e-12) {
          ++expected_interior;
          ASSERT_GE(node, 0);
          EXPECT_EQ(g.nodes[static_cast<size_t>(node)], w);
        } else {
          EXPECT_EQ(node, -1);
        }
      }
    }
    EXPECT_EQ(g.interior_count, expected_interior);
    const DiskGridShape shape = disk_grid_shape(n);
    EXPECT_EQ(shape.interior_count, g.interior_count);
    EXPECT_EQ(shape.rim_count, g.rim_count);
    // Rim nodes: on the circle at 2π k / B, to the lattice's rounding (1 / (2 Q M) < 1e-8).
    for (int k = 0; k < g.rim_count; ++k) {
      const Vec2& w = g.nodes[static_cast<size_t>(g.interior_count + k)];
      EXPECT_LT((w - Vec2(std::cos(g.rim_angle(k)), std::sin(g.rim_angle(k)))).norm(), 1e-8);
    }
    const MeshTopology topology(g.faces, g.node_count());
    EXPECT_TRUE(topology.is_manifold());
    EXPECT_EQ(topology.euler_characteristic(), 1);
    ASSERT_EQ(topology.boundary_loops().size(), 1u);
    EXPECT_EQ(topology.boundary_loops()[0].size(), static_cast<size_t>(g.rim_count));
    std::vector<Vec3> lifted;
    for (const Vec2& w : g.nodes) lifted.emplace_back(w.x(), w.y(), 0);
    double min_angle = kPi, area = 0;
    for (const auto& a : corner_angles(lifted, g.faces)) min_angle = std::min({min_angle, a[0], a[1], a[2]});
    for (const Face& f : g.faces) {
      const Vec2 &a = g.nodes[static_cast<size_t>(f[0])], &b = g.nodes[static_cast<size_t>(f[1])], &c = g.nodes[static_cast<size_t>(f[2])];
      const double twice = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
      EXPECT_GT(twice, 0);
      area += twice / 2;
    }
    EXPECT_GT(min_angle * 180 / kPi, 20.0) << "N = " << n;                         // no slivers at the rim
    EXPECT_NEAR(area, g.rim_count / 2.0 * std::sin(2 * kPi / g.rim_count), 1e-8);  // the rim polygon's area
    EXPECT_EQ(g.faces, canonical(g.faces)) << "faces are stored in the canonical order";
  }
  testing::expect_error(ErrorCode::kInvalidArgument, "grid size N", [] { make_disk_grid(4); });
  testing::expect_error(ErrorCode::kInvalidArgument, "grid size N", [] { make_disk_grid(kMaxGridSize + 1); });
}

TEST(DiskGrid, EveryFullSquareIsSplitAlongItsRisingDiagonal) {
  const DiskGrid g = make_disk_grid(33);
  std::set<Face> faces(g.faces.begin(), g.faces.end());
  int squares = 0;
  for (int j = 0; j + 1 < g.n; ++j) {
    for (int i = 0; i + 1 < g.n; ++i) {
      const int32_t a = g.node(i, j), b = g.node(i + 1, j), c = g.node(i + 1, j + 1), d = g.node(i, j + 1);
      if (a < 0 || b < 0 || c < 0 || d < 0) continue;
      ++squares;
      EXPECT_TRUE(faces.count(canonical({{a, b, c}})[0])) << i << ", " << j;
      EXPECT_TRUE(faces.count(canonical({{a, c, d}})[0])) << i << ", " << j;
    }
  }
  EXPECT_GT(squares, 600);
}

TEST(DiskGrid, IsTheDelaunayTriangulationOfAllItsNodes) {
  // The rule (spec/method.md §4) defines G as the perturbed Delaunay triangulation of every node;
  // the construction builds the squares directly and triangulates only the band. Same faces.
  std::vector<int> sizes;
  for (int n = 5; n <= 48; ++n) sizes.push_back(n);
  for (int n : {64, 65, 100, 129, 200}) sizes.push_back(n);
  for (int n : sizes) {
    const DiskGrid g = make_disk_grid(n);
    const ExactDelaunayResult all = exact_delaunay(lattice_of(g));
    EXPECT_EQ(all.unresolved_ties, 0) << "N = " << n;
    EXPECT_EQ(canonical(all.faces), g.faces) << "N = " << n;
  }
}

TEST(DiskGrid, GoldenHashesPinTheRule) {
  // Rule version 1. A change here changes every file's grid: bump kDiskGridRule and the container.
  EXPECT_EQ(kDiskGridRule, 1);
  const std::vector<std::pair<int, uint64_t>> golden = {
      {5, 0x71cee6c240c2fc1dull},   {17, 0xfbb75c4a2a1f2954ull},  {128, 0x5bcb25810177f96cull},
      {256, 0xb88650da7236a7cdull}, {257, 0x098b41b44d2d4c90ull}, {512, 0x019c2b6f0768b74cull},
  };
  for (const auto& [n, hash] : golden) EXPECT_EQ(make_disk_grid(n).hash, hash) << "N = " << n;
}

// The table a header's hash is checked against (codec/grid/disk_grid_hashes.inc) is the rule's own:
// every N to 129, --grid auto's rungs past it (161, 193, 225: files are written at them), and a
// sample of the larger ones. (The whole table takes 40 s.)
TEST(DiskGrid, KnownHashesAreTheGridsOwn) {
  for (int n = kMinGridSize; n <= 129; ++n) EXPECT_EQ(known_disk_grid_hash(n), make_disk_grid(n).hash) << "N = " << n;
  for (int n : {160, 161, 193, 200, 225, 256, 257, 321, 513, 1024, kKnownGridHashes})
    EXPECT_EQ(known_disk_grid_hash(n), make_disk_grid(n).hash) << "N = " << n;
  EXPECT_EQ(known_disk_grid_hash(kKnownGridHashes + 1), 0u);
  EXPECT_EQ(known_disk_grid_hash(kMinGridSize - 1), 0u);
}

TEST(ExactPredicates, DecideTiesByThePerturbationAndHugeValuesExactly) {
  // The unit square is cocircular: x² + y² ties, −ε x y picks the (0,0)-(1,1) diagonal.
  const IntPoint a{0, 0}, b{1, 0}, c{1, 1}, d{0, 1};
  EXPECT_EQ(perturbed_incircle(a, b, c, d), -1);  // d outside (a, b, c): diagonal a-c is Delaunay
  EXPECT_EQ(perturbed_incircle(b, d, a, c), 1);   // c inside (b, d, a): diagonal b-d is not
  EXPECT_EQ(exact_orientation(a, b, c), 1);
  EXPECT_EQ(exact_orientation(a, c, b), -1);
  EXPECT_EQ(exact_orientation(a, c, {5, 5}), 0);
  // Near the limits, a point one unit inside or outside a huge circle: exact, not rounded.
  const int64_t r = int64_t{1} << 30;
  const IntPoint p{-r, 0}, s{r, 0}, t{0, r};
  EXPECT_EQ(perturbed_incircle(p, s, t, {0, -r + 1}), 1);
  EXPECT_EQ(perturbed_incircle(p, s, t, {0, -r - 1}), -1);
  // A long double cannot tell these apart: 3 points on x² + y² = 5⁴·... (a Pythagorean circle).
  const int64_t k = int64_t{1} << 28;
  const IntPoint u{5 * k, 0}, v{3 * k, 4 * k}, w{-4 * k, 3 * k};
  EXPECT_NE(perturbed_incircle(u, v, w, {4 * k, -3 * k}), 0);  // cocircular: the perturbation decides
  EXPECT_EQ(perturbed_incircle(u, v, w, {4 * k, -3 * k + 1}), 1);
  EXPECT_EQ(perturbed_incircle(u, v, w, {4 * k, -3 * k - 1}), -1);
}

}  // namespace
}  // namespace facemorph
