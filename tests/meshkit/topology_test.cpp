#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace facemorph {
namespace {

TriangleMesh flat_square(int n) {
  return testing::grid_mesh(n, [](double u, double v) { return Vec3(u, v, 0); });
}

double signed_loop_area(const TriangleMesh& m, const std::vector<int>& loop) {
  double twice = 0;
  for (size_t i = 0; i < loop.size(); ++i) {
    const Vec3& a = m.positions[static_cast<size_t>(loop[i])];
    const Vec3& b = m.positions[static_cast<size_t>(loop[(i + 1) % loop.size()])];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return twice / 2;
}

TEST(Topology, SquareIsADiskWithOneCounterClockwiseBoundary) {
  const TriangleMesh m = flat_square(6);
  const MeshTopology topo(m.faces, m.vertex_count());
  EXPECT_TRUE(topo.is_manifold());
  EXPECT_EQ(topo.euler_characteristic(), 1);
  EXPECT_EQ(topo.component_count(), 1);
  ASSERT_EQ(topo.boundary_loops().size(), 1u);
  EXPECT_EQ(topo.boundary_loops()[0].size(), 24u);
  // The surface lies to the left of each boundary step: counter-clockwise for upward faces.
  EXPECT_NEAR(signed_loop_area(m, topo.boundary_loops()[0]), 1.0, 1e-12);
  EXPECT_EQ(topo.edge_count(), 6 * 7 * 2 + 36);
}

TEST(Topology, SphereIsClosedGenusZero) {
  const TriangleMesh m = testing::icosphere(1.0, 2);
  const MeshTopology topo(m.faces, m.vertex_count());
  EXPECT_TRUE(topo.is_manifold());
  EXPECT_EQ(topo.euler_characteristic(), 2);
  EXPECT_TRUE(topo.boundary_loops().empty());
}

TEST(Topology, AnnulusHasTwoLoopsAndEulerZero) {
  TriangleMesh m = flat_square(4);
  // Remove the 2x2 block of cells in the middle (8 triangles): a hole.
  std::vector<Face> kept;
  for (size_t f = 0; f < m.faces.size(); ++f) {
    const size_t cell = f / 2;
    const size_t i = cell % 4, j = cell / 4;
    if (!(i >= 1 && i <= 2 && j >= 1 && j <= 2)) kept.push_back(m.faces[f]);
  }
  m.faces = kept;
  const MeshTopology topo(m.faces, m.vertex_count());
  EXPECT_TRUE(topo.is_manifold());
  EXPECT_EQ(topo.boundary_loops().size(), 2u);
  EXPECT_EQ(topo.euler_characteristic(), 0);
  // The inner loop runs clockwise (surface on its left is outside the hole).
  double outer = 0, inner = 0;
  for (const auto& loop : topo.boundary_loops()) {
    const double a = signed_loop_area(m, loop);
    (loop.size() == 16 ? outer : inner) = a;
  }
  EXPECT_NEAR(outer, 1.0, 1e-12);
  EXPECT_NEAR(inner, -0.25, 1e-12);
}

TEST(Topology, DetectsNonManifoldEdgesPinchedVerticesAndFlippedFaces) {
  // Three triangles on one edge.
  std::vector<Face> fin = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  MeshTopology t1(fin, 5);
  EXPECT_EQ(t1.non_manifold_edges().size(), 1u);
  EXPECT_FALSE(t1.is_manifold());

  // Two triangles sharing only vertex 0: a bow tie.
  std::vector<Face> bow = {{0, 1, 2}, {0, 3, 4}};
  MeshTopology t2(bow, 5);
  EXPECT_EQ(t2.non_manifold_vertices(), std::vector<int>{0});

  // A face with reversed orientation against its neighbour.
  std::vector<Face> flipped = {{0, 1, 2}, {0, 1, 3}};
  MeshTopology t3(flipped, 4);
  EXPECT_EQ(t3.inconsistently_oriented_edges().size(), 1u);
}

TEST(Topology, CountsComponents) {
  TriangleMesh a = flat_square(2);
  const int offset = a.vertex_count();
  TriangleMesh b = flat_square(2);
  for (const Vec3& p : b.positions) a.positions.push_back(p + Vec3(5, 0, 0));
  for (Face f : b.faces) a.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
  const MeshTopology topo(a.faces, a.vertex_count());
  EXPECT_EQ(topo.component_count(), 2);
  EXPECT_EQ(topo.euler_characteristic(), 2);
}

// What the cache gives is the topology a fresh build gives for the mesh asked about: the same
// mesh asked again reuses it; an edit that keeps the counts (a face reversed, a vertex added) and
// one that does not each get a fresh build.
TEST(TopologyCache, GivesTheMeshesOwnTopologyAndRebuildsOnlyAfterAnEdit) {
  TriangleMesh m = flat_square(4);
  TopologyCache cache;
  const MeshTopology* first = &cache.of(m);
  EXPECT_EQ(&cache.of(m), first);
  EXPECT_EQ(cache.builds(), 1);
  const MeshTopology fresh(m.faces, m.vertex_count());
  EXPECT_EQ(cache.of(m).edge_count(), fresh.edge_count());
  EXPECT_EQ(cache.of(m).boundary_loops(), fresh.boundary_loops());

  std::swap(m.faces[3][1], m.faces[3][2]);  // same counts, one face reversed
  EXPECT_EQ(cache.of(m).inconsistently_oriented_edges().size(), MeshTopology(m.faces, m.vertex_count()).inconsistently_oriented_edges().size());
  EXPECT_FALSE(cache.of(m).inconsistently_oriented_edges().empty());
  EXPECT_EQ(cache.builds(), 2);

  m.positions.push_back(Vec3(9, 9, 0));  // same faces over one more vertex
  EXPECT_EQ(cache.of(m).vertex_count(), m.vertex_count());
  EXPECT_EQ(cache.builds(), 3);

  m.faces.pop_back();
  EXPECT_EQ(cache.of(m).face_count(), static_cast<int>(m.faces.size()));
  EXPECT_EQ(cache.of(m).boundary_loops(), MeshTopology(m.faces, m.vertex_count()).boundary_loops());
  EXPECT_EQ(cache.builds(), 4);
}

}  // namespace
}  // namespace facemorph
