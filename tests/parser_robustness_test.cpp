// Mutated inputs must give a facemorph::Error or a valid result: never a crash, never an out-of-
// bounds read (this runs under AddressSanitizer in CI). A deterministic stand-in for fuzzing.
#include "facemorph/capture.hpp"
#include "facemorph/mesh_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <random>

namespace facemorph {
namespace {

TriangleMesh sample_mesh() {
  TriangleMesh m = testing::grid_mesh(3, [](double u, double v) { return Vec3(u, v, u * v); });
  m.uvs = {};
  for (const Vec3& p : m.positions) m.uvs.emplace_back(p.x(), p.y());
  m.uv_faces = m.faces;
  return m;
}

std::vector<uint8_t> mutate(std::vector<uint8_t> bytes, std::mt19937& rng) {
  std::uniform_int_distribution<int> kind(0, 4), byte(0, 255);
  const int edits = 1 + static_cast<int>(rng() % 4);
  for (int e = 0; e < edits && !bytes.empty(); ++e) {
    const size_t at = rng() % bytes.size();
    switch (kind(rng)) {
      case 0: bytes[at] = static_cast<uint8_t>(byte(rng)); break;                       // flip a byte
      case 1: bytes.resize(at); break;                                                   // truncate
      case 2: bytes.insert(bytes.begin() + static_cast<long>(at), static_cast<uint8_t>(byte(rng))); break;
      case 3: bytes.erase(bytes.begin() + static_cast<long>(at)); break;
      case 4: bytes[at] = "0123456789-.e \n/"[rng() % 16]; break;                        // plausible text
    }
  }
  return bytes;
}

template <typename Parse>
void survive_mutations(const std::vector<uint8_t>& seed, unsigned rng_seed, Parse&& parse) {
  std::mt19937 rng(rng_seed);
  int errors = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    const std::vector<uint8_t> input = mutate(seed, rng);
    try {
      parse(input);
    } catch (const Error&) {
      ++errors;
    }
  }
  EXPECT_GT(errors, 0);  // the mutations did reach the error paths
}

TEST(ParserRobustness, ObjSurvivesMutations) {
  const std::string text = format_obj(sample_mesh(), "");
  survive_mutations({text.begin(), text.end()}, 1, [](const std::vector<uint8_t>& b) {
    parse_obj({reinterpret_cast<const char*>(b.data()), b.size()}, "m.obj", ".", {.allow_missing_texture = true});
  });
}

TEST(ParserRobustness, BinaryAndAsciiPlySurviveMutations) {
  for (PlyEncoding encoding : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kAscii}) {
    survive_mutations(format_ply(sample_mesh(), encoding, "t.png"), 2, [](const std::vector<uint8_t>& b) {
      parse_ply(b, "m.ply", ".", {.allow_missing_texture = true});
    });
  }
}

TEST(ParserRobustness, LandmarksCsvSurvivesMutations) {
  const std::string csv = "frame,name,x,y,z\n0,nose_tip,1,2,3\n1,rim_0,4,5,6\n1,chin,-1e-3,2.5,7\n";
  survive_mutations({csv.begin(), csv.end()}, 3, [](const std::vector<uint8_t>& b) {
    Capture c;
    c.frames = {{"a.obj", 0}, {"b.obj", 1}};
    parse_landmarks_csv({reinterpret_cast<const char*>(b.data()), b.size()}, "lm.csv", c);
  });
}

TEST(ParserRobustness, CaptureManifestSurvivesMutations) {
  testing::TempDir dir;
  testing::write_text(dir / "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const std::string json = R"({"fps": 30, "units": "cm", "frames": [{"mesh": "a.obj", "time": 0}, {"mesh": "a.obj", "time": 0.5}]})";
  survive_mutations({json.begin(), json.end()}, 4, [&](const std::vector<uint8_t>& b) {
    testing::write_text(dir / "capture.json", std::string(b.begin(), b.end()));
    read_capture(dir.path());
  });
}

}  // namespace
}  // namespace facemorph
