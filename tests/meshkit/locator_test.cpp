#include "codec/meshkit/geometry/locator.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <vector>

namespace facemorph {
namespace {

// A disk triangulation crowded towards its centre as a conformal map crowds a face's far parts
// (radius r drawn at r³): buckets there hold many small faces, at the rim few large ones.
struct CrowdedDisk {
  std::vector<Vec2> points;
  std::vector<Face> faces;
};

CrowdedDisk crowded_disk() {
  const TriangleMesh mesh = testing::polar_disk(24, 40, [](const Vec2& w) {
    const double r = w.norm();
    return Vec3(w.x() * r * r, w.y() * r * r, 0);
  });
  CrowdedDisk disk;
  for (const Vec3& p : mesh.positions) disk.points.emplace_back(p.x(), p.y());
  disk.faces = mesh.faces;
  return disk;
}

// What locate() promises, from every face: the deepest (the least barycentric the greatest), the
// earliest face of equally deep ones, clamped into the face within the tolerance, none beyond it.
std::optional<SurfacePoint> deepest_of_all(const TriangleLocator& locator, size_t face_count, const Vec2& p, double tolerance) {
  SurfacePoint best;
  double best_depth = -std::numeric_limits<double>::infinity();
  for (size_t f = 0; f < face_count; ++f) {
    const Vec3 bary = locator.barycentric(static_cast<int>(f), p);
    if (bary.minCoeff() > best_depth) {
      best_depth = bary.minCoeff();
      best = {static_cast<int>(f), bary};
    }
  }
  if (best_depth < -tolerance) return std::nullopt;
  if (best_depth < 0) {
    best.bary = best.bary.cwiseMax(0.0);
    best.bary /= best.bary.sum();
  }
  return best;
}

void expect_same(const std::optional<SurfacePoint>& found, const std::optional<SurfacePoint>& expected, const Vec2& p) {
  ASSERT_EQ(found.has_value(), expected.has_value()) << "at (" << p.x() << ", " << p.y() << ")";
  if (!found) return;
  EXPECT_EQ(found->face, expected->face) << "at (" << p.x() << ", " << p.y() << ")";
  for (int k = 0; k < 3; ++k) EXPECT_EQ(found->bary[k], expected->bary[k]) << "the coordinates to the bit";
}

TEST(Locator, FindsTheFaceEveryFaceScannedFindsInsideOnEdgesAndAtVertices) {
  const CrowdedDisk disk = crowded_disk();
  const TriangleLocator locator(disk.points, disk.faces);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1), t(0, 1);
  int inside = 0;
  for (int i = 0; i < 4000; ++i) {
    Vec2 p;
    const Face& f = disk.faces[static_cast<size_t>(i) % disk.faces.size()];
    const Vec2 &a = disk.points[static_cast<size_t>(f[0])], &b = disk.points[static_cast<size_t>(f[1])];
    switch (i % 4) {
      case 0: p = Vec2(u(rng), u(rng)); break;           // anywhere, most inside, the crowded centre too
      case 1: p = a; break;                              // a vertex: every face around it at depth 0
      case 2: p = a + t(rng) * (b - a); break;           // on an edge: the two faces beside it tie
      default: p = 1e-3 * Vec2(u(rng), u(rng)); break;   // in the crowded middle, a bucket of many faces
    }
    const auto expected = deepest_of_all(locator, disk.faces.size(), p, 1e-9);
    inside += expected.has_value();
    expect_same(locator.locate(p), expected, p);
  }
  EXPECT_GT(inside, 3000);  // the disk holds most of the square's points
}

TEST(Locator, APointJustOutsideTheRimIsClampedIntoItsFaceAndOneFartherIsNone) {
  // Outside every face but within the tolerance (a caller's 1e-6 on a rim edge, here larger):
  // points 1e-12 out lie within the faces' boxes (one float step of slack), points 1e-3 out past
  // them, found only by measuring every face of their bucket (the boxes' shortcut must give way
  // there; without it this test fails), and the face found is still the nearest.
  const CrowdedDisk disk = crowded_disk();
  const TriangleLocator locator(disk.points, disk.faces);
  const size_t rim_first = disk.points.size() - 40;  // the outer ring's vertices
  for (const double tolerance : {1e-9, 0.05}) {
    for (size_t v = rim_first; v < disk.points.size(); ++v) {
      for (const double out : {1e-12, 1e-3}) {
        const Vec2 near = disk.points[v] * (1 + out);
        const auto expected = deepest_of_all(locator, disk.faces.size(), near, tolerance);
        ASSERT_EQ(expected.has_value(), out < tolerance);
        expect_same(locator.locate(near, tolerance), expected, near);
      }
      EXPECT_FALSE(locator.locate(disk.points[v] * 1.2, tolerance).has_value());
    }
  }
}

TEST(Locator, WhereFacesOverlapTheOneThePointIsDeepestInsideWins) {
  // A folded embedding: a small face inside a large one, listed after it; and the reverse order.
  const std::vector<Vec2> points = {{0, 0}, {1, 0}, {0, 1}, {0.1, 0.1}, {0.3, 0.1}, {0.1, 0.3}};
  for (const bool small_first : {false, true}) {
    std::vector<Face> faces = {{0, 1, 2}, {3, 4, 5}};
    if (small_first) std::swap(faces[0], faces[1]);
    const TriangleLocator locator(points, faces);
    const Vec2 centre_of_small(0.5 / 3, 0.5 / 3);  // depth 1/3 in the small face, about 0.17 in the large
    const auto hit = locator.locate(centre_of_small);
    ASSERT_TRUE(hit.has_value());
    EXPECT_EQ(hit->face, small_first ? 0 : 1);
    const Vec2 large_only(0.6, 0.2);
    ASSERT_TRUE(locator.locate(large_only).has_value());
    EXPECT_EQ(locator.locate(large_only)->face, small_first ? 1 : 0);
  }
}

TEST(Locator, AFaceWhoseBoxHoldsThePointDoesNotHideANearerFaceOutsideIt) {
  // p lies just outside face A (depth -0.01) and outside its box; face B's box holds p, but p is far
  // outside B. Within a tolerance of 0.05, A is the answer, found only past the boxes.
  const std::vector<Vec2> points = {{0, 0}, {1, 0}, {0, 1}, {-0.5, 0.4}, {0, 0.4}, {-0.5, 0.6}};
  const std::vector<Face> faces = {{0, 1, 2}, {3, 4, 5}};
  const TriangleLocator locator(points, faces);
  const Vec2 p(-0.01, 0.5);
  const auto hit = locator.locate(p, 0.05);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->face, 0);
  expect_same(hit, deepest_of_all(locator, faces.size(), p, 0.05), p);
  EXPECT_FALSE(locator.locate(p, 0.001).has_value());
}

}  // namespace
}  // namespace facemorph
