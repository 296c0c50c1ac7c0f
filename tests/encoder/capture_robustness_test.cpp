// Mutated capture manifests and landmark files must give a facemorph::Error or a valid result:
// never a crash, never an out-of-bounds read (this runs under the sanitizers in CI), never a capture
// that breaks the reader's promises (broken_capture_invariant).
#include "codec/encoder/capture/capture.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace facemorph {
namespace {

using testing::survive_mutations;

// The first promise the capture reader broke in `c`, empty when it kept them all: fps finite and
// positive, frames named, times finite and strictly increasing, landmarks either absent or one row
// per frame of one entry per name, each entry finite or wholly NaN (absent from that frame).
std::string broken_capture_invariant(const Capture& c) {
  if (!(std::isfinite(c.fps) && c.fps > 0)) return "fps " + std::to_string(c.fps);
  if (c.frames.empty()) return "no frames";
  for (size_t i = 0; i < c.frames.size(); ++i) {
    if (c.frames[i].mesh.empty()) return "frame " + std::to_string(i) + " has no mesh";
    if (!std::isfinite(c.frames[i].time)) return "frame " + std::to_string(i) + " time is not finite";
    if (i > 0 && !(c.frames[i].time > c.frames[i - 1].time)) return "frame " + std::to_string(i) + " time does not increase";
  }
  if (c.landmarks.empty()) return {};
  if (c.landmarks.size() != c.frames.size()) {
    return std::to_string(c.landmarks.size()) + " landmark rows for " + std::to_string(c.frames.size()) + " frames";
  }
  for (size_t f = 0; f < c.landmarks.size(); ++f) {
    if (c.landmarks[f].size() != c.landmark_names.size()) {
      return "frame " + std::to_string(f) + " has " + std::to_string(c.landmarks[f].size()) + " landmarks for " +
             std::to_string(c.landmark_names.size()) + " names";
    }
    for (const Vec3& p : c.landmarks[f]) {
      if (!p.allFinite() && !p.array().isNaN().all()) return "frame " + std::to_string(f) + " has a partly finite landmark";
    }
  }
  for (const std::string& name : c.landmark_names) {
    if (name.empty()) return "an empty landmark name";
  }
  return {};
}

TEST(ParserRobustness, LandmarksCsvSurvivesMutations) {
  const std::string csv = "frame,name,x,y,z\n0,nose_tip,1,2,3\n1,rim_0,4,5,6\n1,chin,-1e-3,2.5,7\n";
  survive_mutations({csv.begin(), csv.end()}, 3, [](const std::vector<uint8_t>& b) {
    Capture c;
    c.fps = 1;
    c.frames = {{"a.obj", 0}, {"b.obj", 1}};
    parse_landmarks_csv({reinterpret_cast<const char*>(b.data()), b.size()}, "lm.csv", c);
    EXPECT_EQ(broken_capture_invariant(c), "");
  });
}

TEST(ParserRobustness, CaptureManifestSurvivesMutations) {
  testing::TempDir dir;
  testing::write_text(dir / "a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const std::string json = R"({"fps": 30, "units": "cm", "frames": [{"mesh": "a.obj", "time": 0}, {"mesh": "a.obj", "time": 0.5}]})";
  survive_mutations({json.begin(), json.end()}, 4, [&](const std::vector<uint8_t>& b) {
    testing::write_text(dir / "capture.json", std::string(b.begin(), b.end()));
    EXPECT_EQ(broken_capture_invariant(read_capture(dir.path())), "");
  });
}

}  // namespace
}  // namespace facemorph
