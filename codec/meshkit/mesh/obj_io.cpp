// Wavefront OBJ + MTL reading and writing.
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include "codec/meshkit/mesh/text_scan.hpp"
#include "format/file_io.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

namespace facemorph {
namespace fs = std::filesystem;

namespace {

struct Corner {
  int32_t vertex = -1;
  int32_t uv = -1;  // -1: none
};

[[noreturn]] void obj_fail(ErrorCode code, const std::string& source, size_t line, const std::string& why) {
  throw Error(code, source + ":" + std::to_string(line) + ": " + why);
}

// Resolves an OBJ index (1-based, or negative = relative to the end) against `count` elements.
int32_t resolve_index(std::string_view token, size_t count, const char* kind, const std::string& source, size_t line) {
  bool too_large = false;  // a whole integer beyond int64 is out of range, not malformed
  const auto value = text::parse_int(token, &too_large);
  if (!value && !too_large) {
    obj_fail(ErrorCode::kParse, source, line, std::string("malformed ") + kind + " index '" + std::string(token) + "'");
  }
  // value >= INT64_MIN and count < 2^63: neither adjustment can overflow.
  const int64_t index = !value ? -1 : *value < 0 ? *value + static_cast<int64_t>(count) : *value - 1;
  // Indices are int32 in memory: elements past the first 2^31 cannot be referenced.
  const int64_t usable = std::min<int64_t>(static_cast<int64_t>(count), int64_t{std::numeric_limits<int32_t>::max()} + 1);
  if (!value || *value == 0 || index < 0 || index >= usable) {
    obj_fail(ErrorCode::kInvalidMesh, source, line,
             std::string(kind) + " index " + std::string(token) + " out of range (" + std::to_string(count) + " defined so far)");
  }
  return static_cast<int32_t>(index);
}

// Parses "v", "v/vt", "v/vt/vn" or "v//vn".
Corner parse_corner(std::string_view token, size_t vertex_count, size_t uv_count, size_t normal_count, const std::string& source,
                    size_t line) {
  Corner corner;
  const size_t slash1 = token.find('/');
  corner.vertex = resolve_index(token.substr(0, slash1), vertex_count, "vertex", source, line);
  if (slash1 == std::string_view::npos) return corner;
  std::string_view rest = token.substr(slash1 + 1);
  const size_t slash2 = rest.find('/');
  const std::string_view uv_token = rest.substr(0, slash2);
  if (!uv_token.empty()) corner.uv = resolve_index(uv_token, uv_count, "texture-coordinate", source, line);
  if (slash2 != std::string_view::npos) {
    const std::string_view normal_token = rest.substr(slash2 + 1);
    if (!normal_token.empty()) (void)resolve_index(normal_token, normal_count, "normal", source, line);
  }
  return corner;
}

// OBJ/MTL file names may contain options before them ("map_Kd -s 1 1 1 skin.png"): the image is the
// last token. Names with spaces are not supported (documented in spec/capture.md).
std::string_view last_token(std::string_view rest) {
  std::string_view last;
  for (std::string_view token = text::next_token(rest); !token.empty(); token = text::next_token(rest)) {
    last = token;
  }
  return last;
}

// Finds map_Kd of `material` (or of the first material with a map_Kd when `material` is empty).
std::string find_diffuse_map(std::string_view mtl_text, const std::string& material) {
  text::LineScanner lines(mtl_text);
  std::string_view line;
  std::string current;
  std::string first_map;
  while (lines.next(line)) {
    std::string_view rest = line;
    const std::string_view keyword = text::next_token(rest);
    if (keyword == "newmtl") {
      current = std::string(text::trim(rest));
    } else if (keyword == "map_Kd") {
      const std::string name(last_token(rest));
      if (name.empty()) continue;
      if (!material.empty() && current == material) return name;
      if (first_map.empty()) first_map = name;
    }
  }
  return material.empty() ? first_map : std::string();
}

// The colour after a "v" line's coordinates: "v x y z r g b" (r, g, b in [0, 1]); nothing after them,
// or a single w (the rational weight some writers add), is no colour.
std::optional<Vec3> vertex_colour(std::string_view rest, const std::string& source, size_t line) {
  std::string_view tokens[4];
  int count = 0;
  for (std::string_view token = text::next_token(rest); !token.empty(); token = text::next_token(rest)) {
    if (count == 4) break;
    tokens[count++] = token;
  }
  if (count <= 1) return std::nullopt;
  if (count != 3) obj_fail(ErrorCode::kParse, source, line, "malformed v line: expected x y z, x y z w or x y z r g b");
  Vec3 colour;
  for (int k = 0; k < 3; ++k) {
    const auto value = text::parse_double(tokens[k]);
    if (!value) obj_fail(ErrorCode::kParse, source, line, "malformed vertex colour '" + std::string(tokens[k]) + "'");
    if (!(*value >= 0 && *value <= 1)) {
      obj_fail(ErrorCode::kInvalidMesh, source, line, "vertex colour '" + std::string(tokens[k]) + "' outside [0, 1]");
    }
    colour[k] = *value;
  }
  return colour;
}

void append_number(std::string& out, double value, int significant_digits) {
  char buffer[48];
  auto result = significant_digits > 0
                    ? std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::general, significant_digits)
                    : std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

void append_int(std::string& out, int64_t value) {
  char buffer[24];
  auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

}  // namespace

TriangleMesh parse_obj(std::string_view text_data, const std::string& source, const fs::path& base_dir, const MeshReadOptions& options,
                       Warnings* warnings) {
  TriangleMesh mesh;
  size_t normal_count = 0;
  size_t polygons = 0;
  size_t faces_with_uv = 0;
  size_t faces_without_uv = 0;
  std::vector<std::string> libraries;
  std::string material;
  std::vector<Face> uv_faces;
  std::vector<Corner> corners;

  text::LineScanner lines(text_data);
  std::string_view line;
  while (lines.next(line)) {
    std::string_view rest = line;
    const std::string_view keyword = text::next_token(rest);
    if (keyword.empty() || keyword.front() == '#') continue;
    if (keyword == "v" || keyword == "vt") {
      const int needed = keyword == "v" ? 3 : 2;
      double values[3] = {0, 0, 0};
      for (int k = 0; k < needed; ++k) {
        const std::string_view token = text::next_token(rest);
        const auto value = text::parse_double(token);
        if (!value) {
          obj_fail(ErrorCode::kParse, source, lines.line_number(),
                   std::string("malformed ") + std::string(keyword) + " line: expected " + std::to_string(needed) + " numbers");
        }
        if (!std::isfinite(*value)) {
          obj_fail(ErrorCode::kInvalidMesh, source, lines.line_number(),
                   std::string(keyword) + " line: non-finite coordinate '" + std::string(token) + "'");
        }
        values[k] = *value;
      }
      if (keyword == "v") {
        mesh.positions.emplace_back(values[0], values[1], values[2]);
        if (const auto colour = vertex_colour(rest, source, lines.line_number())) {
          mesh.colours.resize(mesh.positions.size() - 1, Vec3::Constant(-1));  // -1: a vertex without colour
          mesh.colours.push_back(*colour);
        }
      } else {
        mesh.uvs.emplace_back(values[0], values[1]);
      }
    } else if (keyword == "vn") {
      ++normal_count;
    } else if (keyword == "f") {
      corners.clear();
      for (std::string_view token = text::next_token(rest); !token.empty(); token = text::next_token(rest)) {
        corners.push_back(parse_corner(token, mesh.positions.size(), mesh.uvs.size(), normal_count, source, lines.line_number()));
      }
      if (corners.size() < 3) {
        obj_fail(ErrorCode::kParse, source, lines.line_number(),
                 "face with " + std::to_string(corners.size()) + " corners (at least 3 needed)");
      }
      bool has_uv = true;
      for (const Corner& c : corners) has_uv = has_uv && c.uv >= 0;
      if (corners.size() > 3) ++polygons;
      for (size_t k = 1; k + 1 < corners.size(); ++k) {
        mesh.faces.push_back({corners[0].vertex, corners[k].vertex, corners[k + 1].vertex});
        if (has_uv) {
          uv_faces.push_back({corners[0].uv, corners[k].uv, corners[k + 1].uv});
          ++faces_with_uv;
        } else {
          uv_faces.push_back({-1, -1, -1});
          ++faces_without_uv;
        }
      }
    } else if (keyword == "mtllib") {
      for (std::string_view token = text::next_token(rest); !token.empty(); token = text::next_token(rest)) {
        libraries.emplace_back(token);
      }
    } else if (keyword == "usemtl") {
      if (material.empty()) material = std::string(text::trim(rest));
    }
    // o, g, s, l, p, and vendor keywords carry nothing facemorph uses.
  }

  if (polygons > 0 && warnings) {
    warnings->push_back(source + ": " + std::to_string(polygons) + " polygon faces fan-triangulated");
  }
  if (!mesh.colours.empty()) {
    // Colour on some vertices only: no colour a vertex could stand for the others', so none.
    mesh.colours.resize(mesh.positions.size(), Vec3::Constant(-1));
    const auto without = std::count_if(mesh.colours.begin(), mesh.colours.end(), [](const Vec3& c) { return c.x() < 0; });
    if (without > 0) {
      if (warnings) warnings->push_back(source + ": " + std::to_string(without) + " vertices lack a colour; vertex colours dropped");
      mesh.colours.clear();
    }
  }
  if (faces_with_uv > 0 && faces_without_uv == 0) {
    mesh.uv_faces = std::move(uv_faces);
  } else {
    if (faces_with_uv > 0 && warnings) {
      warnings->push_back(source + ": " + std::to_string(faces_without_uv) +
                          " faces lack texture coordinates; texture coordinates dropped");
    }
    mesh.uvs.clear();
  }

  auto missing = [&](const std::string& why) {
    if (!options.allow_missing_texture) throw Error(ErrorCode::kMissingTexture, source + ": " + why);
    if (warnings) warnings->push_back(source + ": " + why + "; reading without texture");
  };
  for (const std::string& library : libraries) {
    const fs::path library_path = base_dir / library;
    std::vector<uint8_t> bytes;
    try {
      bytes = format::read_file(library_path, uint64_t{1} << 26);
    } catch (const Error&) {
      missing("material library " + library + " not found");
      continue;
    }
    const std::string map = find_diffuse_map(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), material);
    if (map.empty()) continue;
    const fs::path texture = base_dir / map;
    std::error_code ec;
    if (!fs::is_regular_file(texture, ec)) {
      missing("texture image " + map + " (map_Kd in " + library + ") not found");
    } else {
      mesh.texture = texture;
    }
    break;
  }
  return mesh;
}

std::string format_obj(const TriangleMesh& mesh, const std::string& material_library, int significant_digits) {
  std::string out;
  out.reserve(mesh.positions.size() * 40 + mesh.faces.size() * 30 + mesh.uvs.size() * 28);
  out += "# facemorph\n";
  if (!material_library.empty()) out += "mtllib " + material_library + "\nusemtl face\n";
  const bool colours = mesh.has_colours();
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3& p = mesh.positions[v];
    out += "v ";
    append_number(out, p.x(), significant_digits);
    out += ' ';
    append_number(out, p.y(), significant_digits);
    out += ' ';
    append_number(out, p.z(), significant_digits);
    for (int k = 0; k < 3 && colours; ++k) {
      out += ' ';
      append_number(out, mesh.colours[v][k], significant_digits);
    }
    out += '\n';
  }
  const bool uv = mesh.has_uvs();
  if (uv) {
    for (const Vec2& t : mesh.uvs) {
      out += "vt ";
      append_number(out, t.x(), significant_digits);
      out += ' ';
      append_number(out, t.y(), significant_digits);
      out += '\n';
    }
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    out += 'f';
    for (int k = 0; k < 3; ++k) {
      out += ' ';
      append_int(out, int64_t{mesh.faces[f][k]} + 1);
      if (uv) {
        out += '/';
        append_int(out, int64_t{mesh.uv_faces[f][k]} + 1);
      }
    }
    out += '\n';
  }
  return out;
}

void write_obj_files(const fs::path& path, const TriangleMesh& mesh, const MeshWriteOptions& options) {
  std::string library;
  if (options.write_material && !mesh.texture.empty()) {
    fs::path mtl_path = path;
    mtl_path.replace_extension(".mtl");
    library = mtl_path.filename().string();
    std::error_code ec;
    fs::path texture = fs::relative(mesh.texture, path.parent_path().empty() ? "." : path.parent_path(), ec);
    if (ec || texture.empty()) texture = fs::absolute(mesh.texture, ec);
    const std::string mtl = "# facemorph\nnewmtl face\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nillum 1\nmap_Kd " + texture.generic_string() + "\n";
    format::write_file_atomically(mtl_path, std::string_view(mtl));
  }
  format::write_file_atomically(path, std::string_view(format_obj(mesh, library, options.significant_digits)));
}

}  // namespace facemorph
