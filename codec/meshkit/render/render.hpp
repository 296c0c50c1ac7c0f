// A small software rasterizer for previews and diagnostic pictures (orthographic, z-buffered,
// headlight Lambert shading, flat or smooth). Deliberately dependency-free so the decoder can embed it.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"

#include <functional>
#include <span>
#include <vector>

namespace facemorph {

// Surface colour at a point of face `face` with barycentric coordinates `bary` (RGB 0..255).
using SurfaceShader = std::function<std::array<double, 3>(int face, const Vec3& bary)>;

// How the tools show a face to a person (fmdec --preview, fmview, fmplay's video): turned 20 degrees
// about the vertical axis, so the nose and cheeks read as relief. One value, so that a decoded frame's
// preview and the captured frame's picture are seen from the same camera and can be set side by side.
inline constexpr double kPreviewYawDegrees = 20;

struct RenderOptions {
  int width = 800;
  int height = 800;
  double yaw_degrees = 0;    // rotation about the vertical axis, applied first
  double pitch_degrees = 0;  // then about the horizontal axis
  double margin = 0.05;      // fraction of the image left around the mesh
  bool shading = true;       // multiply by a headlight Lambert term
  std::array<uint8_t, 3> background = {255, 255, 255};
  bool wireframe = false;  // draw the edges over the shading
  std::array<uint8_t, 3> wire_color = {30, 30, 30};
};

// Renders `mesh` looking down -z (after the yaw/pitch rotation), fitting its bounding box.
// `vertex_normals`, one per position (shading_normals), shade smoothly: the headlight term
// 0.25 + 0.75 |n · z| takes the normal interpolated across the triangle at each pixel, as a GPU
// interpolates a vertex attribute (web/facemorph.js draws the same); where that interpolation
// vanishes, or without normals, the triangle is lit flat by its own normal. A size other than
// positions.size() throws kInvalidArgument.
Image render(const TriangleMesh& mesh, const SurfaceShader& shader, const RenderOptions& options = {},
             std::span<const Vec3> vertex_normals = {});

// The decoder's vertex normals of `mesh` (area-weighted, unit, zero for a vertex on no triangle of
// non-zero area: what fm_decoder_decode gives as fm_frame.normals for a decoded frame), for
// render's smooth shading of any mesh, decoded or read from a file. Throws kInvalidArgument for a
// face index out of range.
std::vector<Vec3> shading_normals(const TriangleMesh& mesh);

// Shaders.
SurfaceShader constant_shader(std::array<double, 3> rgb);
// Looks the mesh's per-corner UVs up in `texture` (falls back to grey without UVs).
SurfaceShader texture_shader(const TriangleMesh& mesh, const Image& texture);
// A checkerboard of `squares` per unit of the per-corner UVs: pulled back through a
// parametrization it shows how angles and areas are distorted (the paper's Figure 3).
SurfaceShader checkerboard_shader(const TriangleMesh& mesh, double squares);

}  // namespace facemorph
