#include "codec/meshkit/mesh/mesh_io.hpp"

#include "format/file_io.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace facemorph {
namespace {

using testing::expect_error;
using testing::TempDir;
using testing::write_text;

TriangleMesh textured_square() {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5}, {0, 1, 0.25}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.uv_faces = m.faces;
  return m;
}

// An input that must fail: its error code and a fragment of the message.
struct BadInput {
  ErrorCode code;
  std::string fragment;
  std::string input;
};

// Each input handed to `parse` must throw its named error.
template <typename Parse>
void expect_errors(const std::vector<BadInput>& cases, Parse&& parse) {
  for (const BadInput& c : cases) {
    SCOPED_TRACE(c.input);
    expect_error(c.code, c.fragment, [&] { parse(c.input); });
  }
}

void expect_same_geometry(const TriangleMesh& a, const TriangleMesh& b, double tol) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  ASSERT_EQ(a.faces.size(), b.faces.size());
  for (size_t i = 0; i < a.positions.size(); ++i) EXPECT_LE((a.positions[i] - b.positions[i]).norm(), tol);
  for (size_t f = 0; f < a.faces.size(); ++f) EXPECT_EQ(a.faces[f], b.faces[f]);
  ASSERT_EQ(a.has_uvs(), b.has_uvs());
  if (!a.has_uvs()) return;
  for (size_t f = 0; f < a.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vec2& ta = a.uvs[static_cast<size_t>(a.uv_faces[f][k])];
      const Vec2& tb = b.uvs[static_cast<size_t>(b.uv_faces[f][k])];
      EXPECT_LE((ta - tb).norm(), 1e-6);
    }
  }
}

TEST(ObjIo, RoundTripKeepsPositionsUvsAndTexture) {
  TempDir dir;
  write_text(dir / "skin.png", "not really a png; existence is what the reader checks");
  TriangleMesh m = textured_square();
  m.positions[1] = {0.1234567890123456789, -1e-7, 3e5};
  m.texture = dir / "skin.png";
  write_mesh(dir / "square.obj", m);
  const TriangleMesh back = read_mesh(dir / "square.obj");
  expect_same_geometry(m, back, 0.0);  // shortest round-trip decimal: bit exact
  EXPECT_EQ(back.texture, dir / "skin.png");
  EXPECT_TRUE(std::filesystem::exists(dir / "square.mtl"));
}

TEST(ObjIo, ParsesAllCornerFormsPolygonsAndRelativeIndices) {
  const std::string text =
      "# comment\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
      "g group\ns off\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";
  Warnings warnings;
  const TriangleMesh m = parse_obj(text, "quad.obj", ".", {}, &warnings);
  ASSERT_EQ(m.faces.size(), 2u);
  EXPECT_EQ(m.faces[0], (Face{0, 1, 2}));
  EXPECT_EQ(m.faces[1], (Face{0, 2, 3}));
  EXPECT_TRUE(m.has_uvs());
  EXPECT_EQ(warnings.size(), 1u);

  const TriangleMesh rel = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf -3//1 -2//1 -1//1\n", "rel.obj", ".");
  ASSERT_EQ(rel.faces.size(), 1u);
  EXPECT_EQ(rel.faces[0], (Face{0, 1, 2}));
  EXPECT_FALSE(rel.has_uvs());
}

TEST(ObjIo, BadInputIsANamedError) {
  expect_error(ErrorCode::kInvalidMesh, "bad.obj:4", [] { parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.obj", "."); });
  expect_error(ErrorCode::kInvalidMesh, "out of range", [] { parse_obj("v 0 0 0\nf 0 1 1\n", "zero.obj", "."); });
  expect_error(ErrorCode::kParse, "bad.obj:2", [] { parse_obj("v 0 0 0\nv 1 nan-ish 0\n", "bad.obj", "."); });
  expect_error(ErrorCode::kParse, "at least 3", [] { parse_obj("v 0 0 0\nv 1 0 0\nf 1 2\n", "two.obj", "."); });
  expect_error(ErrorCode::kParse, "malformed", [] { parse_obj("v 0 0 0\nv 1 0 0\nv 1 1 1\nf 1 2 x\n", "x.obj", "."); });
}

// Indices no integer type holds are out of range, found before any conversion (a cast of 1e20 to
// int64 is undefined); non-finite coordinates are rejected where they enter.
TEST(ObjIo, HugeIndicesAndNonFiniteCoordinatesAreNamedErrors) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\n";
  auto parse = [&](const std::string& face) { return parse_obj(tri + face + "\n", "big.obj", "."); };
  expect_errors(
      {{ErrorCode::kInvalidMesh, "big.obj:5: vertex index 99999999999999999999 out of range", "f 99999999999999999999 1 2"},
       {ErrorCode::kInvalidMesh, "vertex index -99999999999999999999 out of range", "f -99999999999999999999 1 2"},
       {ErrorCode::kInvalidMesh, "vertex index -9223372036854775808 out of range", "f -9223372036854775808 1 2"},
       {ErrorCode::kInvalidMesh, "vertex index 9223372036854775807 out of range", "f 9223372036854775807 1 2"},
       {ErrorCode::kInvalidMesh, "vertex index -4 out of range", "f -4 1 2"},
       {ErrorCode::kInvalidMesh, "texture-coordinate index 18446744073709551617 out of range", "f 1/18446744073709551617 2/1 3/1"},
       {ErrorCode::kInvalidMesh, "texture-coordinate index -2 out of range", "f 1/-2 2/1 3/1"},
       {ErrorCode::kParse, "malformed vertex index '1e300'", "f 1e300 1 2"},
       {ErrorCode::kParse, "malformed vertex index '2.5'", "f 2.5 1 2"},
       {ErrorCode::kParse, "malformed vertex index '+-1'", "f +-1 1 2"},
       {ErrorCode::kInvalidMesh, "big.obj:5: v line: non-finite coordinate 'nan'", "v 1 nan 0"},
       {ErrorCode::kInvalidMesh, "big.obj:5: vt line: non-finite coordinate '-inf'", "vt 0 -inf"},
       {ErrorCode::kParse, "big.obj:5: malformed v line", "v 0 1e999 0"}},
      parse);
  EXPECT_EQ(parse("f +1 -2 3").faces[0], (Face{0, 1, 2}));
}

TEST(ObjIo, MissingTextureIsAnErrorUnlessAllowed) {
  TempDir dir;
  write_text(dir / "a.obj", "mtllib a.mtl\nusemtl face\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_error(ErrorCode::kMissingTexture, "a.mtl not found", [&] { read_mesh(dir / "a.obj"); });
  write_text(dir / "a.mtl", "newmtl face\nmap_Kd -s 1 1 1 skin.jpg\n");
  expect_error(ErrorCode::kMissingTexture, "skin.jpg", [&] { read_mesh(dir / "a.obj"); });
  Warnings warnings;
  const TriangleMesh m = read_mesh(dir / "a.obj", {.allow_missing_texture = true}, &warnings);
  EXPECT_TRUE(m.texture.empty());
  EXPECT_EQ(warnings.size(), 1u);
  write_text(dir / "skin.jpg", "x");
  EXPECT_EQ(read_mesh(dir / "a.obj").texture, dir / "skin.jpg");
}

TEST(PlyIo, BinaryAndAsciiRoundTrip) {
  TempDir dir;
  const TriangleMesh m = textured_square();
  for (PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kAscii}) {
    write_mesh(dir / "m.ply", m, {.ply_encoding = encoding});
    expect_same_geometry(m, read_mesh(dir / "m.ply"), 0.0);
  }
}

TEST(PlyIo, ReadsPerVertexUvsPolygonsAndBigEndian) {
  const std::string ascii =
      "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nproperty float s\nproperty float t\nproperty uchar red\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n"
      "0 0 0 0 0 255\n1 0 0 1 0 255\n1 1 0 1 1 255\n0 1 0 0 1 255\n4 0 1 2 3\n";
  const TriangleMesh m = parse_ply({reinterpret_cast<const uint8_t*>(ascii.data()), ascii.size()}, "a.ply", ".");
  ASSERT_EQ(m.faces.size(), 2u);
  ASSERT_TRUE(m.has_uvs());
  EXPECT_DOUBLE_EQ(m.uvs[2].y(), 1.0);

  std::string big =
      "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
      "property double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n";
  auto put_be = [&big](const void* p, size_t n) {
    for (size_t i = 0; i < n; ++i) big.push_back(static_cast<const char*>(p)[n - 1 - i]);
  };
  const double coords[9] = {0, 0, 0, 2.5, 0, 0, 0, -1.25, 0};
  for (double c : coords) put_be(&c, 8);
  big.push_back(3);
  for (uint32_t i : {0u, 1u, 2u}) put_be(&i, 4);
  const TriangleMesh b = parse_ply({reinterpret_cast<const uint8_t*>(big.data()), big.size()}, "b.ply", ".");
  ASSERT_EQ(b.positions.size(), 3u);
  EXPECT_DOUBLE_EQ(b.positions[1].x(), 2.5);
  EXPECT_DOUBLE_EQ(b.positions[2].y(), -1.25);
}

TEST(PlyIo, TruncatedAndCorruptFilesAreNamedErrors) {
  TriangleMesh m = textured_square();
  std::vector<uint8_t> bytes = format_ply(m, PlyEncoding::kBinaryLittleEndian, "");
  for (size_t cut : {bytes.size() - 1, bytes.size() - 20, bytes.size() / 2}) {
    std::vector<uint8_t> part(bytes.begin(), bytes.begin() + static_cast<long>(cut));
    expect_error(ErrorCode::kTruncated, "cut.ply", [&] { parse_ply(part, "cut.ply", "."); });
  }
  const std::string huge =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\n"
      "property float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
  expect_error(ErrorCode::kTruncated, "announces", [&] {
    parse_ply({reinterpret_cast<const uint8_t*>(huge.data()), huge.size()}, "huge.ply", ".");
  });
  const std::string not_ply = "solid cube\n";
  expect_error(ErrorCode::kParse, "not a PLY", [&] {
    parse_ply({reinterpret_cast<const uint8_t*>(not_ply.data()), not_ply.size()}, "x.ply", ".");
  });
  const std::vector<uint8_t> ascii_bytes = format_ply(m, PlyEncoding::kAscii, "");
  std::string ascii(ascii_bytes.begin(), ascii_bytes.end());
  ascii.resize(ascii.size() - 8);
  expect_error(ErrorCode::kTruncated, "truncated", [&] {
    parse_ply({reinterpret_cast<const uint8_t*>(ascii.data()), ascii.size()}, "t.ply", ".");
  });
  const std::string bad_index =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
  expect_error(ErrorCode::kInvalidMesh, "vertex index 7", [&] {
    parse_ply({reinterpret_cast<const uint8_t*>(bad_index.data()), bad_index.size()}, "i.ply", ".");
  });
}

// A PLY with one triangle whose index list is typed `index_type`, followed by `body`.
std::string triangle_ply(const std::string& encoding, const std::string& count_type, const std::string& index_type) {
  return "ply\nformat " + encoding +
         " 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 1\nproperty list " +
         count_type + " " + index_type + " vertex_indices\nend_header\n";
}

TriangleMesh parse_ply_text(const std::string& text, const std::string& name) {
  return parse_ply({reinterpret_cast<const uint8_t*>(text.data()), text.size()}, name, ".");
}

// A vertex index or list count is range-checked while still a double: converting 1e300 or NaN to
// an integer first is undefined behaviour (clang's -fsanitize=float-cast-overflow reports it).
TEST(PlyIo, AsciiIndicesAndCountsNoIntegerHoldsAreNamedErrors) {
  const std::string head = triangle_ply("ascii", "uchar", "int") + "0 0 0\n1 0 0\n0 1 0\n";
  auto face = [&](const std::string& row) { return parse_ply_text(head + row + "\n", "a.ply"); };
  expect_errors({{ErrorCode::kInvalidMesh, "a.ply: face 0: vertex index 1e+300 out of range (3 vertices)", "3 0 1 1e300"},
                 {ErrorCode::kInvalidMesh, "face 0: vertex index -1e+300 out of range", "3 -1e300 1 2"},
                 {ErrorCode::kInvalidMesh, "face 0: vertex index 9223372036854775808 out of range", "3 0 1 9223372036854775808"},
                 {ErrorCode::kCorrupt, "face 0: vertex index nan is not an integer", "3 0 nan 2"},
                 {ErrorCode::kCorrupt, "face 0: vertex index inf is not an integer", "3 0 1 inf"},
                 {ErrorCode::kCorrupt, "face 0: vertex index 2.5 is not an integer", "3 0 1 2.5"},
                 {ErrorCode::kCorrupt, "face 0: implausible list length 1e+300", "1e300 0 1 2"},
                 {ErrorCode::kCorrupt, "face 0: implausible list length 3.5", "3.5 0 1 2"},
                 {ErrorCode::kCorrupt, "face 0: implausible list length nan", "nan 0 1 2"}},
                face);
  EXPECT_EQ(face("+3 0 1 2.0").faces[0], (Face{0, 1, 2}));

  const std::string nan_vertex = triangle_ply("ascii", "uchar", "int") + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n";
  expect_error(ErrorCode::kInvalidMesh, "n.ply: vertex 1 has a non-finite coordinate", [&] { parse_ply_text(nan_vertex, "n.ply"); });
  std::string count = triangle_ply("ascii", "uchar", "int") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  count.replace(count.find("vertex 3"), 8, "vertex 99999999999999999999");
  expect_error(ErrorCode::kCorrupt, "c.ply: element 'vertex' count 99999999999999999999 out of range (0..2147483647) (header line 3)",
               [&] { parse_ply_text(count, "c.ply"); });
  count.replace(count.find("vertex 9"), 27, "vertex -1");
  expect_error(ErrorCode::kCorrupt, "element 'vertex' count -1 out of range", [&] { parse_ply_text(count, "c.ply"); });
  count.replace(count.find("vertex -1"), 9, "vertex 1e3");
  expect_error(ErrorCode::kParse, "malformed element line (header line 3)", [&] { parse_ply_text(count, "c.ply"); });
}

TEST(PlyIo, BinaryFloatIndicesNoIntegerHoldsAreNamedErrors) {
  for (const std::string index_type : {"float", "double"}) {
    auto face = [&](double a, double b, double c) {
      std::string bytes = triangle_ply("binary_little_endian", "uchar", index_type);
      auto put = [&bytes](const auto& value) { bytes.append(reinterpret_cast<const char*>(&value), sizeof value); };
      for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put(x);
      put(uint8_t{3});
      for (double v : {a, b, c}) {
        if (index_type == "float")
          put(static_cast<float>(v));
        else
          put(v);
      }
      return parse_ply_text(bytes, index_type + ".ply");
    };
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const double huge = index_type == "float" ? 0x1p100 : 1e300;  // exact in the list's type
    const std::string huge_text = index_type == "float" ? "1.2676506002282294e+30" : "1e+300";
    SCOPED_TRACE(index_type);
    expect_error(ErrorCode::kInvalidMesh, "face 0: vertex index " + huge_text + " out of range", [&] { face(0, 1, huge); });
    expect_error(ErrorCode::kInvalidMesh, "out of range (3 vertices)", [&] { face(-huge, 1, 2); });
    expect_error(ErrorCode::kInvalidMesh, "vertex index 4294967296 out of range", [&] { face(0, 4294967296.0, 2); });
    expect_error(ErrorCode::kCorrupt, "face 0: vertex index nan is not an integer", [&] { face(0, nan, 2); });
    expect_error(ErrorCode::kCorrupt, "face 0: vertex index -inf is not an integer", [&] { face(-inf, 1, 2); });
    expect_error(ErrorCode::kCorrupt, "face 0: vertex index 2.5 is not an integer", [&] { face(0, 1, 2.5); });
    EXPECT_EQ(face(2, 1, 0).faces[0], (Face{2, 1, 0}));
  }
}

TEST(MeshFiles, WritesAreAtomicAndFailuresNameTheFile) {
  TempDir dir;
  const TriangleMesh m = textured_square();
  std::filesystem::create_directory(dir / "taken.obj");  // a folder where the file should go
  expect_error(ErrorCode::kIo, "taken.obj", [&] { write_mesh(dir / "taken.obj", m); });
  size_t leftovers = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    leftovers += entry.path().filename().string().find(".tmp-") != std::string::npos;
  }
  EXPECT_EQ(leftovers, 0u);
  expect_error(ErrorCode::kIo, "missing.ply", [&] { read_mesh(dir / "missing.ply"); });
  expect_error(ErrorCode::kUnsupported, ".stl", [&] { read_mesh(dir / "x.stl"); });
}

// Vertex colours: PLY red/green/blue (+ alpha) as uchar or float, OBJ "v x y z r g b".
std::string coloured_ply_head(const std::string& encoding, const std::string& colour_type, bool alpha) {
  std::string head = "ply\nformat " + encoding + " 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  for (const char* c : {"red", "green", "blue"}) head += "property " + colour_type + " " + c + "\n";
  if (alpha) head += "property " + colour_type + " alpha\n";
  return head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
}

void expect_colours(const TriangleMesh& m, const std::vector<Vec3>& expected, double tolerance) {
  ASSERT_TRUE(m.has_colours());
  ASSERT_EQ(m.colours.size(), expected.size());
  for (size_t v = 0; v < expected.size(); ++v) EXPECT_LE((m.colours[v] - expected[v]).cwiseAbs().maxCoeff(), tolerance) << "vertex " << v;
}

TEST(PlyIo, ReadsVertexColoursAsciiAndBinaryUcharAndFloatWithAlpha) {
  const std::vector<Vec3> expected = {{1, 0, 0}, {0, 128 / 255.0, 1}, {51 / 255.0, 102 / 255.0, 153 / 255.0}};
  // ASCII uchar with alpha (ignored).
  const TriangleMesh a = parse_ply_text(
      coloured_ply_head("ascii", "uchar", true) + "0 0 0 255 0 0 255\n1 0 0 0 128 255 7\n0 1 0 51 102 153 0\n3 0 1 2\n", "a.ply");
  expect_colours(a, expected, 0.0);
  EXPECT_EQ(a.positions[1], Vec3(1, 0, 0));  // alpha does not shift the other properties
  // ASCII float without alpha.
  const TriangleMesh f = parse_ply_text(
      coloured_ply_head("ascii", "float", false) + "0 0 0 1 0 0\n1 0 0 0 0.50196078 1\n0 1 0 0.2 0.4 0.6\n3 0 1 2\n", "f.ply");
  expect_colours(f, expected, 1e-7);
  // Binary little-endian, uchar and float, with alpha.
  for (const std::string type : {"uchar", "float"}) {
    std::string bytes = coloured_ply_head("binary_little_endian", type, true);
    auto put = [&bytes](const auto& value) { bytes.append(reinterpret_cast<const char*>(&value), sizeof value); };
    const float xyz[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int v = 0; v < 3; ++v) {
      for (float x : xyz[v]) put(x);
      for (int c = 0; c < 4; ++c) {
        const double value = c < 3 ? expected[static_cast<size_t>(v)][c] : 1.0;
        if (type == "uchar")
          put(static_cast<uint8_t>(std::lround(255 * value)));
        else
          put(static_cast<float>(value));
      }
    }
    put(uint8_t{3});
    for (int32_t i : {0, 1, 2}) put(i);
    SCOPED_TRACE(type);
    expect_colours(parse_ply_text(bytes, type + ".ply"), expected, type == "uchar" ? 0.0 : 1e-7);
  }
  // 16-bit colours are full range too.
  const TriangleMesh wide = parse_ply_text(
      coloured_ply_head("ascii", "ushort", false) + "0 0 0 65535 0 0\n1 0 0 0 32896 65535\n0 1 0 13107 26214 39321\n3 0 1 2\n", "u.ply");
  expect_colours(wide, expected, 1e-15);
  // Without red/green/blue, no colours.
  EXPECT_FALSE(parse_ply_text(triangle_ply("ascii", "uchar", "int") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "n.ply").has_colours());
}

TEST(PlyIo, BadVertexColoursAreNamedErrors) {
  const std::string uchar = coloured_ply_head("ascii", "uchar", false), real = coloured_ply_head("ascii", "float", false);
  auto parse = [](const std::string& text) { return parse_ply_text(text + "1 0 0 0 0 0\n0 1 0 0 0 0\n3 0 1 2\n", "c.ply"); };
  expect_errors({{ErrorCode::kInvalidMesh, "c.ply: vertex 0: colour red 256 is not a whole number in [0, 255]", uchar + "0 0 0 256 0 0\n"},
                 {ErrorCode::kInvalidMesh, "vertex 0: colour green 1.5 is not a whole number", uchar + "0 0 0 0 1.5 0\n"},
                 {ErrorCode::kInvalidMesh, "vertex 0: colour blue -1 is not a whole number", uchar + "0 0 0 0 0 -1\n"},
                 {ErrorCode::kInvalidMesh, "c.ply: vertex 0: colour red 1.5 is not in [0, 1]", real + "0 0 0 1.5 0 0\n"},
                 {ErrorCode::kInvalidMesh, "vertex 0: colour green -0.25 is not in [0, 1]", real + "0 0 0 0 -0.25 0\n"},
                 {ErrorCode::kInvalidMesh, "vertex 0: colour blue nan is not in [0, 1]", real + "0 0 0 0 0 nan\n"},
                 {ErrorCode::kUnsupported, "vertex colour 'red' has a type other than uchar",
                  coloured_ply_head("ascii", "int", false) + "0 0 0 0 0 0\n"}},
                parse);
  Warnings warnings;
  const std::string partial =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0 1 2\n1 0 0 3 4\n0 1 0 5 6\n3 0 1 2\n";
  const TriangleMesh m = parse_ply({reinterpret_cast<const uint8_t*>(partial.data()), partial.size()}, "p.ply", ".", {}, &warnings);
  EXPECT_FALSE(m.has_colours());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("not all three"), std::string::npos);
}

TEST(ObjIo, ReadsVertexColoursAndBadOnesAreNamedErrors) {
  const TriangleMesh m = parse_obj("v 0 0 0 1 0 0\nv 1 0 0 0 0.5 1\nv 0 1 0 0.2 0.4 0.6\nf 1 2 3\n", "c.obj", ".");
  expect_colours(m, {{1, 0, 0}, {0, 0.5, 1}, {0.2, 0.4, 0.6}}, 0.0);
  EXPECT_EQ(m.positions[1], Vec3(1, 0, 0));
  // A weight w is no colour.
  EXPECT_FALSE(parse_obj("v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n", "w.obj", ".").has_colours());
  // Colour on some vertices only: dropped, with a warning.
  Warnings warnings;
  EXPECT_FALSE(parse_obj("v 0 0 0\nv 1 0 0 0 0.5 1\nv 0 1 0\nf 1 2 3\n", "some.obj", ".", {}, &warnings).has_colours());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("2 vertices lack a colour"), std::string::npos);
  auto parse = [](const std::string& text) { parse_obj(text + "v 1 0 0\nv 0 1 0\nf 1 2 3\n", "bad.obj", "."); };
  expect_errors({{ErrorCode::kInvalidMesh, "bad.obj:1: vertex colour '255' outside [0, 1]", "v 0 0 0 255 0 0\n"},
                 {ErrorCode::kInvalidMesh, "bad.obj:1: vertex colour '-0.1' outside [0, 1]", "v 0 0 0 0 -0.1 0\n"},
                 {ErrorCode::kInvalidMesh, "vertex colour 'nan' outside [0, 1]", "v 0 0 0 0 0 nan\n"},
                 {ErrorCode::kParse, "bad.obj:1: malformed vertex colour 'red'", "v 0 0 0 red 0 0\n"},
                 {ErrorCode::kParse, "bad.obj:1: malformed v line: expected x y z, x y z w or x y z r g b", "v 0 0 0 0.5 0.5\n"}},
                parse);
}

TEST(MeshFiles, VertexColoursRoundTripThroughObjAndBothPlyEncodings) {
  TempDir dir;
  TriangleMesh m = textured_square();
  m.colours = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {17 / 255.0, 200 / 255.0, 99 / 255.0}};
  write_mesh(dir / "c.obj", m);
  expect_colours(read_mesh(dir / "c.obj"), m.colours, 0.0);  // shortest round-trip decimal: exact
  for (PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kAscii}) {
    write_mesh(dir / "c.ply", m, {.ply_encoding = encoding});
    const TriangleMesh back = read_mesh(dir / "c.ply");
    expect_same_geometry(m, back, 0.0);
    expect_colours(back, m.colours, 1e-15);  // 8 bits a channel: k / 255 comes back as k / 255
  }
  // Without colours, none are written.
  write_mesh(dir / "plain.ply", textured_square());
  EXPECT_FALSE(read_mesh(dir / "plain.ply").has_colours());
}

TEST(MeshFiles, ReadsTheRealMedusaFrame) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const TriangleMesh m = read_mesh(data / "medusa-mediapipe-4d/capture/frame_0000.obj");
  EXPECT_EQ(m.positions.size(), 468u);
  EXPECT_EQ(m.faces.size(), 898u);
  EXPECT_TRUE(m.has_uvs());
  EXPECT_EQ(m.texture.filename(), "frame_0000.jpg");
}

}  // namespace
}  // namespace facemorph
