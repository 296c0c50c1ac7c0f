#include "codec/encoder/conformal/resample.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/synth/synth.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace facemorph {
namespace {

using testing::kPi;

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
    EXPECT_LT((positions[static_cast<size_t>(i)] - Vec3(grid.nodes[static_cast<size_t>(i)].x(), grid.nodes[static_cast<size_t>(i)].y(), 0))
                  .norm(),
              1e-9);
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
