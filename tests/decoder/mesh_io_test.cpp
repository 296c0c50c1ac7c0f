#include "facemorph/mesh_io.hpp"

#include "format/file_io.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

namespace facemorph {
namespace {

using testing::TempDir;
using testing::expect_error;
using testing::write_text;

TriangleMesh textured_square() {
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5}, {0, 1, 0.25}};
  m.faces = {{0, 1, 2}, {0, 2, 3}};
  m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  m.uv_faces = m.faces;
  return m;
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

  std::string big = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
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
  const std::string huge = "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\n"
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
  const std::string bad_index = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n";
  expect_error(ErrorCode::kInvalidMesh, "vertex index 7", [&] {
    parse_ply({reinterpret_cast<const uint8_t*>(bad_index.data()), bad_index.size()}, "i.ply", ".");
  });
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
