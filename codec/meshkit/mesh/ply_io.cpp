// PLY reading (ASCII, binary little/big endian) and writing (ASCII, binary little endian).
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include "codec/meshkit/mesh/text_scan.hpp"
#include "format/byte_reader.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace facemorph {
namespace fs = std::filesystem;

namespace {

enum class ScalarType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

std::optional<ScalarType> parse_scalar_type(std::string_view name) {
  if (name == "char" || name == "int8") return ScalarType::kInt8;
  if (name == "uchar" || name == "uint8") return ScalarType::kUint8;
  if (name == "short" || name == "int16") return ScalarType::kInt16;
  if (name == "ushort" || name == "uint16") return ScalarType::kUint16;
  if (name == "int" || name == "int32") return ScalarType::kInt32;
  if (name == "uint" || name == "uint32") return ScalarType::kUint32;
  if (name == "float" || name == "float32") return ScalarType::kFloat32;
  if (name == "double" || name == "float64") return ScalarType::kFloat64;
  return std::nullopt;
}

size_t scalar_size(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUint8: return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16: return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32: return 4;
    case ScalarType::kFloat64: return 8;
  }
  return 1;
}

bool is_integer(ScalarType type) { return type != ScalarType::kFloat32 && type != ScalarType::kFloat64; }

struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

enum class Encoding { kAscii, kBinaryLittle, kBinaryBig };

struct Header {
  Encoding encoding = Encoding::kAscii;
  std::vector<Element> elements;
  std::string texture_file;
  size_t body_offset = 0;
};

[[noreturn]] void ply_fail(ErrorCode code, const std::string& source, const std::string& why) { throw Error(code, source + ": " + why); }

Header parse_header(std::span<const uint8_t> bytes, const std::string& source) {
  // The header is text up to and including "end_header\n"; bound it so a binary blob is not scanned whole.
  const size_t limit = std::min<size_t>(bytes.size(), 1 << 20);
  const std::string_view head(reinterpret_cast<const char*>(bytes.data()), limit);
  const size_t end = head.find("end_header");
  if (head.substr(0, 3) != "ply") ply_fail(ErrorCode::kParse, source, "not a PLY file (no 'ply' magic)");
  if (end == std::string_view::npos) ply_fail(ErrorCode::kTruncated, source, "PLY header has no end_header line");
  size_t body = head.find('\n', end);
  if (body == std::string_view::npos) ply_fail(ErrorCode::kTruncated, source, "PLY header ends without a newline");
  Header header;
  header.body_offset = body + 1;
  bool have_format = false;
  text::LineScanner lines(head.substr(0, end));
  std::string_view line;
  lines.next(line);  // "ply"
  while (lines.next(line)) {
    std::string_view rest = line;
    const std::string_view keyword = text::next_token(rest);
    const auto where = " (header line " + std::to_string(lines.line_number()) + ")";
    if (keyword == "format") {
      const std::string_view kind = text::next_token(rest);
      if (kind == "ascii")
        header.encoding = Encoding::kAscii;
      else if (kind == "binary_little_endian")
        header.encoding = Encoding::kBinaryLittle;
      else if (kind == "binary_big_endian")
        header.encoding = Encoding::kBinaryBig;
      else
        ply_fail(ErrorCode::kUnsupported, source, "unknown PLY format '" + std::string(kind) + "'" + where);
      have_format = true;
    } else if (keyword == "comment") {
      std::string_view comment = rest;
      if (text::next_token(comment) == "TextureFile") header.texture_file = std::string(text::trim(comment));
    } else if (keyword == "element") {
      Element element;
      element.name = std::string(text::next_token(rest));
      const std::string_view count_token = text::next_token(rest);
      bool too_large = false;
      const auto count = text::parse_int(count_token, &too_large);
      if (element.name.empty() || (!count && !too_large)) ply_fail(ErrorCode::kParse, source, "malformed element line" + where);
      // Vertex indices are int32 in memory, so no element may hold more.
      if (!count || *count < 0 || *count > std::numeric_limits<int32_t>::max()) {
        ply_fail(ErrorCode::kCorrupt, source,
                 "element '" + element.name + "' count " + std::string(count_token) + " out of range (0.." +
                     std::to_string(std::numeric_limits<int32_t>::max()) + ")" + where);
      }
      element.count = static_cast<uint64_t>(*count);
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) ply_fail(ErrorCode::kParse, source, "property before any element" + where);
      Property property;
      std::string_view type = text::next_token(rest);
      if (type == "list") {
        property.is_list = true;
        const auto count_type = parse_scalar_type(text::next_token(rest));
        const auto item_type = parse_scalar_type(text::next_token(rest));
        if (!count_type || !item_type || !is_integer(*count_type)) {
          ply_fail(ErrorCode::kParse, source, "malformed list property" + where);
        }
        property.count_type = *count_type;
        property.type = *item_type;
      } else {
        const auto scalar = parse_scalar_type(type);
        if (!scalar) ply_fail(ErrorCode::kParse, source, "unknown property type '" + std::string(type) + "'" + where);
        property.type = *scalar;
      }
      property.name = std::string(text::next_token(rest));
      if (property.name.empty()) ply_fail(ErrorCode::kParse, source, "property without a name" + where);
      header.elements.back().properties.push_back(std::move(property));
    } else if (keyword == "obj_info" || keyword.empty()) {
      continue;
    } else {
      ply_fail(ErrorCode::kParse, source, "unknown header keyword '" + std::string(keyword) + "'" + where);
    }
  }
  if (!have_format) ply_fail(ErrorCode::kParse, source, "PLY header has no format line");
  return header;
}

// Reads scalars from either encoding, so element decoding is written once.
class ValueSource {
 public:
  ValueSource(std::span<const uint8_t> body, Encoding encoding, const std::string& source)
      : encoding_(encoding), binary_(body, source), text_(reinterpret_cast<const char*>(body.data()), body.size()), source_(source) {}

  double read(ScalarType type, const char* what) {
    if (encoding_ == Encoding::kAscii) return read_text(what);
    const bool big = encoding_ == Encoding::kBinaryBig;
    switch (type) {
      case ScalarType::kInt8: return binary_.read<int8_t>(what, big);
      case ScalarType::kUint8: return binary_.read<uint8_t>(what, big);
      case ScalarType::kInt16: return binary_.read<int16_t>(what, big);
      case ScalarType::kUint16: return binary_.read<uint16_t>(what, big);
      case ScalarType::kInt32: return binary_.read<int32_t>(what, big);
      case ScalarType::kUint32: return binary_.read<uint32_t>(what, big);
      case ScalarType::kFloat32: return binary_.read<float>(what, big);
      case ScalarType::kFloat64: return binary_.read<double>(what, big);
    }
    return 0;
  }

  size_t remaining_bytes() const { return encoding_ == Encoding::kAscii ? text_.size() : binary_.remaining(); }
  bool binary() const { return encoding_ != Encoding::kAscii; }

 private:
  double read_text(const char* what) {
    const std::string_view token = text::next_token(text_);
    if (token.empty()) ply_fail(ErrorCode::kTruncated, source_, std::string("truncated: ") + what + " missing");
    const auto value = text::parse_double(token);
    if (!value) ply_fail(ErrorCode::kParse, source_, std::string("malformed number '") + std::string(token) + "' in " + what);
    return *value;
  }

  Encoding encoding_;
  format::ByteReader binary_;
  std::string_view text_;
  const std::string& source_;
};

int find_property(const Element& element, std::initializer_list<const char*> names) {
  for (const char* name : names) {
    for (size_t i = 0; i < element.properties.size(); ++i) {
      if (!element.properties[i].is_list && element.properties[i].name == name) return static_cast<int>(i);
    }
  }
  return -1;
}

int find_list(const Element& element, std::initializer_list<const char*> names) {
  for (const char* name : names) {
    for (size_t i = 0; i < element.properties.size(); ++i) {
      if (element.properties[i].is_list && element.properties[i].name == name) return static_cast<int>(i);
    }
  }
  return -1;
}

// Smallest encoded size of one element: a guard against counts no file of this size can hold.
size_t minimum_element_bytes(const Element& element, bool binary) {
  size_t bytes = 0;
  for (const Property& p : element.properties) bytes += binary ? scalar_size(p.is_list ? p.count_type : p.type) : 2;
  return bytes;
}

std::string element_entry(const Element& element, uint64_t e) { return element.name + " " + std::to_string(e); }

// A list count read as double (ASCII text, or any integer type in binary), as a bounded integer.
uint64_t list_length(double value, const std::string& source, const Element& element, uint64_t e) {
  const auto length = text::to_integer(value, 0, 1'000'000);
  if (!length) {
    ply_fail(ErrorCode::kCorrupt, source, element_entry(element, e) + ": implausible list length " + text::format_number(value));
  }
  return static_cast<uint64_t>(*length);
}

// A face's vertex index read as double (the list type may be float or double) as an index into the
// vertices read so far: range-checked before the cast, which is undefined for 1e300.
int32_t vertex_index(double value, size_t vertex_count, const std::string& source, uint64_t face) {
  const std::string where = "face " + std::to_string(face) + ": vertex index " + text::format_number(value);
  if (!std::isfinite(value) || value != std::trunc(value)) ply_fail(ErrorCode::kCorrupt, source, where + " is not an integer");
  const auto index = text::to_integer(value, 0, static_cast<int64_t>(vertex_count) - 1);
  if (!index) {
    ply_fail(ErrorCode::kInvalidMesh, source, where + " out of range (" + std::to_string(vertex_count) + " vertices)");
  }
  return static_cast<int32_t>(*index);  // vertex_count <= int32 max: the header bounds element counts
}

// The scale that takes a colour property to [0, 1]: 8- and 16-bit unsigned integers are full range,
// floats are already in [0, 1]. Other types no scanner writes; refusing them beats guessing a range.
double colour_scale(const Property& property, const std::string& source) {
  switch (property.type) {
    case ScalarType::kUint8: return 1.0 / 255;
    case ScalarType::kUint16: return 1.0 / 65535;
    case ScalarType::kFloat32:
    case ScalarType::kFloat64: return 1.0;
    default:
      ply_fail(ErrorCode::kUnsupported, source,
               "vertex colour '" + property.name + "' has a type other than uchar, ushort, float or double");
  }
}

// A colour component as read (ASCII text, or the binary type), as a value in [0, 1]. Integer types
// must hold a whole number in their range; floats must lie in [0, 1].
double colour_value(double value, const Property& property, double scale, const std::string& source, const Element& element, uint64_t e) {
  const double limit = is_integer(property.type) ? 1 / scale : 1.0;
  const bool whole = !is_integer(property.type) || value == std::trunc(value);
  if (!std::isfinite(value) || !whole || value < 0 || value > limit) {
    ply_fail(ErrorCode::kInvalidMesh, source,
             element_entry(element, e) + ": colour " + property.name + " " + text::format_number(value) + " is not " +
                 (is_integer(property.type) ? "a whole number in [0, " + text::format_number(limit) + "]" : std::string("in [0, 1]")));
  }
  return value * scale;
}

}  // namespace

TriangleMesh parse_ply(std::span<const uint8_t> bytes, const std::string& source, const fs::path& base_dir, const MeshReadOptions& options,
                       Warnings* warnings) {
  const Header header = parse_header(bytes, source);
  ValueSource values(bytes.subspan(header.body_offset), header.encoding, source);
  TriangleMesh mesh;
  std::vector<Vec2> vertex_uvs;
  std::vector<Vec2> corner_uvs;
  bool have_vertices = false;
  bool have_faces = false;
  size_t polygons = 0;

  for (const Element& element : header.elements) {
    const size_t min_bytes = minimum_element_bytes(element, values.binary());
    if (min_bytes > 0 && element.count > values.remaining_bytes() / min_bytes + 1) {
      ply_fail(ErrorCode::kTruncated, source,
               "truncated: element '" + element.name + "' announces " + std::to_string(element.count) + " entries but only " +
                   std::to_string(values.remaining_bytes()) + " bytes remain");
    }
    if (min_bytes == 0) continue;  // no properties: nothing to read, whatever the count

    const bool is_vertex = element.name == "vertex";
    const bool is_face = element.name == "face";
    int ix = -1, iy = -1, iz = -1, iu = -1, iv = -1, ilist = -1, itex = -1;
    int icolour[3] = {-1, -1, -1};
    double colour_scales[3] = {1, 1, 1};
    if (is_vertex) {
      if (have_vertices) ply_fail(ErrorCode::kParse, source, "two vertex elements");
      ix = find_property(element, {"x"});
      iy = find_property(element, {"y"});
      iz = find_property(element, {"z"});
      if (ix < 0 || iy < 0 || iz < 0) ply_fail(ErrorCode::kParse, source, "vertex element lacks x, y or z");
      iu = find_property(element, {"s", "u", "texture_u", "texture_s"});
      iv = find_property(element, {"t", "v", "texture_v", "texture_t"});
      if (iu < 0 || iv < 0) iu = iv = -1;
      // Colour: red, green and blue together (alpha, when present, is read and ignored). One or two
      // of them is no colour a frame could be painted with: read past, said in a warning.
      icolour[0] = find_property(element, {"red", "diffuse_red"});
      icolour[1] = find_property(element, {"green", "diffuse_green"});
      icolour[2] = find_property(element, {"blue", "diffuse_blue"});
      const int colour_count = (icolour[0] >= 0) + (icolour[1] >= 0) + (icolour[2] >= 0);
      if (colour_count != 3) {
        if (colour_count > 0 && warnings)
          warnings->push_back(source + ": vertices have some of red, green and blue but not all three; colour ignored");
        icolour[0] = icolour[1] = icolour[2] = -1;
      }
      for (int c = 0; c < 3 && colour_count == 3; ++c)
        colour_scales[c] = colour_scale(element.properties[static_cast<size_t>(icolour[c])], source);
      mesh.positions.reserve(element.count);
      if (colour_count == 3) mesh.colours.reserve(element.count);
      have_vertices = true;
    } else if (is_face) {
      if (have_faces) ply_fail(ErrorCode::kParse, source, "two face elements");
      ilist = find_list(element, {"vertex_indices", "vertex_index"});
      if (ilist < 0) ply_fail(ErrorCode::kParse, source, "face element lacks vertex_indices");
      itex = find_list(element, {"texcoord"});
      have_faces = true;
    }

    std::vector<int32_t> polygon;
    std::vector<double> texcoords;
    for (uint64_t e = 0; e < element.count; ++e) {
      double scalar[3] = {0, 0, 0};
      double uv[2] = {0, 0};
      Vec3 colour = Vec3::Zero();
      polygon.clear();
      texcoords.clear();
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        const int pi = static_cast<int>(p);
        if (property.is_list) {
          const uint64_t n = list_length(values.read(property.count_type, "list length"), source, element, e);
          for (uint64_t k = 0; k < n; ++k) {
            const double value = values.read(property.type, element.name.c_str());
            if (pi == ilist)
              polygon.push_back(vertex_index(value, mesh.positions.size(), source, e));
            else if (pi == itex)
              texcoords.push_back(value);
          }
        } else {
          const double value = values.read(property.type, element.name.c_str());
          if (pi == ix)
            scalar[0] = value;
          else if (pi == iy)
            scalar[1] = value;
          else if (pi == iz)
            scalar[2] = value;
          else if (pi == iu)
            uv[0] = value;
          else if (pi == iv)
            uv[1] = value;
          for (int c = 0; c < 3; ++c) {
            if (pi == icolour[c]) colour[c] = colour_value(value, property, colour_scales[c], source, element, e);
          }
        }
      }
      if (is_vertex) {
        mesh.positions.emplace_back(scalar[0], scalar[1], scalar[2]);
        if (iu >= 0) vertex_uvs.emplace_back(uv[0], uv[1]);
        if (icolour[0] >= 0) mesh.colours.push_back(colour);
        if (!mesh.positions.back().allFinite() || (iu >= 0 && !vertex_uvs.back().allFinite())) {
          ply_fail(ErrorCode::kInvalidMesh, source, element_entry(element, e) + " has a non-finite coordinate");
        }
      } else if (is_face) {
        if (polygon.size() < 3) {
          ply_fail(ErrorCode::kParse, source, "face " + std::to_string(e) + " has " + std::to_string(polygon.size()) + " corners");
        }
        for (double t : texcoords) {
          if (!std::isfinite(t))
            ply_fail(ErrorCode::kInvalidMesh, source, element_entry(element, e) + " has a non-finite texture coordinate");
        }
        const bool corner_uv = itex >= 0 && texcoords.size() == 2 * polygon.size();
        if (polygon.size() > 3) ++polygons;
        for (size_t k = 1; k + 1 < polygon.size(); ++k) {
          mesh.faces.push_back({polygon[0], polygon[k], polygon[k + 1]});
          if (corner_uv) {
            for (size_t c : {size_t{0}, k, k + 1}) corner_uvs.emplace_back(texcoords[2 * c], texcoords[2 * c + 1]);
          }
        }
      }
    }
  }
  if (!have_vertices) ply_fail(ErrorCode::kParse, source, "no vertex element");
  if (!have_faces) ply_fail(ErrorCode::kParse, source, "no face element (point clouds are not surfaces)");
  if (polygons > 0 && warnings) {
    warnings->push_back(source + ": " + std::to_string(polygons) + " polygon faces fan-triangulated");
  }

  if (corner_uvs.size() == 3 * mesh.faces.size() && !mesh.faces.empty()) {
    mesh.uvs = std::move(corner_uvs);
    mesh.uv_faces.resize(mesh.faces.size());
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const auto base = static_cast<int32_t>(3 * f);
      mesh.uv_faces[f] = {base, base + 1, base + 2};
    }
  } else if (!vertex_uvs.empty()) {
    mesh.uvs = std::move(vertex_uvs);
    mesh.uv_faces = mesh.faces;
  }
  if (!header.texture_file.empty()) {
    const fs::path texture = base_dir / header.texture_file;
    std::error_code ec;
    if (fs::is_regular_file(texture, ec)) {
      mesh.texture = texture;
    } else if (!options.allow_missing_texture) {
      ply_fail(ErrorCode::kMissingTexture, source, "texture image " + header.texture_file + " not found");
    } else if (warnings) {
      warnings->push_back(source + ": texture image " + header.texture_file + " not found; reading without texture");
    }
  }
  return mesh;
}

std::vector<uint8_t> format_ply(const TriangleMesh& mesh, PlyEncoding encoding, const std::string& texture_name) {
  const bool ascii = encoding == PlyEncoding::kAscii;
  const bool uv = mesh.has_uvs();
  std::string head = "ply\nformat ";
  head += ascii ? "ascii 1.0\n" : "binary_little_endian 1.0\n";
  head += "comment facemorph\n";
  if (!texture_name.empty()) head += "comment TextureFile " + texture_name + "\n";
  head += "element vertex " + std::to_string(mesh.positions.size()) + "\n";
  head += "property double x\nproperty double y\nproperty double z\n";
  const bool colours = mesh.has_colours();
  if (colours) head += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  head += "element face " + std::to_string(mesh.faces.size()) + "\n";
  head += "property list uchar int vertex_indices\n";
  if (uv) head += "property list uchar float texcoord\n";
  head += "end_header\n";

  std::vector<uint8_t> out(head.begin(), head.end());
  auto put = [&out](const void* data, size_t n) {
    const auto* p = static_cast<const uint8_t*>(data);
    out.insert(out.end(), p, p + n);  // x86-64 and aarch64 hosts are little-endian
  };
  auto put_text = [&out](std::string_view s) { out.insert(out.end(), s.begin(), s.end()); };
  char buffer[32];
  // Shortest round-trip text for floats; plain decimal for indices (never "1e+06").
  auto number = [&](auto value) {
    auto r = std::to_chars(buffer, buffer + sizeof buffer, value);
    return std::string_view(buffer, static_cast<size_t>(r.ptr - buffer));
  };
  static_assert(std::endian::native == std::endian::little, "binary PLY writer assumes a little-endian host");
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3& p = mesh.positions[v];
    uint8_t rgb[3] = {0, 0, 0};
    if (colours) {
      // 8 bits a channel, as scanners write them: k / 255 reads back exactly.
      for (int k = 0; k < 3; ++k) rgb[k] = static_cast<uint8_t>(std::clamp(std::lround(255 * mesh.colours[v][k]), 0L, 255L));
    }
    if (ascii) {
      for (int k = 0; k < 3; ++k) {
        put_text(number(p[k]));
        put_text(k < 2 || colours ? " " : "\n");
      }
      for (int k = 0; k < 3 && colours; ++k) {
        put_text(number(int{rgb[k]}));
        put_text(k < 2 ? " " : "\n");
      }
    } else {
      put(p.data(), 3 * sizeof(double));
      if (colours) put(rgb, sizeof rgb);
    }
  }
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (ascii) {
      put_text("3");
      for (int k = 0; k < 3; ++k) {
        put_text(" ");
        put_text(number(mesh.faces[f][k]));
      }
      if (uv) {
        put_text(" 6");
        for (int k = 0; k < 3; ++k) {
          const Vec2& t = mesh.uvs[static_cast<size_t>(mesh.uv_faces[f][k])];
          put_text(" ");
          put_text(number(static_cast<float>(t.x())));
          put_text(" ");
          put_text(number(static_cast<float>(t.y())));
        }
      }
      put_text("\n");
    } else {
      const uint8_t three = 3;
      put(&three, 1);
      put(mesh.faces[f].data(), 3 * sizeof(int32_t));
      if (uv) {
        const uint8_t six = 6;
        put(&six, 1);
        for (int k = 0; k < 3; ++k) {
          const Vec2& t = mesh.uvs[static_cast<size_t>(mesh.uv_faces[f][k])];
          const float st[2] = {static_cast<float>(t.x()), static_cast<float>(t.y())};
          put(st, sizeof st);
        }
      }
    }
  }
  return out;
}

}  // namespace facemorph
