// The triangle mesh that flows through facemorph: a captured frame, a filled frame, a decoded frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products on Vec3

#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace facemorph {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
// Three vertex indices, counter-clockwise seen from the side the normal points to.
using Face = std::array<int32_t, 3>;

// Hash and sort key of the edge a -> b (vertex indices, non-negative): a in the high 32 bits.
constexpr uint64_t directed_edge_key(int32_t a, int32_t b) { return (uint64_t{static_cast<uint32_t>(a)} << 32) | static_cast<uint32_t>(b); }
// The same for the undirected edge {a, b}: both directions give the key of (min, max).
constexpr uint64_t undirected_edge_key(int32_t a, int32_t b) { return a < b ? directed_edge_key(a, b) : directed_edge_key(b, a); }

struct TriangleMesh {
  std::vector<Vec3> positions;  // capture units (see Capture::units)
  std::vector<Face> faces;

  // Optional texture coordinates, per corner: uv_faces[f][k] indexes uvs for corner k of faces[f].
  // Either empty or exactly faces.size() long. (u, v) with v pointing up, as in OBJ.
  std::vector<Vec2> uvs;
  std::vector<Face> uv_faces;

  // Texture image (OBJ map_Kd, PLY "comment TextureFile"); empty when there is none. Resolved
  // against the mesh file's folder by the readers.
  std::filesystem::path texture;

  // Optional colour per vertex (PLY red/green/blue, OBJ "v x y z r g b"): linear RGB in [0, 1],
  // either empty or exactly positions.size() long. Scanners without a texture image write these;
  // the encoder paints the disk texture from them (spec/capture.md).
  std::vector<Vec3> colours;

  bool has_uvs() const { return !uv_faces.empty() && uv_faces.size() == faces.size(); }
  bool has_colours() const { return !colours.empty() && colours.size() == positions.size(); }
  int vertex_count() const { return static_cast<int>(positions.size()); }
  int face_count() const { return static_cast<int>(faces.size()); }
};

}  // namespace facemorph
