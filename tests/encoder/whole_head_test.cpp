// Issue 47 part 2: a whole head whose rim is the neck (eyes, mouth and nostrils open) encodes at the
// default settings, given landmarks or finding them (--landmarks auto), and decodes within 1.5x the
// error of its cropped face (the same synthetic face alone, same holes). spec/method.md §7.11.
#include "facemorph/encoder/sequence_encoder.hpp"
#include "facemorph/encoder/synth.hpp"
#include "facemorph/meshkit/distance.hpp"
#include "facemorph/meshkit/mesh_io.hpp"
#include "facemorph/sequence.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>

namespace facemorph {
namespace {

Capture synthetic(const testing::TempDir& dir, bool whole_head) {
  SynthOptions o;
  o.frames = 4;
  o.vertices = 2000;
  o.texture_size = 128;
  o.holes = true;
  o.whole_head = whole_head;
  write_synthetic_capture(dir.path(), o);
  return read_capture(dir.path());
}

struct Encoded {
  EncodeReport report;
  Representation representation = Representation::kHLT;
  double keyframe_error = 0;  // worst keyframe, RMS point-to-surface distance against its frame, metres
};

Encoded encode(Capture capture, bool find_landmarks) {
  if (find_landmarks) {  // as fmenc --landmarks auto
    capture.landmark_names.clear();
    capture.landmarks.assign(capture.frames.size(), {});
  }
  EncodeOptions options;
  options.texture = false;  // the geometry is what is measured
  options.threads = 2;
  Encoded out;
  const Sequence sequence = encode_capture(capture, options, &out.report);
  out.representation = sequence.representation;
  SequenceDecoder decoder(std::make_shared<const Sequence>(sequence));
  for (int k : out.report.keyframes) {
    const DecodedFrame frame = decoder.decode(capture.frames[static_cast<size_t>(k)].time);
    EXPECT_TRUE(frame.converged) << "keyframe " << k;
    const SurfaceDistance d = surface_distance(read_mesh(capture.mesh_path(static_cast<size_t>(k))), frame.mesh);
    out.keyframe_error = std::max(out.keyframe_error, d.rms);
  }
  return out;
}

TEST(WholeHead, EncodesAndDecodesWithinOneAndAHalfTimesItsCroppedFace) {
  testing::TempDir face_dir, head_dir;
  const Capture face = synthetic(face_dir, false), head = synthetic(head_dir, true);
  const Encoded cropped = encode(face, false);
  EXPECT_EQ(cropped.report.radial_equalising, 0);  // a face's conformal disk is not crowded
  EXPECT_GT(cropped.report.density_equalising.half_area_radius_before, 0.5);
  EXPECT_EQ(cropped.representation, Representation::kHLT);
  for (bool find_landmarks : {false, true}) {
    SCOPED_TRACE(find_landmarks ? "--landmarks auto" : "given landmarks");
    const Encoded whole = encode(head, find_landmarks);
    EXPECT_TRUE(whole.report.dropped.empty());
    // The neck crowds the face into the disk's middle; spread radially, half the surface holds
    // half the disk's area, and the keyframes are positions.
    EXPECT_LT(whole.report.density_equalising.half_area_radius_before, kCrowdedHalfAreaRadius);
    EXPECT_EQ(whole.report.radial_equalising, 1);
    EXPECT_NEAR(whole.report.density_equalising.half_area_radius_after, std::sqrt(0.5), 0.02);
    EXPECT_EQ(whole.representation, Representation::kXYZ);
    EXPECT_LT(whole.keyframe_error, 1.5 * cropped.keyframe_error) << "head " << whole.keyframe_error << " m, face " << cropped.keyframe_error << " m";
  }
}

// ICT's whole head (tools/ict_whole_head.py reads ../shared/data/ict-facekit; skipped without it):
// the face area joined to the back of the head down to the neck, eyes and mouth open; and the model
// with its separate eyeballs, teeth, gums and lashes, which --largest-component drops.
TEST(WholeHead, IctsWholeHeadEncodesAtTheDefaultSettings) {
  const auto data = testing::shared_data();
  if (data.empty() || !std::filesystem::exists(data / "ict-facekit/originals/FaceXModel/generic_neutral_mesh.obj.xz")) {
    GTEST_SKIP() << "../shared/data/ict-facekit absent";
  }
  if (std::system("python3 --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "python3 absent";
  // The project's root: FACEMORPH_SHARED_DATA is "<root>/../shared/data".
  const std::string shared = FACEMORPH_SHARED_DATA, tail = "/../shared/data";
  const std::filesystem::path script = std::filesystem::path(shared.substr(0, shared.size() - tail.size())) / "tools/ict_whole_head.py";
  testing::TempDir dir;
  for (bool pieces : {false, true}) {
    SCOPED_TRACE(pieces ? "with its pieces" : "the head");
    const std::filesystem::path out = dir.path() / (pieces ? "pieces" : "head");
    const std::string command = "python3 '" + script.string() + "' '" + out.string() + "' --frames 3 --data '" + data.string() + "'" +
                                (pieces ? " --pieces" : "") + " > /dev/null";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    EncodeOptions options;
    options.threads = 2;
    options.largest_component = pieces;
    EncodeReport report;
    const Sequence sequence = encode_capture(read_capture(out), options, &report);
    EXPECT_TRUE(report.dropped.empty());
    EXPECT_EQ(report.radial_equalising, 1);
    EXPECT_EQ(sequence.representation, Representation::kXYZ);
    EXPECT_TRUE(sequence.has_holes());
  }
}

}  // namespace
}  // namespace facemorph
