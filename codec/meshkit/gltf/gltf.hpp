// Decoded clips as glTF 2.0 binary (.glb), the file three.js, Blender and every engine load
// (spec/method.md §8). One mesh on G's triangles; frame 0 is the base and every later frame a morph
// target (positions and normals as differences from frame 0; the normals the decoder gives, area-
// weighted over the clip's triangles, so a viewer shades the face smoothly); one animation drives the morph
// weights, one-hot at each frame's time and linear between, so a player interpolates frames as
// fmdec would at its own rate. glTF has no animated textures: the clip carries one texture, or
// (switched_textures) several, each on a copy of the node that the animation shows alone while its
// texture is the current one.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"

#include <cstdint>
#include <vector>

namespace facemorph {

struct GltfClip {
  std::vector<double> times;                 // seconds, strictly increasing, one per frame
  std::vector<std::vector<Vec3>> positions;  // per frame, one per vertex
  std::vector<Face> faces;                   // shared by every frame, counter-clockwise
  std::vector<Vec2> uvs;                     // per vertex, in [0,1]² (v up, as glTF's is flipped on writing)
  Image texture;                             // RGB or RGBA; empty: untextured grey material
  // Two or more: instead of `texture`, texture i is shown from starts[i] (seconds, the clip's times;
  // the first at or before the first frame) until starts[i + 1]: one node per texture sharing every
  // accessor, its scale animated (STEP) to the node's own while its texture is current and to 0 else.
  // Stored as WebP (EXT_texture_webp, which three.js reads) in a compact clip, PNG otherwise.
  struct SwitchedTexture {
    double start = 0;
    Image image;
  };
  std::vector<SwitchedTexture> switched_textures;
  std::string name = "face";
  // For the web (issue 29): positions and their morph differences as int16 on one grid of the
  // clip's box (the node's scale and translation undo it: KHR_mesh_quantization), normals as
  // normalised int8 and their differences as int8 code differences (so each frame reads its own
  // codes, within 1/127 a component of the decoder's normals), UVs as normalised uint16; then every vertex stream and the
  // indices compressed with meshoptimizer (EXT_meshopt_compression) where that is smaller. The
  // positions move by at most half a grid step: the box's largest side / 65534 / 2.
  bool compact = false;
  // The decoder's vertex normals in the base and every morph target (NORMAL), so a viewer shades
  // the face smoothly; without them a viewer shades each triangle flat (glTF 2.0 §3.7.2.1), and a
  // compact clip is smaller (the README sample's: 1.22 MB against 1.94 MB).
  bool normals = true;
};

// The .glb bytes (with `compact`, needing KHR_mesh_quantization and, where a stream was compressed,
// EXT_meshopt_compression: three.js reads both, the latter with its MeshoptDecoder). Throws kInvalidArgument for an empty clip, times not
// increasing, frames of different sizes, faces out of range, UVs of the wrong count, or non-finite positions.
std::vector<uint8_t> encode_glb(const GltfClip& clip);

// Holes in a morphing mesh: glTF cannot change a mesh's triangles over time. The clip drops the
// triangles that lie inside a hole (all three corners at level < 0) in every frame of the clip, so
// eyes and a mouth that stay open are open; a hole that opens or closes within the clip shows the
// encoder's fill while it is open (fmdec's OBJ/PLY frames and previews cut it exactly). Moving the
// hole's nodes onto its outline instead was tried: the triangles across the hole then span it as a
// lid. `levels`: per frame, one level per vertex.
std::vector<Face> faces_outside_holes(const std::vector<Face>& faces, const std::vector<std::vector<double>>& levels);

}  // namespace facemorph
