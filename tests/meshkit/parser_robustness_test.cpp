// Mutated inputs must give a facemorph::Error or a valid result: never a crash, never an out-of-
// bounds read (this runs under AddressSanitizer in CI), never a mesh that breaks the parser's
// promises (testing::broken_mesh_invariant). A deterministic stand-in for fuzzing.
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <random>

namespace facemorph {
namespace {

using testing::survive_mutations;

TriangleMesh sample_mesh() {
  TriangleMesh m = testing::grid_mesh(3, [](double u, double v) { return Vec3(u, v, u * v); });
  m.uvs = {};
  for (const Vec3& p : m.positions) m.uvs.emplace_back(p.x(), p.y());
  m.uv_faces = m.faces;
  return m;
}

// The sample with a colour per vertex (PLY red/green/blue, OBJ "v x y z r g b").
TriangleMesh coloured_sample_mesh() {
  TriangleMesh m = sample_mesh();
  for (const Vec3& p : m.positions) m.colours.emplace_back(p.x() / 2, p.y() / 2, 0.5);
  return m;
}

TEST(ParserRobustness, ObjSurvivesMutations) {
  for (const TriangleMesh& sample : {sample_mesh(), coloured_sample_mesh()}) {
    const std::string text = format_obj(sample, "");
    survive_mutations({text.begin(), text.end()}, 1, [](const std::vector<uint8_t>& b) {
      const TriangleMesh m = parse_obj({reinterpret_cast<const char*>(b.data()), b.size()}, "m.obj", ".", {.allow_missing_texture = true});
      EXPECT_EQ(testing::broken_mesh_invariant(m), "");
    });
  }
}

TEST(ParserRobustness, BinaryAndAsciiPlySurviveMutations) {
  for (const TriangleMesh& sample : {sample_mesh(), coloured_sample_mesh()}) {
    for (PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kAscii}) {
      survive_mutations(format_ply(sample, encoding, "t.png"), 2, [](const std::vector<uint8_t>& b) {
        EXPECT_EQ(testing::broken_mesh_invariant(parse_ply(b, "m.ply", ".", {.allow_missing_texture = true})), "");
      });
    }
  }
}

}  // namespace
}  // namespace facemorph
