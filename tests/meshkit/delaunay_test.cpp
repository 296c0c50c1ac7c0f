#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

void expect_delaunay(const std::vector<Vec2>& points, const std::vector<Face>& faces) {
  for (const Face& f : faces) {
    const Vec2 &a = points[static_cast<size_t>(f[0])], &b = points[static_cast<size_t>(f[1])], &c = points[static_cast<size_t>(f[2])];
    ASSERT_GT(orient2d(a, b, c), 0) << "clockwise or flat triangle";
    for (size_t i = 0; i < points.size(); ++i) {
      if (static_cast<int32_t>(i) == f[0] || static_cast<int32_t>(i) == f[1] || static_cast<int32_t>(i) == f[2]) continue;
      ASSERT_LE(incircle(a, b, c, points[i]), 1e-12) << "point " << i << " inside a circumcircle";
    }
  }
}

TEST(Delaunay, RandomPointsGiveAnEmptyCircleTriangulationOfTheHull) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec2> points;
  while (points.size() < 400) {
    const Vec2 p(u(rng), u(rng));
    if (p.norm() < 0.95) points.push_back(p);
  }
  // Points on the circle: all must be hull vertices, joined by hull edges in order.
  const int rim = 60;
  for (int k = 0; k < rim; ++k) {
    const double a = 2 * std::numbers::pi * k / rim;
    points.emplace_back(std::cos(a), std::sin(a));
  }
  const auto faces = delaunay_triangulation(points);
  expect_delaunay(points, faces);
  const MeshTopology topo(faces, static_cast<int>(points.size()));
  EXPECT_TRUE(topo.is_manifold());
  EXPECT_EQ(topo.euler_characteristic(), 1);
  ASSERT_EQ(topo.boundary_loops().size(), 1u);
  EXPECT_EQ(topo.boundary_loops()[0].size(), static_cast<size_t>(rim));
  EXPECT_EQ(topo.referenced_vertex_count(), static_cast<int>(points.size()));
}

TEST(Delaunay, DuplicatesAreLeftOutAndTinyInputsAreEmpty) {
  std::vector<Vec2> points = {{0, 0}, {1, 0}, {0, 1}, {1, 0}, {1, 1}};
  const auto faces = delaunay_triangulation(points);
  EXPECT_EQ(faces.size(), 2u);
  for (const Face& f : faces) {
    for (int32_t v : f) EXPECT_NE(v, 3);
  }
  EXPECT_TRUE(delaunay_triangulation(std::vector<Vec2>{{0, 0}, {1, 1}}).empty());
}

TEST(Delaunay, LargeJitteredLatticeIsAValidDisk) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::vector<Vec2> points;
  for (int j = 0; j < 300; ++j) {
    for (int i = 0; i < 300; ++i) points.emplace_back(i + jitter(rng), j + jitter(rng));
  }
  const auto faces = delaunay_triangulation(points);
  const MeshTopology topo(faces, static_cast<int>(points.size()));
  EXPECT_TRUE(topo.is_manifold());
  EXPECT_EQ(topo.euler_characteristic(), 1);
  EXPECT_EQ(topo.boundary_loops().size(), 1u);
  double area = 0;
  for (const Face& f : faces)
    area += 0.5 * orient2d(points[static_cast<size_t>(f[0])], points[static_cast<size_t>(f[1])], points[static_cast<size_t>(f[2])]);
  EXPECT_GT(area, 299.0 * 299.0 * 0.98);
}

}  // namespace
}  // namespace facemorph
