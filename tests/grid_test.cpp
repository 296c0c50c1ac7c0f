#include "facemorph/conformal.hpp"
#include "facemorph/disk_grid.hpp"
#include "facemorph/geometry.hpp"
#include "facemorph/resample.hpp"
#include "facemorph/synth.hpp"
#include "facemorph/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace facemorph {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(DiskGrid, IsACartesianInteriorWithARimOnTheCircleAndNoSlivers) {
  for (int n : {17, 65, 257}) {
    const DiskGrid g = make_disk_grid(n);
    EXPECT_DOUBLE_EQ(g.h, 2.0 / (n - 1));
    EXPECT_EQ(g.rim_count, static_cast<int>(std::lround(2 * kPi / g.h)));
    int expected_interior = 0;
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const Vec2 w(-1 + i * g.h, -1 + j * g.h);
        const int32_t node = g.node_at[static_cast<size_t>(j) * n + i];
        if (w.norm() <= 1 - 0.5 * g.h) {
          ++expected_interior;
          ASSERT_GE(node, 0);
          EXPECT_EQ(g.nodes[static_cast<size_t>(node)], w);
        } else {
          EXPECT_EQ(node, -1);
        }
      }
    }
    EXPECT_EQ(g.interior_count, expected_interior);
    for (int k = 0; k < g.rim_count; ++k) EXPECT_NEAR(g.nodes[static_cast<size_t>(g.interior_count + k)].norm(), 1.0, 1e-15);
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
    EXPECT_GT(min_angle * 180 / kPi, 20.0) << "N = " << n;  // no slivers at the rim
    EXPECT_NEAR(area, g.rim_count / 2.0 * std::sin(2 * kPi / g.rim_count), 1e-9);  // the rim polygon's area
  }
  testing::expect_error(ErrorCode::kInvalidArgument, "grid size N", [] { make_disk_grid(3); });
}

TEST(Resample, AFlatDiskResamplesToTheGridItself) {
  // The linear map of a polar-grid disk is the identity, so the resampled surface is the grid.
  TriangleMesh disk;
  disk.positions.emplace_back(0, 0, 0);
  const int rings = 12, sectors = 48;
  for (int r = 1; r <= rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      const double a = 2 * kPi * s / sectors, radius = static_cast<double>(r) / rings;
      disk.positions.emplace_back(radius * std::cos(a), radius * std::sin(a), 0);
    }
  }
  auto id = [](int r, int s) { return r == 0 ? 0 : 1 + (r - 1) * sectors + (s % sectors); };
  for (int s = 0; s < sectors; ++s) disk.faces.push_back({id(0, 0), id(1, s), id(1, s + 1)});
  for (int r = 1; r < rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      disk.faces.push_back({id(r, s), id(r + 1, s), id(r + 1, s + 1)});
      disk.faces.push_back({id(r, s), id(r + 1, s + 1), id(r, s + 1)});
    }
  }
  const DiskMap map = conformal_disk_map(disk, {.method = ConformalMethod::kLinear});
  const InverseDiskMap inverse(map);
  const DiskGrid grid = make_disk_grid(33);
  const auto positions = resample_positions(inverse, grid);
  for (int i = 0; i < grid.interior_count; ++i) {
    EXPECT_LT((positions[static_cast<size_t>(i)] - Vec3(grid.nodes[static_cast<size_t>(i)].x(), grid.nodes[static_cast<size_t>(i)].y(), 0)).norm(), 1e-9);
  }
  // Rim nodes land on the boundary polygon (within its chord sagitta of the circle).
  for (int k = 0; k < grid.rim_count; ++k) {
    EXPECT_NEAR(positions[static_cast<size_t>(grid.interior_count + k)].norm(), 1.0, 1 - std::cos(kPi / sectors) + 1e-12);
  }
}

TEST(Resample, SyntheticTextureIsReproducedOnTheDisk) {
  const SyntheticFace face(Expression::kSmile, 1);
  TriangleMesh mesh = face.truth_mesh(0.0, 6000);
  Image texture(256, 256, 3);
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      const double u = (x + 0.5) / 256, v = 1 - (y + 0.5) / 256;
      const auto rgb = face.color({(2 * u - 1) * SyntheticFace::kHalfWidth, (2 * v - 1) * SyntheticFace::kHalfHeight}, 0.0);
      std::copy(rgb.begin(), rgb.end(), texture.at(x, y));
    }
  }
  const DiskMap map = conformal_disk_map(mesh);
  const InverseDiskMap inverse(map);
  const Image disk = resample_texture(map, inverse, texture, 128);
  ASSERT_EQ(disk.width, 128);
  // Each texel agrees with the texture looked up through the inverse map at its centre.
  double error = 0;
  int count = 0;
  for (int y = 0; y < 128; y += 3) {
    for (int x = 0; x < 128; x += 3) {
      Vec2 w(2 * (x + 0.5) / 128 - 1, 1 - 2 * (y + 0.5) / 128);
      const bool outside = w.norm() > 1;
      if (outside) w.normalize();
      const auto hit = inverse.locate(w);
      ASSERT_TRUE(hit.has_value());
      const Vec2 uv = inverse.texture_uv(*hit);
      const auto expected = sample_bilinear(texture, uv.x(), uv.y());
      for (int c = 0; c < 3; ++c) error = std::max(error, std::abs(disk.at(x, y)[c] - expected[static_cast<size_t>(c)]));
      ++count;
    }
  }
  EXPECT_GT(count, 1000);
  EXPECT_LE(error, 1.0);  // rounding only
}

}  // namespace
}  // namespace facemorph
