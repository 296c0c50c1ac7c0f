// The density-equalising reparametrisation of the reference disk (issue 8 item 10, spec/method.md
// §7.11): it leaves an evenly mapped disk alone, spreads a crowded one, stays a bijection with the
// rim on the circle, and refuses a strength outside [0, 1].
#include "codec/encoder/density/density_equalising.hpp"
#include "codec/core/geometry/differential.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>
#include <vector>

namespace facemorph {
namespace {

// A disk with a tall narrow bump in the middle (a nose): the conformal map gives the bump's area a
// small patch of the disk.
TriangleMesh bump(double height) {
  return testing::polar_disk(32, 128, [height](const Vec2& p) { return Vec3(p.x(), p.y(), height * std::exp(-p.squaredNorm() / 0.04)); });
}

// Surface areas of G's triangles when G is sampled through the reparametrisation.
std::vector<double> surface_areas_of_grid(const DiskMap& map, const DiskReparametrisation& reparametrise, const DiskGrid& grid) {
  const InverseDiskMap inverse(map);
  std::vector<Vec3> positions;
  for (const Vec2& node : grid.nodes) {
    const auto hit = inverse.locate(reparametrise(node));
    EXPECT_TRUE(hit.has_value());
    positions.push_back(hit ? inverse.position(*hit) : Vec3::Zero());
  }
  return face_areas(positions, grid.faces);
}

double coefficient_of_variation(const std::vector<double>& values) {
  double mean = 0, spread = 0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(values.size());
  for (double v : values) spread += (v - mean) * (v - mean);
  return std::sqrt(spread / static_cast<double>(values.size())) / mean;
}

// The disk radius within which the grid, sampled through `reparametrise`, holds half the surface: its
// faces' sampled areas summed in the order of their centroids' radii. Measured on the surface the grid
// samples, not read from the reparametrisation's own tables.
double grid_half_area_radius(const DiskMap& map, const DiskReparametrisation& reparametrise, const DiskGrid& grid) {
  const std::vector<double> areas = surface_areas_of_grid(map, reparametrise, grid);
  std::vector<std::pair<double, double>> by_radius;  // (centroid radius, surface area)
  double total = 0;
  for (size_t f = 0; f < grid.faces.size(); ++f) {
    Vec2 centroid = Vec2::Zero();
    for (int32_t v : grid.faces[f]) centroid += grid.nodes[static_cast<size_t>(v)] / 3.0;
    by_radius.emplace_back(centroid.norm(), areas[f]);
    total += areas[f];
  }
  std::sort(by_radius.begin(), by_radius.end());
  double sum = 0;
  for (const auto& [radius, area] : by_radius) {
    if ((sum += area) >= 0.5 * total) return radius;
  }
  return 1;
}

TEST(DensityEqualising, StrengthZeroIsTheIdentity) {
  const DiskMap map = conformal_disk_map(bump(0.5));
  const DiskReparametrisation identity(map, {.strength = 0});
  EXPECT_TRUE(identity.identity());
  for (const Vec2& node : make_disk_grid(17).nodes) EXPECT_EQ(identity(node), node);
}

TEST(DensityEqualising, AnEvenlyMappedDiskIsLeftAlone) {
  // A flat disk maps onto the unit disk by (nearly) a similarity: its density is uniform already.
  const DiskMap map = conformal_disk_map(testing::polar_disk(24, 96, [](const Vec2& p) { return Vec3(p.x(), p.y(), 0); }));
  const DiskReparametrisation equalise(map, {.strength = 1});
  EXPECT_LT(equalise.report().variation_before, 0.05);
  double moved = 0;
  for (const Vec2& node : make_disk_grid(33).nodes) moved = std::max(moved, (equalise(node) - node).norm());
  EXPECT_LT(moved, 0.02);
}

TEST(DensityEqualising, ACrowdedBumpIsSpreadAndTheMapStaysABijection) {
  const DiskMap map = conformal_disk_map(bump(0.6));
  const DiskGrid grid = make_disk_grid(33);
  const DiskReparametrisation conformal, half(map, {.strength = 0.5}), full(map, {.strength = 1});
  const double before = coefficient_of_variation(surface_areas_of_grid(map, conformal, grid));
  const double at_half = coefficient_of_variation(surface_areas_of_grid(map, half, grid));
  const double at_full = coefficient_of_variation(surface_areas_of_grid(map, full, grid));
  EXPECT_GT(before, 0.5) << "the bump should crowd the conformal disk";
  EXPECT_LT(at_half, 0.75 * before);
  EXPECT_LT(at_full, 0.5 * before);
  EXPECT_LT(full.report().variation_after, 0.5 * full.report().variation_before);
  for (const DiskReparametrisation* d : {&half, &full}) {
    // Every triangle of G keeps its orientation on the conformal disk; the rim stays on the circle
    // in its order.
    for (const Face& f : grid.faces) {
      const Vec2 a = (*d)(grid.nodes[static_cast<size_t>(f[0])]), b = (*d)(grid.nodes[static_cast<size_t>(f[1])]),
                 c = (*d)(grid.nodes[static_cast<size_t>(f[2])]);
      EXPECT_GT((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x(), 0);
    }
    double turned = 0;
    for (int k = 0; k < grid.rim_count; ++k) {
      const Vec2& node = grid.nodes[static_cast<size_t>(grid.interior_count + k)];
      const Vec2 p = (*d)(node);
      const Vec2 q = (*d)(grid.nodes[static_cast<size_t>(grid.interior_count + (k + 1) % grid.rim_count)]);
      EXPECT_NEAR(p.norm(), std::min(node.norm(), 1.0), 1e-12);
      const double step = std::atan2(p.x() * q.y() - p.y() * q.x(), p.dot(q));
      EXPECT_GT(step, 0);
      turned += step;
    }
    EXPECT_NEAR(turned, 2 * std::numbers::pi, 1e-9);
  }
}

TEST(DensityEqualising, StrengthOutsideTheUnitIntervalIsRefused) {
  const DiskMap map = conformal_disk_map(bump(0.2));
  testing::expect_error(ErrorCode::kInvalidArgument, "strength", [&] { DiskReparametrisation(map, {.strength = 1.5}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "strength", [&] { DiskReparametrisation(map, {.strength = -0.1}); });
}

// The radial reparametrisation (whole heads, spec/method.md §7.11): the disk's radius holding half
// the surface goes to sqrt(1/2) at strength 1, the circle stays the circle, radii keep their order,
// and an evenly mapped disk is left alone.
TEST(RadialEqualising, AnEvenlyMappedDiskIsLeftAlone) {
  const DiskMap map = conformal_disk_map(testing::polar_disk(24, 96, [](const Vec2& p) { return Vec3(p.x(), p.y(), 0); }));
  EXPECT_NEAR(half_area_radius(map), std::sqrt(0.5), 0.01);
  const DiskReparametrisation radial = DiskReparametrisation::radial(map, 1);
  EXPECT_FALSE(radial.identity());
  double moved = 0;
  for (const Vec2& node : make_disk_grid(33).nodes) moved = std::max(moved, (radial(node) - node).norm());
  EXPECT_LT(moved, 0.01);
  // Measured on the sampled surface: half of it within sqrt(1/2) with or without the map, and the
  // report says nothing moved.
  const DiskGrid grid = make_disk_grid(65);
  const double conformal = grid_half_area_radius(map, DiskReparametrisation(), grid);
  EXPECT_NEAR(conformal, std::sqrt(0.5), 0.02);
  EXPECT_NEAR(grid_half_area_radius(map, radial, grid), conformal, 0.01);
  EXPECT_NEAR(radial.report().half_area_radius_after, radial.report().half_area_radius_before, 0.01);
}

TEST(RadialEqualising, ACrowdedCentreIsSpreadByRadius) {
  // A tall narrow bump: most of the surface crowds the disk's centre, as a whole head's face does.
  const DiskMap map = conformal_disk_map(bump(3.0));
  const double before = half_area_radius(map);
  EXPECT_LT(before, 0.3);
  const DiskReparametrisation radial = DiskReparametrisation::radial(map, 1);
  // G sampled through it: the surface half of the grid's area holds (by radius) is half the surface,
  // where without it half the surface lay within the crowded centre; the report says what the grid
  // measures.
  const DiskGrid grid = make_disk_grid(65);
  const double measured = grid_half_area_radius(map, radial, grid);
  EXPECT_NEAR(measured, std::sqrt(0.5), 0.02);
  // Without it, half lies near the centre (0.34 as the 65² grid resolves it; the map's own is lower).
  EXPECT_LT(grid_half_area_radius(map, DiskReparametrisation(), grid), 0.4);
  EXPECT_NEAR(radial.report().half_area_radius_before, before, 1e-12);
  EXPECT_NEAR(radial.report().half_area_radius_after, measured, 0.02);
  const std::vector<double> areas = surface_areas_of_grid(map, radial, grid);
  double inside = 0, total = 0;
  for (size_t f = 0; f < grid.faces.size(); ++f) {
    Vec2 centroid = Vec2::Zero();
    for (int32_t v : grid.faces[f]) centroid += grid.nodes[static_cast<size_t>(v)] / 3.0;
    total += areas[f];
    if (centroid.norm() < std::sqrt(0.5)) inside += areas[f];
  }
  EXPECT_NEAR(inside / total, 0.5, 0.03);
  EXPECT_LT(coefficient_of_variation(areas), coefficient_of_variation(surface_areas_of_grid(map, DiskReparametrisation(), grid)));
  // Radial, monotone, the circle onto itself, the centre fixed.
  EXPECT_EQ(radial(Vec2(0, 0)), Vec2(0, 0));
  double previous = 0;
  for (int k = 1; k <= 200; ++k) {
    const double R = k / 200.0, theta = 0.7 * k;
    const Vec2 g = R * Vec2(std::cos(theta), std::sin(theta)), w = radial(g);
    EXPECT_NEAR(std::atan2(w.y(), w.x()), std::atan2(g.y(), g.x()), 1e-12);
    EXPECT_GT(w.norm(), previous);
    previous = w.norm();
  }
  EXPECT_NEAR(previous, 1.0, 1e-12);
}

TEST(RadialEqualising, StrengthOutsideItsIntervalIsRefused) {
  const DiskMap map = conformal_disk_map(bump(0.5));
  testing::expect_error(ErrorCode::kInvalidArgument, "strength", [&] { DiskReparametrisation::radial(map, 0); });
  testing::expect_error(ErrorCode::kInvalidArgument, "strength", [&] { DiskReparametrisation::radial(map, 1.5); });
}

}  // namespace
}  // namespace facemorph
