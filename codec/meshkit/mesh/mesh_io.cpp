// Format dispatch for mesh files: by extension, with atomic writes.
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include "format/file_io.hpp"

#include <algorithm>
#include <cctype>

namespace facemorph {
namespace fs = std::filesystem;

void write_obj_files(const fs::path& path, const TriangleMesh& mesh, const MeshWriteOptions& options);

namespace {

std::string lower_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace

TriangleMesh read_mesh(const fs::path& path, const MeshReadOptions& options, Warnings* warnings) {
  const std::string ext = lower_extension(path);
  if (ext != ".obj" && ext != ".ply") {
    throw Error(ErrorCode::kUnsupported, path.string() + ": unknown mesh format '" + ext + "' (expected .obj or .ply)");
  }
  const std::vector<uint8_t> bytes = format::read_file(path);
  const fs::path base = path.parent_path();
  if (ext == ".obj") {
    return parse_obj(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path.string(), base, options, warnings);
  }
  return parse_ply(bytes, path.string(), base, options, warnings);
}

void write_mesh(const fs::path& path, const TriangleMesh& mesh, const MeshWriteOptions& options) {
  const std::string ext = lower_extension(path);
  if (ext == ".obj") {
    write_obj_files(path, mesh, options);
  } else if (ext == ".ply") {
    std::string texture;
    if (!mesh.texture.empty()) {
      std::error_code ec;
      fs::path relative = fs::relative(mesh.texture, path.parent_path().empty() ? "." : path.parent_path(), ec);
      texture = (ec || relative.empty()) ? mesh.texture.generic_string() : relative.generic_string();
    }
    format::write_file_atomically(path, format_ply(mesh, options.ply_encoding, texture));
  } else {
    throw Error(ErrorCode::kInvalidArgument, path.string() + ": unknown mesh format '" + ext + "' (expected .obj or .ply)");
  }
}

}  // namespace facemorph
