// Reading and writing triangle meshes: Wavefront OBJ (+MTL) and PLY (ASCII, binary little- and
// big-endian). Parsers never trust counts in a file: allocation is bounded by the bytes present,
// and a file that ends early is ErrorCode::kTruncated, naming the file and the element.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace facemorph {

struct MeshReadOptions {
  // When false (default), a referenced material library or texture image that does not exist is
  // ErrorCode::kMissingTexture. When true it becomes a warning and the mesh has no texture.
  bool allow_missing_texture = false;
};

// Non-fatal remarks from a reader ("polygon faces fan-triangulated: 12"). May be null.
using Warnings = std::vector<std::string>;

// Reads .obj or .ply (by extension, case-insensitive). Throws facemorph::Error naming the file.
TriangleMesh read_mesh(const std::filesystem::path& path, const MeshReadOptions& options = {}, Warnings* warnings = nullptr);

// Parsers over memory, for fuzzing and tests. `source` names the input in messages; relative
// MTL/texture names resolve against `base_dir`.
TriangleMesh parse_obj(std::string_view text, const std::string& source, const std::filesystem::path& base_dir,
                       const MeshReadOptions& options = {}, Warnings* warnings = nullptr);
TriangleMesh parse_ply(std::span<const uint8_t> bytes, const std::string& source, const std::filesystem::path& base_dir,
                       const MeshReadOptions& options = {}, Warnings* warnings = nullptr);

enum class PlyEncoding { kBinaryLittleEndian, kAscii };

struct MeshWriteOptions {
  PlyEncoding ply_encoding = PlyEncoding::kBinaryLittleEndian;
  // OBJ only: write NAME.mtl beside NAME.obj referencing mesh.texture (when the mesh has one).
  bool write_material = true;
  // Text formats: significant digits of coordinates; 0 writes the shortest text that reads back
  // bit-exact (up to 17 digits). 7 is float precision: 0.1 µm on a face in metres.
  int significant_digits = 0;
};

// Writes .obj (+ .mtl) or .ply by extension, each file atomically (temporary name, then rename),
// so a failure never leaves a half-written file in place of a good one. Throws kIo / kInvalidArgument.
void write_mesh(const std::filesystem::path& path, const TriangleMesh& mesh, const MeshWriteOptions& options = {});

// The OBJ text of `mesh`; `material_library` (may be empty) is referenced with mtllib/usemtl.
std::string format_obj(const TriangleMesh& mesh, const std::string& material_library, int significant_digits = 0);

// The PLY bytes of `mesh`. Per-corner UVs go in a face property `texcoord` (MeshLab's layout),
// the texture in a `comment TextureFile NAME` header line.
std::vector<uint8_t> format_ply(const TriangleMesh& mesh, PlyEncoding encoding, const std::string& texture_name);

}  // namespace facemorph
