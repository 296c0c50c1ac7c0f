// Issue 47 part 2: a whole head whose rim is the neck (eyes, mouth and nostrils open) encodes at the
// default settings, given landmarks or finding them (--landmarks auto), and decodes within 1.5x the
// error of its cropped face (the same synthetic face alone, same holes). spec/method.md §7.11.
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

namespace facemorph {
namespace {

// 12 frames: over 4, --landmarks auto once passed while at 12 the found landmarks' disagreement took
// --grid auto to N = 41 and the head to 3x its face's error (the up point slid along the nose).
Capture synthetic(const testing::TempDir& dir, bool whole_head, int frames = 12) {
  SynthOptions o;
  o.frames = frames;
  o.vertices = 2000;
  o.texture_size = 128;
  o.holes = true;
  o.whole_head = whole_head;
  write_synthetic_capture(dir.path(), o);
  return read_capture(dir.path());
}

// The geometry alone (what is measured), on two threads.
EncodeOptions geometry_options() {
  EncodeOptions options;
  options.texture = false;
  options.threads = 2;
  return options;
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
  const EncodeOptions options = geometry_options();
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
  // The face's representation is the choice by bytes at equal error's (spec/method.md §7.14): since
  // the density-equalised disk and the coarser field step are among its candidates, positions may
  // win here; the file holds the kept one.
  const RepresentationRate& rate = cropped.report.representation_rate;
  ASSERT_TRUE(rate.measured);
  EXPECT_EQ(cropped.representation, rate.candidates[rate.chosen].representation);
  for (bool find_landmarks : {false, true}) {
    SCOPED_TRACE(find_landmarks ? "--landmarks auto" : "given landmarks");
    const Encoded whole = encode(head, find_landmarks);
    EXPECT_TRUE(whole.report.dropped.empty());
    // fmsynth writes the head as a scanner without defects would: nothing to repair (at 2000
    // vertices it wrote a bow tie at a nostril, split here by the encoder's preparation).
    for (const EncodedFrameReport& f : whole.report.frames) {
      EXPECT_EQ(f.repair_totals.faces_changed, 0) << f.name << ": " << f.repair;
      EXPECT_EQ(f.repair_totals.vertices_changed, 0) << f.name << ": " << f.repair;
    }
    // The neck crowds the face into the disk's middle; spread radially, half the surface holds
    // half the disk's area, and the keyframes are positions.
    EXPECT_LT(whole.report.density_equalising.half_area_radius_before, kCrowdedHalfAreaRadius);
    EXPECT_EQ(whole.report.radial_equalising, 1);
    EXPECT_NEAR(whole.report.density_equalising.half_area_radius_after, std::sqrt(0.5), 0.02);
    EXPECT_EQ(whole.representation, Representation::kXYZ);
    EXPECT_LT(whole.keyframe_error, 1.5 * cropped.keyframe_error)
        << "head " << whole.keyframe_error << " m, face " << cropped.keyframe_error << " m";
    if (find_landmarks) {
      // The found landmarks' disagreement from frame to frame reads as frame noise, above the given
      // landmarks' (spec/method.md §7.14): on a whole head whose frames share no interior landmarks
      // with the reference it does not set --grid auto's N (fa76b86: it took N to 33).
      EXPECT_EQ(whole.report.frames_without_interior_landmarks, static_cast<int>(head.frames.size()) - 1);
      EXPECT_GT(whole.report.median_noise, whole.report.grid_target);  // the noise would have asked for a coarser grid
      EXPECT_NE(whole.report.grid_term, "noise");
    }
  }
}

// Where a keyframe's fields do not reconstruct, the capture is not refused (issue 47 part 2): the
// whole head on its conformal disk (--radial-equalising 0, no radial spread) gives hl+t keyframes
// that do not converge; the encoder then stores every keyframe as positions and the report (the
// summary's warning, the settings' representation_fallback) names the keyframe and how far it was.
// Letting the failure through (no fallback) is the mutation this test catches.
TEST(WholeHead, AKeyframeThatDoesNotReconstructIsStoredAsPositions) {
  testing::TempDir dir;
  const Capture head = synthetic(dir, true, 2);
  EncodeOptions options = geometry_options();
  options.density_equalising.radial = 0;
  // N = 129 given, not --grid auto's (on these two frames nothing is predicted, so auto follows half
  // the error bound: N = 41 at the defaults, spec/method.md §7.6; the test below asserts < 257).
  // At 129 the fields' iteration fails as at 257, the fixed floor's N before (last change 2.7e-5 of
  // the rim diameter against 5.9e-7, both far above 1e-8), in a fifth of the time; at N = 65 it
  // converges, so the grid is not taken lower.
  options.grid = 129;
  EncodeReport report;
  const Sequence sequence = encode_capture(head, options, &report);
  EXPECT_EQ(sequence.representation, Representation::kXYZ);
  EXPECT_EQ(report.radial_equalising, 0);
  EXPECT_NE(report.representation_fallback.find("keyframe "), std::string::npos) << report.representation_fallback;
  EXPECT_NE(report.representation_fallback.find("did not converge"), std::string::npos) << report.representation_fallback;
  // Both keyframes fail: the one named is keyframe 0, whose decode the rounding meets first, never
  // the other as the threads happen to finish (the file's settings carry this text).
  EXPECT_NE(report.representation_fallback.find("keyframe 0: "), std::string::npos) << report.representation_fallback;
  ASSERT_FALSE(report.warnings.empty());
  EXPECT_NE(report.warnings.back().find("every keyframe stored as positions (xyz)"), std::string::npos) << report.warnings.back();
  // Asked for the fields, the encode still fails: positions were not asked for.
  options.representation = Representation::kHLT;
  testing::expect_error(ErrorCode::kNotConverged, "did not converge", [&] { encode_capture(head, options); });
}

// --grid auto on a whole head of two frames (nothing predicted: the RMS target is half the error
// bound, met at a coarse N) whose reference's fields reconstruct to no surface, or to another one,
// at most N (spec/method.md §7.6, "The worst region through the reconstruction"): a candidate
// whose decoded p99 is over the bound is refused; one whose fields do not reconstruct reads the
// positions the encode then stores, and the file holds positions at that N.
TEST(WholeHead, TheGridReadsTheReconstructionOrThePositionsItFallsBackTo) {
  testing::TempDir dir;
  const Capture head = synthetic(dir, true, 2);
  EncodeReport report;
  const Sequence sequence = encode_capture(head, geometry_options(), &report);
  const auto& decoded = report.grid_decoded_floors;
  ASSERT_FALSE(decoded.empty());
  ASSERT_EQ(decoded.back().n, sequence.grid_n);
  const auto resampled_p99 = [&](int n) {
    for (const auto& [m, p99] : report.grid_floor_p99s) {
      if (m == n) return p99;
    }
    ADD_FAILURE() << "no resampled floor at " << n;
    return 0.0;
  };
  for (size_t i = 0; i + 1 < decoded.size(); ++i) {
    EXPECT_GT(std::max(decoded[i].p99, resampled_p99(decoded[i].n)), report.grid_worst_target) << decoded[i].n;
  }
  EXPECT_LE(std::max(decoded.back().p99, resampled_p99(decoded.back().n)), report.grid_worst_target);
  EXPECT_LT(sequence.grid_n, 257) << "the fixed floor's N: half the bound asks for less";
  if (!decoded.back().reconstructed) {
    EXPECT_EQ(sequence.representation, Representation::kXYZ);
    EXPECT_DOUBLE_EQ(decoded.back().p99, resampled_p99(decoded.back().n));
  }
  bool any_not_reconstructed = false;
  for (const auto& d : decoded) any_not_reconstructed = any_not_reconstructed || !d.reconstructed;
  EXPECT_TRUE(any_not_reconstructed) << "this head's fields reconstruct at every N measured: the test no longer covers the fallback";
}

// The project's root: FACEMORPH_SHARED_DATA is "<root>/../shared/data".
std::filesystem::path ict_script() {
  const std::string shared = FACEMORPH_SHARED_DATA, tail = "/../shared/data";
  return std::filesystem::path(shared.substr(0, shared.size() - tail.size())) / "tools/ict_whole_head.py";
}

bool have_ict(std::string* why) {
  const auto data = testing::shared_data();
  if (data.empty() || !std::filesystem::exists(data / "ict-facekit/originals/FaceXModel/generic_neutral_mesh.obj.xz")) {
    *why = "../shared/data/ict-facekit absent";
    return false;
  }
  if (std::system("python3 --version > /dev/null 2>&1") != 0) {
    *why = "python3 absent";
    return false;
  }
  return true;
}

Capture ict_capture(const std::filesystem::path& out, int frames, const std::string& flags) {
  const std::string command = "python3 '" + ict_script().string() + "' '" + out.string() + "' --frames " + std::to_string(frames) +
                              " --data '" + testing::shared_data().string() + "' " + flags + " > /dev/null";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  return read_capture(out);
}

// ICT's whole head with --landmarks auto against its face area (the same 12 frames cropped to the
// face, its landmarks given): every frame was a keyframe (the found up read the wrong way on 5 of 12
// frames, the blinking frame's tip lay on the forehead) and the spline predicted 17% between them.
// Now 3 keyframes, 0.73x the face's keyframe error in centimetres.
TEST(WholeHead, IctsWholeHeadWithFoundLandmarksWithinOneAndAHalfTimesItsFace) {
  std::string why;
  if (!have_ict(&why)) GTEST_SKIP() << why;
  testing::TempDir dir;
  const Encoded face = encode(ict_capture(dir.path() / "face", 12, "--face-only"), false);
  const Encoded head = encode(ict_capture(dir.path() / "head", 12, ""), true);
  EXPECT_TRUE(head.report.dropped.empty());
  EXPECT_EQ(head.representation, Representation::kXYZ);
  EXPECT_LE(head.report.keyframes.size(), 4u);
  EXPECT_LT(head.keyframe_error, 1.5 * face.keyframe_error)
      << "head " << head.keyframe_error << " cm, face " << face.keyframe_error << " cm";
}

// ICT's whole head (tools/ict_whole_head.py reads ../shared/data/ict-facekit; skipped without it):
// the face area joined to the back of the head down to the neck, eyes and mouth open; and the model
// with its separate eyeballs, teeth, gums and lashes, which --largest-component drops.
TEST(WholeHead, IctsWholeHeadEncodesAtTheDefaultSettings) {
  std::string why;
  if (!have_ict(&why)) GTEST_SKIP() << why;
  testing::TempDir dir;
  for (bool pieces : {false, true}) {
    SCOPED_TRACE(pieces ? "with its pieces" : "the head");
    const Capture capture = ict_capture(dir.path() / (pieces ? "pieces" : "head"), 3, pieces ? "--pieces" : "");
    EncodeOptions options;
    options.threads = 2;
    options.largest_component = pieces;
    EncodeReport report;
    const Sequence sequence = encode_capture(capture, options, &report);
    EXPECT_TRUE(report.dropped.empty());
    EXPECT_EQ(report.radial_equalising, 1);
    EXPECT_EQ(sequence.representation, Representation::kXYZ);
    EXPECT_TRUE(sequence.has_holes());
  }
}

}  // namespace
}  // namespace facemorph
