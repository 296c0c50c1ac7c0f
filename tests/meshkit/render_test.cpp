// The preview renderer's shading: with the decoder's vertex normals a curved surface shows no facet
// edges (issue 48 part 4), while flat shading of the same triangles does, so the measure can fail.
#include "codec/meshkit/render/render.hpp"

#include "format/error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace facemorph {
namespace {

// A spherical cap of radius 1 facing +z (the viewer), from the pole to 75 degrees, in `rings`
// rings of `sectors` triangles fans: coarse on purpose, so that flat facets are wide.
TriangleMesh dome(int rings, int sectors) {
  TriangleMesh mesh;
  mesh.positions.push_back(Vec3(0, 0, 1));
  for (int r = 1; r <= rings; ++r) {
    const double polar = 75.0 * std::numbers::pi / 180 * r / rings;
    for (int s = 0; s < sectors; ++s) {
      const double azimuth = 2 * std::numbers::pi * s / sectors;
      mesh.positions.push_back(Vec3(std::sin(polar) * std::cos(azimuth), std::sin(polar) * std::sin(azimuth), std::cos(polar)));
    }
  }
  const auto at = [&](int r, int s) { return r == 0 ? 0 : 1 + (r - 1) * sectors + (s % sectors); };
  for (int s = 0; s < sectors; ++s) mesh.faces.push_back({at(0, 0), at(1, s), at(1, s + 1)});
  for (int r = 1; r < rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      mesh.faces.push_back({at(r, s), at(r + 1, s), at(r + 1, s + 1)});
      mesh.faces.push_back({at(r, s), at(r + 1, s + 1), at(r, s + 1)});
    }
  }
  return mesh;
}

// The largest step in intensity between neighbouring pixels (right and below) well inside the
// drawn surface: both pixels and a 3-pixel band around them drawn, so the silhouette does not count.
int largest_inner_step(const Image& image, uint8_t background) {
  const auto drawn = [&](int x, int y) { return image.at(x, y)[0] != background; };
  const auto inner = [&](int x, int y) {
    for (int dy = -3; dy <= 3; ++dy) {
      for (int dx = -3; dx <= 3; ++dx) {
        const int u = x + dx, v = y + dy;
        if (u < 0 || v < 0 || u >= image.width || v >= image.height || !drawn(u, v)) return false;
      }
    }
    return true;
  };
  int largest = 0;
  for (int y = 0; y + 1 < image.height; ++y) {
    for (int x = 0; x + 1 < image.width; ++x) {
      if (!inner(x, y)) continue;
      const int here = image.at(x, y)[0];
      if (inner(x + 1, y)) largest = std::max(largest, std::abs(image.at(x + 1, y)[0] - here));
      if (inner(x, y + 1)) largest = std::max(largest, std::abs(image.at(x, y + 1)[0] - here));
    }
  }
  return largest;
}

TEST(Render, TheDecodersNormalsShadeACurvedSurfaceWithoutFacetEdges) {
  const TriangleMesh mesh = dome(6, 16);
  RenderOptions options;
  options.width = options.height = 300;
  options.background = {255, 255, 255};  // the shaded grey (200 at most) never reaches it
  const SurfaceShader grey = constant_shader({200, 200, 200});
  const Image flat = render(mesh, grey, options);
  const Image smooth = render(mesh, grey, options, shading_normals(mesh));
  const int flat_step = largest_inner_step(flat, 255), smooth_step = largest_inner_step(smooth, 255);
  // Flat: adjacent facets of the cap differ by up to 12.5 degrees, a jump of tens of levels at
  // their shared edge. Smooth: the interpolated normal turns a fraction of a degree a pixel.
  EXPECT_GE(flat_step, 15) << "the control: flat facets of this dome should show edges";
  EXPECT_LE(smooth_step, 4) << "smooth shading shows a jump of " << smooth_step << " levels between neighbouring pixels";
  // The same silhouette either way: only the lighting differs.
  int differ = 0;
  for (int y = 0; y < options.height; ++y) {
    for (int x = 0; x < options.width; ++x) differ += (flat.at(x, y)[0] == 255) != (smooth.at(x, y)[0] == 255);
  }
  EXPECT_EQ(differ, 0);
}

TEST(Render, ShadingNormalsAreTheDecodersUnitAreaWeightedNormals) {
  const TriangleMesh mesh = dome(3, 8);
  const std::vector<Vec3> normals = shading_normals(mesh);
  ASSERT_EQ(normals.size(), mesh.positions.size());
  // The pole's normal is the mean of its fan's face normals, by area: straight up by symmetry.
  EXPECT_NEAR(normals[0].z(), 1.0, 1e-6);
  for (size_t v = 0; v < normals.size(); ++v) {
    EXPECT_NEAR(normals[v].norm(), 1.0, 1e-6);
    // Outward (the faces wind counter-clockwise seen from outside) and near the sphere's own normal.
    EXPECT_GT(normals[v].dot(mesh.positions[v].normalized()), 0.95) << "vertex " << v;
  }
}

TEST(Render, NormalsOfAnotherCountAreAnError) {
  const TriangleMesh mesh = dome(2, 6);
  const std::vector<Vec3> short_by_one(mesh.positions.size() - 1, Vec3::UnitZ());
  EXPECT_THROW(render(mesh, constant_shader({200, 200, 200}), {}, short_by_one), Error);
}

}  // namespace
}  // namespace facemorph
