// Mutated capture manifests and landmark files must give a facemorph::Error or a valid result:
// never a crash, never an out-of-bounds read (this runs under the sanitizers in CI).
#include "facemorph/encoder/capture.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

namespace facemorph {
namespace {

using testing::survive_mutations;

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
