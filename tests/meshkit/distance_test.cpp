#include "codec/meshkit/geometry/distance.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace facemorph {
namespace {

double brute_force(const TriangleMesh& mesh, const Vec3& p) {
  double best = 1e300;
  for (const Face& f : mesh.faces) {
    // Dense sampling is not exact; use the closest-point formula through a one-face mesh.
    TriangleMesh one;
    one.positions = {mesh.positions[static_cast<size_t>(f[0])], mesh.positions[static_cast<size_t>(f[1])],
                     mesh.positions[static_cast<size_t>(f[2])]};
    one.faces = {{0, 1, 2}};
    best = std::min(best, PointToMesh(one).distance(p));
  }
  return best;
}

// An icosphere and the same with every face twice (exact ties everywhere, the copy the higher index).
std::pair<TriangleMesh, TriangleMesh> sphere_and_doubled() {
  TriangleMesh sphere = testing::icosphere(1.0, 3);
  TriangleMesh doubled = sphere;
  doubled.faces.insert(doubled.faces.end(), sphere.faces.begin(), sphere.faces.end());
  return {sphere, doubled};
}

// Query i of a search test: a vertex of the mesh (ties between the faces around it), a point near
// one, or one far off the surface, in turn.
Vec3 probe(const TriangleMesh& mesh, int i, std::mt19937& rng) {
  std::normal_distribution<double> jitter(0, 0.01);
  std::uniform_real_distribution<double> far(-3, 3);
  const Vec3& vertex = mesh.positions[static_cast<size_t>(i) % mesh.positions.size()];
  if (i % 3 == 0) return vertex;
  if (i % 3 == 1) return vertex + Vec3(jitter(rng), jitter(rng), jitter(rng));
  return Vec3(far(rng), far(rng), far(rng));
}

TEST(Distance, BucketSearchMatchesBruteForceInsideAndFarOutside) {
  const TriangleMesh sphere = testing::icosphere(1.0, 2);
  const PointToMesh query(sphere);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int i = 0; i < 300; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    EXPECT_NEAR(query.distance(p), brute_force(sphere, p), 1e-12);
  }
  EXPECT_NEAR(query.distance(Vec3(0, 0, 10)), 9.0, 0.01);
}

// A bounded query: the distance where it is under the bound, something at least the bound where it
// is not, and it stops early (a search that ignored the bound would pass the first check, one that
// stopped too soon the second).
TEST(Distance, ABoundedQueryIsExactUnderItsBoundAndAtLeastItBeyond) {
  const TriangleMesh sphere = testing::icosphere(1.0, 3);
  const PointToMesh query(sphere);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-4, 4), bound(0, 3);
  int under = 0, beyond = 0;
  for (int i = 0; i < 400; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    const double b = bound(rng), exact = query.distance(p), bounded = query.distance_below(p, b);
    if (exact < b) {
      EXPECT_EQ(bounded, exact) << i;
      ++under;
    } else {
      EXPECT_GE(bounded, b) << i;
      ++beyond;
    }
  }
  EXPECT_GT(under, 50);
  EXPECT_GT(beyond, 50);
  EXPECT_EQ(query.distance_below(Vec3(0, 0, 10), std::numeric_limits<double>::infinity()), query.distance(Vec3(0, 0, 10)));
  // At the centre, a bound under the radius ends the search in the empty cells around it: nothing
  // found there. Above the radius it finds the surface.
  EXPECT_EQ(query.distance_below(Vec3::Zero(), 0.3), std::numeric_limits<double>::infinity());
  EXPECT_EQ(query.distance_below(Vec3::Zero(), 2.0), query.distance(Vec3::Zero()));
}

TEST(Distance, ClosestPointIsTheNearestFaceWithItsBarycentrics) {
  const TriangleMesh sphere = testing::icosphere(1.0, 2);
  const PointToMesh query(sphere);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int i = 0; i < 300; ++i) {
    const Vec3 p(u(rng), u(rng), u(rng));
    const SurfacePoint c = query.closest(p);
    ASSERT_GE(c.face, 0);
    EXPECT_NEAR(c.bary.sum(), 1.0, 1e-12);
    EXPECT_GE(c.bary.minCoeff(), -1e-12);
    const Face& f = sphere.faces[static_cast<size_t>(c.face)];
    const Vec3 x = c.bary[0] * sphere.positions[static_cast<size_t>(f[0])] + c.bary[1] * sphere.positions[static_cast<size_t>(f[1])] +
                   c.bary[2] * sphere.positions[static_cast<size_t>(f[2])];
    EXPECT_NEAR((x - p).norm(), brute_force(sphere, p), 1e-12);
  }
  // A vertex shared by several faces: the lowest face index wins, whatever bucket is searched first.
  const Vec3 vertex = sphere.positions[5];
  int lowest = -1;
  for (size_t f = 0; f < sphere.faces.size() && lowest < 0; ++f) {
    for (int32_t v : sphere.faces[f]) lowest = v == 5 ? static_cast<int>(f) : lowest;
  }
  EXPECT_EQ(query.closest(1.5 * vertex).face, lowest);
  EXPECT_EQ(PointToMesh(TriangleMesh{}).closest(vertex).face, -1);
}

// The search skips a cell or face whose box is farther than the nearest face found so far: what it
// returns must be, to the bit, what a scan of every face returns (the smallest squared distance as
// closest_point_barycentric computes it, of equal ones the lowest index), for points near the surface
// (where the skips cut most), on it (at vertices: ties between the faces around one), far off it,
// and on a mesh whose faces all come twice (exact ties everywhere), with and without a face to start
// from. A skip rule that dropped a face as near as the best (without the slack, or a box measured
// from the wrong corner) fails here.
TEST(Distance, TheSearchsSkipsReturnWhatAScanOfEveryFaceReturnsToTheBit) {
  const auto [sphere, doubled] = sphere_and_doubled();
  std::mt19937 rng(11);
  for (const TriangleMesh* mesh : {&sphere, &doubled}) {
    const PointToMesh query(*mesh);
    const auto scan = [&](const Vec3& p, double& best) {
      SurfacePoint point;
      best = std::numeric_limits<double>::infinity();
      for (size_t f = 0; f < mesh->faces.size(); ++f) {
        const Vec3& a = mesh->positions[static_cast<size_t>(mesh->faces[f][0])];
        const Vec3& b = mesh->positions[static_cast<size_t>(mesh->faces[f][1])];
        const Vec3& c = mesh->positions[static_cast<size_t>(mesh->faces[f][2])];
        const Vec3 bary = closest_point_barycentric(p, a, b, c);
        const double squared = (bary[0] * a + bary[1] * b + bary[2] * c - p).squaredNorm();
        if (squared < best) best = squared, point = {static_cast<int>(f), bary};
      }
      return point;
    };
    int ties = 0;
    std::uniform_int_distribution<int> any_face(0, static_cast<int>(mesh->faces.size()) - 1);
    for (int i = 0; i < 600; ++i) {
      const Vec3 p = probe(*mesh, i, rng);
      double expected = 0, squared = 0;
      const SurfacePoint want = scan(p, expected);
      const SurfacePoint got = query.closest_squared(p, squared);
      ASSERT_EQ(got.face, want.face) << i;
      EXPECT_EQ(got.bary, want.bary) << i;
      EXPECT_EQ(squared, expected) << i;
      ties += i % 3 == 0;
      // Started from a hint (closest_from): the nearest itself, a tie of a higher index (the doubled
      // mesh's copy), any face, or none: the same answer. A hint kept where a lower face ties it, or
      // whose distance were taken as a bound below the nearest, fails here.
      const int copy = mesh == &doubled ? (want.face + static_cast<int>(sphere.faces.size())) % static_cast<int>(mesh->faces.size()) : want.face;
      for (const int hint : {want.face, copy, any_face(rng), -1}) {
        double distance = 0;
        const SurfacePoint from = query.closest_from(p, hint, &distance);
        ASSERT_EQ(from.face, want.face) << i << " hint " << hint;
        EXPECT_EQ(from.bary, want.bary) << i << " hint " << hint;
        EXPECT_EQ(distance, std::sqrt(expected)) << i << " hint " << hint;
        double hinted = 0;
        EXPECT_EQ(query.closest_squared(p, hinted, nullptr, std::numeric_limits<double>::infinity(), hint).face, want.face) << i;
        EXPECT_EQ(hinted, expected) << i;
      }
    }
    EXPECT_GT(ties, 100);
  }
}

// closest_squared with a bound measures no box past it (its search starts there): just above the
// nearest distance (as the patch measure's searches bound theirs, 1e-9 past a distance already
// found) it still returns, to the bit, what an unbounded search returns, ties included (the doubled
// mesh); just below it, nothing nearer than the bound. A limit set at the bound without the slack,
// or short of it, loses the nearest here.
TEST(Distance, ABoundedClosestSquaredFindsTheNearestJustUnderItsBound) {
  const auto [sphere, doubled] = sphere_and_doubled();
  std::mt19937 rng(13);
  for (const TriangleMesh* mesh : {&sphere, &doubled}) {
    const PointToMesh query(*mesh);
    int found = 0;
    for (int i = 0; i < 600; ++i) {
      const Vec3 p = probe(*mesh, i, rng);
      double expected = 0;
      const SurfacePoint want = query.closest_squared(p, expected);
      const double distance = std::sqrt(expected);
      double squared = 0;
      const SurfacePoint got = query.closest_squared(p, squared, nullptr, distance * (1 + 1e-9) + 1e-300);
      ASSERT_EQ(got.face, want.face) << i;
      EXPECT_EQ(got.bary, want.bary) << i;
      EXPECT_EQ(squared, expected) << i;
      found += got.face >= 0;
      double below = 0;
      const SurfacePoint none = query.closest_squared(p, below, nullptr, distance * (1 - 1e-6));
      EXPECT_GE(below, distance * (1 - 1e-6) * distance * (1 - 1e-6)) << i;
      if (none.face >= 0) {
        EXPECT_GE(below, expected) << i;
      }
    }
    EXPECT_EQ(found, 600);
  }
}

// Two faces equally near p, the lower index only in the next shell of the bucket search, at
// exactly that shell's reach: the tie rule (the lowest index wins, as a scan over every face gives)
// must still hold, so the search stops only once the best is strictly within the reach. Faces 1 and
// 3 are both 0.25 from p; stopping at "within or at the reach" returned face 3.
TEST(Distance, ATieAtAShellsReachStillGoesToTheLowestFaceIndex) {
  const double corners[10][3][3] = {
      {{0, 0.5, 1}, {0.5, 0, 0}, {0.5, 0.5, 0.5}},    {{0, 0.5, 1}, {0.5, 0.5, 0.5}, {0, 0.5, 0.5}},
      {{0.5, 0, 0}, {1, 0, 0}, {0.5, 0.5, -1}},       {{0.5, 0, 0}, {0.5, 0.5, -1}, {0.5, 0.5, 0.5}},
      {{1, 0, 0}, {1.5, 0, 1}, {0.5, 0.5, -1}},       {{1.5, 0, 1}, {1.5, 0.5, 1}, {0.5, 0.5, -1}},
      {{0.5, 0.5, 0.5}, {0.5, 0.5, -1}, {0.5, 1, 1}}, {{0.5, 0.5, -1}, {1, 1, 0.5}, {0.5, 1, 1}},
      {{0.5, 0.5, -1}, {1.5, 0.5, 1}, {1.5, 1, 1}},   {{0.5, 0.5, -1}, {1.5, 1, 1}, {1, 1, 0.5}}};
  TriangleMesh mesh;
  for (const auto& triangle : corners) {
    Face f;
    for (size_t k = 0; k < 3; ++k) {
      f[k] = static_cast<int32_t>(mesh.positions.size());
      mesh.positions.push_back(Vec3(triangle[k][0], triangle[k][1], triangle[k][2]));
    }
    mesh.faces.push_back(f);
  }
  const Vec3 p(0.25, 0.5, 0.25);
  double distance = 0;
  const SurfacePoint nearest = PointToMesh(mesh).closest(p, &distance);
  EXPECT_EQ(distance, 0.25);
  EXPECT_EQ(nearest.face, 1);
}

// A collapsed triangle (vertices on one line, two or three of them one point) has no face region:
// its nearest point is that of its longest edge, whichever vertex lies between, with finite
// coordinates that sum to 1 and put the point there. Ericson's face region divides by the squared
// area, 0 here: without the collapsed case the coordinates were NaN or a point of the wrong edge.
TEST(Distance, ACollapsedTriangleIsItsLongestEdge) {
  struct Case {
    Vec3 a, b, c, p, nearest;
  };
  const Case cases[] = {
      {{0, 0, 0}, {2, 0, 0}, {1, 0, 0}, {1.5, 1, 0}, {1.5, 0, 0}},  // c between a and b: edge ab
      {{0, 0, 0}, {1, 0, 0}, {3, 0, 0}, {2.5, 1, 0}, {2.5, 0, 0}},  // b between: edge ac, beyond ab
      {{1, 0, 0}, {0, 0, 0}, {3, 0, 0}, {2, -1, 2}, {2, 0, 0}},     // a between: edge bc
      {{0, 0, 0}, {0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, 0, 0}},  // a and b one point
      {{0, 0, 0}, {1, 0, 0}, {3, 0, 0}, {-1, 1, 0}, {0, 0, 0}},     // beyond the segment's end
      {{1, 2, 3}, {1, 2, 3}, {1, 2, 3}, {0, 0, 0}, {1, 2, 3}},      // one point
      {{0, 0, 0}, {4, 4, 0}, {1, 1, 1e-14}, {3, 1, 0}, {2, 2, 0}},  // all but collinear (sine ~1e-14)
  };
  for (size_t i = 0; i < std::size(cases); ++i) {
    const Case& k = cases[i];
    const Vec3 bary = closest_point_barycentric(k.p, k.a, k.b, k.c);
    ASSERT_TRUE(bary.allFinite()) << i;
    EXPECT_NEAR(bary.sum(), 1.0, 1e-12) << i;
    EXPECT_GE(bary.minCoeff(), 0.0) << i;
    const Vec3 x = bary[0] * k.a + bary[1] * k.b + bary[2] * k.c;
    EXPECT_NEAR((x - k.nearest).norm(), 0.0, 1e-9) << i;
  }
  // Through the mesh search: a one-face mesh of a collapsed triangle is as far as its longest edge.
  TriangleMesh sliver;
  sliver.positions = {{0, 0, 0}, {1, 0, 0}, {3, 0, 0}};
  sliver.faces = {{0, 1, 2}};
  EXPECT_NEAR(PointToMesh(sliver).distance(Vec3(2, 0, 2)), 2.0, 1e-12);
}

// The nearest rank: the ceil(0.99 n)-th smallest, so that 1% of the values may lie above it.
TEST(Distance, TheNearestRankP99IsTheCeilOf99PercentOfTheCountThSmallest) {
  std::vector<double> none;
  EXPECT_EQ(nearest_rank_p99(none), 0.0);
  std::vector<double> one{7.0};
  EXPECT_EQ(nearest_rank_p99(one), 7.0);
  std::vector<double> hundred(100), hundred_one(101);
  for (size_t i = 0; i < hundred.size(); ++i) hundred[i] = static_cast<double>((i * 37) % 100);  // 0..99, shuffled
  for (size_t i = 0; i < hundred_one.size(); ++i) hundred_one[i] = static_cast<double>((i * 37) % 101);
  EXPECT_EQ(nearest_rank_p99(hundred), 98.0);      // rank 99 of 100: one value (99) above it
  EXPECT_EQ(nearest_rank_p99(hundred_one), 99.0);  // rank ceil(99.99) = 100 of 101
}

TEST(Distance, SymmetricDistanceOfAnOffsetSurfaceIsTheOffset) {
  const TriangleMesh a = testing::grid_mesh(20, [](double x, double y) { return Vec3(x, y, 0); });
  TriangleMesh b = testing::grid_mesh(13, [](double x, double y) { return Vec3(x, y, 0.01); });
  const SurfaceDistance d = surface_distance(a, b);
  EXPECT_NEAR(d.rms, 0.01, 1e-12);
  EXPECT_NEAR(d.max, 0.01, 1e-12);
  EXPECT_NEAR(d.p99, 0.01, 1e-12);
  EXPECT_NEAR(d.diagonal, std::sqrt(2.0), 1e-12);
}

// One spike on an otherwise exact copy: the Hausdorff distance is the spike, the 99th percentile is
// not (fewer than 1% of the 2 x 441 distances leave 0: the spike's vertex and the reference's
// vertices under its steep faces), and 1% of the vertices raised sets it to their height.
TEST(Distance, The99thPercentileIgnoresOneStrayVertexButNotOnePercentOfThem) {
  const auto flat = [](double x, double y) { return Vec3(x, y, 0); };
  const TriangleMesh a = testing::grid_mesh(20, flat);
  TriangleMesh b = a;
  b.positions[220] += Vec3(0, 0, 1);  // the centre node (10, 10)
  const SurfaceDistance spike = surface_distance(a, b);
  EXPECT_NEAR(spike.max, 1.0, 1e-12);
  EXPECT_NEAR(spike.p99, 0.0, 1e-12);
  EXPECT_GT(spike.rms, 0.03);
  // Raise the whole surface by 0.02 except along a strip: then over 1% of the distances are 0.02.
  TriangleMesh c = testing::grid_mesh(20, [](double x, double y) { return Vec3(x, y, y > 0.9 ? 0.02 : 0.0); });
  const SurfaceDistance strip = surface_distance(a, c);
  EXPECT_NEAR(strip.p99, 0.02, 1e-12);
}

// Each direction's percentile apart: the test mesh covers the left half of the reference's square,
// so its vertices lie on the reference (0) while the reference's right half misses it by up to 0.5
// (the top 21 of its 441 distances, past the 99th percentile's rank 437), as a sheet a repair dropped.
TEST(Distance, EachDirectionsPercentileIsMeasuredApart) {
  const TriangleMesh reference = testing::grid_mesh(20, [](double x, double y) { return Vec3(x, y, 0); });
  const TriangleMesh half = testing::grid_mesh(10, [](double x, double y) { return Vec3(0.5 * x, y, 0); });
  const SurfaceDistance d = surface_distance(reference, half);
  EXPECT_NEAR(d.p99_test_to_reference, 0.0, 1e-12);
  EXPECT_NEAR(d.p99_reference_to_test, 0.5, 1e-12);
  const SurfaceDistance swapped = surface_distance(half, reference);
  EXPECT_NEAR(swapped.p99_test_to_reference, 0.5, 1e-12);
  EXPECT_NEAR(swapped.p99_reference_to_test, 0.0, 1e-12);
}

// surface_distance starts each vertex's search from the previous vertex's nearest face (a hint): every
// figure is still, to the bit, what a search from no hint gives, where the hint is near (a sphere's
// vertices in order), far (the same vertices shuffled) or ties (every face twice). Taking the hint's
// distance as a bound, or its face as the answer, fails here. So on any number of threads.
TEST(Distance, SurfaceDistanceIsTheUnhintedSearchsToTheBit) {
  const auto [sphere, doubled] = sphere_and_doubled();
  std::mt19937 rng(17);
  std::normal_distribution<double> jitter(0, 0.02);
  TriangleMesh bumpy = testing::icosphere(1.05, 2);
  for (Vec3& p : bumpy.positions) p += Vec3(jitter(rng), jitter(rng), jitter(rng));
  TriangleMesh shuffled = bumpy;  // the same surface, its vertices in a random order
  std::vector<int32_t> order(bumpy.positions.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int32_t>(i);
  std::shuffle(order.begin(), order.end(), rng);
  for (size_t i = 0; i < order.size(); ++i) shuffled.positions[static_cast<size_t>(order[i])] = bumpy.positions[i];
  for (Face& f : shuffled.faces)
    for (int32_t& v : f) v = order[static_cast<size_t>(v)];
  // A vertex no face uses (as a hole's cut leaves them): measured from neither side.
  shuffled.positions.insert(shuffled.positions.begin() + 5, Vec3(9, 9, 9));
  for (Face& f : shuffled.faces)
    for (int32_t& v : f) v += v >= 5;
  for (const TriangleMesh* reference : {&sphere, &doubled}) {
    for (const TriangleMesh* test : {&bumpy, &shuffled}) {
      // Each direction's distances as PointToMesh::distance gives them (no hint), in surface_distance's order.
      std::vector<double> to_reference, to_test;
      const PointToMesh reference_query(*reference), test_query(*test);
      const auto used = [](const TriangleMesh& mesh) {
        std::vector<char> in_a_face(mesh.positions.size(), 0);
        for (const Face& f : mesh.faces)
          for (const int32_t v : f) in_a_face[static_cast<size_t>(v)] = 1;
        return in_a_face;
      };
      const std::vector<char> test_used = used(*test), reference_used = used(*reference);
      for (size_t i = 0; i < test->positions.size(); ++i)
        if (test_used[i]) to_reference.push_back(reference_query.distance(test->positions[i]));
      for (size_t i = 0; i < reference->positions.size(); ++i)
        if (reference_used[i]) to_test.push_back(test_query.distance(reference->positions[i]));
      double sum = 0, max = 0;
      std::vector<double> all = to_reference;
      all.insert(all.end(), to_test.begin(), to_test.end());
      for (const double e : all) sum += e * e, max = std::max(max, e);
      // On any number of threads (runs of consecutive vertices, each with its own hints), the same
      // figures: summing each run apart, or a run that skips or repeats a vertex, fails here.
      for (const int threads : {1, 2, 3, 7}) {
        SCOPED_TRACE(::testing::Message() << threads << " threads");
        const SurfaceDistance d = surface_distance(*reference, *test, threads);
        EXPECT_EQ(d.rms, std::sqrt(sum / static_cast<double>(all.size())));
        EXPECT_EQ(d.max, max);
        EXPECT_EQ(d.p99, nearest_rank_p99(all));
        EXPECT_EQ(d.p99_test_to_reference, nearest_rank_p99(to_reference));
        EXPECT_EQ(d.p99_reference_to_test, nearest_rank_p99(to_test));
        EXPECT_GT(d.max, 0.0);
      }
    }
  }
}

}  // namespace
}  // namespace facemorph
