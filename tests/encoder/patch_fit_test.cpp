// Frame patches fitted to what the decoder shows (codec/encoder/encode/patch_fit.hpp, spec/method.md
// §7.19): a bump the blend cannot show is brought under the bound by a sparse patch, the rounded
// patch reaches the file to the bit, and the decoder shows at the patch's time exactly what the fit
// measured.
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/patch_measure.hpp"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/encoder/encoder_stages.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

namespace facemorph {
namespace {

TEST(PatchFit, ABumpTheBlendMissesIsPatchedAndDecodesAsFitted) {
  // The keyframes as a file holds them (rounded fields), decoded at 0.25 s, between keyframes 0 and 1.
  const Sequence stored = decode_sequence_file(encode_sequence_file(crafted::small_sequence(17, 8), crafted::small_metadata()), "s.fmv");
  const double t = 0.25;
  DecodeOptions o;
  o.continue_correction = false;
  const DecodedFrame plain = SequenceDecoder(std::make_shared<const Sequence>(stored)).decode(t, o);
  const DiskGrid grid = make_disk_grid(17);
  const ShownFrame shown{plain.grid_positions, plain.hole_level, plain.pose};
  // The "captured" frame: the decoded one with a bump of 3% of its diagonal along the face's z near
  // w = (0.2, −0.3), which no blend of the keyframes (one quadric at three amplitudes) holds.
  TriangleMesh captured = shown_mesh(grid, shown.positions, shown.hole_level);
  const double diagonal = bounding_box_diagonal(captured.positions);
  std::vector<Vec2> vertex_w(captured.positions.size(), Vec2::Zero());
  for (size_t f = 0; f < captured.faces.size(); ++f)
    for (int k = 0; k < 3; ++k)
      vertex_w[static_cast<size_t>(captured.faces[f][static_cast<size_t>(k)])] =
          2 * captured.uvs[static_cast<size_t>(captured.uv_faces[f][static_cast<size_t>(k)])] - Vec2(1, 1);
  for (size_t v = 0; v < captured.positions.size(); ++v) {
    const double r2 = (vertex_w[v] - Vec2(0.2, -0.3)).squaredNorm();
    captured.positions[v] += plain.pose.rotation * Vec3(0, 0, 0.03 * diagonal * std::exp(-r2 / 0.04));
  }
  const double step = std::exp2(std::floor(std::log2(kPatchStepShare * 0.01 * diagonal)));
  const PatchFit fit = fit_frame_patch(grid, shown, captured, t, {.lattice = 17, .bound = 0.01, .step_units = step});
  EXPECT_GT(fit.p99_before, 0.01);
  EXPECT_LE(fit.p99_after, 0.01);
  ASSERT_FALSE(fit.patch.nodes.empty());
  EXPECT_LT(fit.patch.nodes.size(), 17u * 17u / 4);  // sparse: the bump's cells, not the disk
  for (const Vec3& d : fit.patch.displacements) EXPECT_EQ(d, (d / step).array().round().matrix() * step);  // rounded
  // The search's approximate p99 bounds the exact one from above: a patch it took was measured exactly
  // (p99_after) and none it put under the bound was over it.
  EXPECT_GE(fit.exact_checks, 1);
  EXPECT_EQ(fit.approximate_misses, 0);
  // The file holds the patch to the bit, and its decoder shows at t what the fit measured.
  Sequence patched = stored;
  patched.patches = {fit.patch};
  const std::vector<uint8_t> bytes = encode_sequence_file(patched, crafted::small_metadata());
  const Sequence back = decode_sequence_file(bytes, "patched.fmv");
  ASSERT_EQ(back.patches.size(), 1u);
  EXPECT_EQ(back.patches[0].nodes, fit.patch.nodes);
  EXPECT_EQ(back.patches[0].displacements, fit.patch.displacements);
  const DecodedFrame shown_by_file = SequenceDecoder(open_sequence_source(bytes, "patched.fmv")).decode(t, o);
  const double p99 = surface_distance(captured, shown_by_file.mesh).p99 / diagonal;
  // Within the reconstruction's tolerance (the file's frame is reconstructed from its own fields; the
  // patch itself is added exactly, FramePatches.AFileHoldsThemToTheBitAndADecoderAddsThem): 5.6e-7 measured.
  EXPECT_NEAR(p99, fit.p99_after, 1e-5);
  EXPECT_LE(p99, 0.01);
  // The search's measure: exact() is fmbench's; approximate() is never under it, for the fitted patch
  // and for patches that move the surface further, the other way (away from the bump) and less.
  const TriangleMesh before = shown_mesh(grid, shown.positions, shown.hole_level);
  const PatchMeasure measure(grid, shown, captured, before);
  EXPECT_NEAR(measure.exact(FramePatch{.time = t, .lattice = 17, .nodes = {}, .displacements = {}}) / diagonal, fit.p99_before, 1e-12);
  for (const double scale : {1.0, 2.0, -1.0, 0.5}) {
    FramePatch scaled = fit.patch;
    for (Vec3& d : scaled.displacements) d *= scale;
    const double exact = measure.exact(scaled);
    EXPECT_EQ(exact, surface_distance(captured, shown_mesh(grid, patched_positions(grid, shown, scaled), shown.hole_level)).p99);
    EXPECT_GE(measure.approximate(scaled), exact) << "scale " << scale;
    EXPECT_LE(measure.approximate(scaled), 1.5 * exact) << "scale " << scale;  // and near it
    // exact() searches only what the patch moved, and so does a measure made from the distances
    // another kept (the fit's pinning rounds): the same p99 to the bit.
    EXPECT_EQ(PatchMeasure(grid, shown, captured, before, measure.distances()).exact(scaled), exact) << "scale " << scale;
    // The second round's samples, from searches of what the patch moved: those of a measure of the
    // patched mesh in full, in the same order, to the bit.
    const TriangleMesh moved = measure.patched(scaled);
    const ShownFrame moved_shown{patched_positions(grid, shown, scaled), shown.hole_level, shown.pose};
    const std::vector<OffsetSample> full = PatchMeasure(grid, moved_shown, captured, moved).samples(), part = measure.samples_of(moved);
    ASSERT_EQ(part.size(), full.size()) << "scale " << scale;
    size_t differ = 0;
    for (size_t i = 0; i < full.size(); ++i) differ += part[i].w != full[i].w || part[i].offset != full[i].offset;
    EXPECT_EQ(differ, 0u) << "scale " << scale;
  }
}

// A pinning round measures again only the frames beside its new pins: exactly those whose patches
// interpolated in t change (frame_patch_displacements before and after the pins went in).
TEST(PatchFit, APinningRoundMeasuresAgainExactlyTheFramesItsPinsChange) {
  const std::vector<double> key_times = {0.0, 1.0, 2.0};
  const std::vector<Vec2> disk = {Vec2(0.1, -0.2), Vec2(-0.5, 0.3), Vec2(0.7, 0.6)};
  std::vector<double> times;
  for (int i = 1; i < 40; ++i) times.push_back(i * 0.05);  // frames in both intervals, keyframe 1.0 among them
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1, 1);
  const auto patch_at = [&](double t) {
    FramePatch p{.time = t, .lattice = 3, .nodes = {0, 4, 8}, .displacements = {}};
    for (int n = 0; n < 3; ++n) p.displacements.push_back(Vec3(unit(rng), unit(rng), unit(rng)));
    return p;
  };
  const auto insert = [](std::vector<FramePatch>& patches, const FramePatch& p) {
    patches.insert(std::upper_bound(patches.begin(), patches.end(), p.time, [](double t, const FramePatch& f) { return t < f.time; }), p);
  };
  size_t beside_total = 0;
  for (int trial = 0; trial < 30; ++trial) {
    std::vector<FramePatch> patches;
    std::vector<double> free_times = times;
    std::shuffle(free_times.begin(), free_times.end(), rng);
    const int fitted = 1 + trial % 5, pinned = 1 + trial % 3;
    for (int i = 0; i < fitted; ++i) insert(patches, patch_at(free_times[static_cast<size_t>(i)]));
    const std::vector<FramePatch> before = patches;
    std::vector<double> pins;
    for (int i = 0; i < pinned; ++i) {
      const double t = free_times[static_cast<size_t>(fitted + i)];
      insert(patches, FramePatch{.time = t, .lattice = 3, .nodes = {}, .displacements = {}});
      pins.push_back(t);
    }
    const std::vector<char> beside = frames_beside_pins(key_times, patches, pins, times);
    ASSERT_EQ(beside.size(), times.size());
    for (size_t i = 0; i < times.size(); ++i) {
      if (std::any_of(patches.begin(), patches.end(), [&](const FramePatch& p) { return p.time == times[i]; })) {
        EXPECT_EQ(beside[i], 0) << "a frame holding a patch";  // its own patch shows there, pinned or fitted
        continue;
      }
      const std::vector<Vec3> was = frame_patch_displacements(key_times, before, times[i], disk);
      const std::vector<Vec3> is = frame_patch_displacements(key_times, patches, times[i], disk);
      const bool changed = was.empty() != is.empty() || (!is.empty() && (was[0] != is[0] || was[1] != is[1] || was[2] != is[2]));
      EXPECT_EQ(beside[i] != 0, changed) << "trial " << trial << ", frame at " << times[i];
      beside_total += beside[i] != 0;
    }
  }
  EXPECT_GT(beside_total, 0u);
}

// Fast speech at 2k vertices, few keyframes: frames between them whose lips the blend misses.
Capture fast_speech(const std::filesystem::path& dir) {
  SynthOptions options = testing::fast_speech_options(16);
  options.texture_size = 32;
  write_synthetic_capture(dir, options);
  return read_capture(dir);
}

// fast_speech's encode: few keyframes, no texture, patches at `patch_bound` (0: none).
EncodeOptions fast_speech_encode(double patch_bound, int threads) {
  EncodeOptions options;
  options.texture = false;
  options.keyframe_fraction = 0.15;
  options.patch_bound = patch_bound;
  options.threads = threads;
  return options;
}

TEST(PatchFit, EveryFrameDecodesUnderTheBoundAndTheFileIsTheSameAtAnyThreadCount) {
  const testing::TempDir dir;
  const Capture capture = fast_speech(dir.path() / "capture");
  // A bound tighter than the default 1%, so that this short capture has frames over it.
  EncodeOptions options = fast_speech_encode(0.005, 1);
  EncodeReport one_report, two_report;
  const Sequence one = encode_capture(capture, options, &one_report);
  options.threads = 2;
  const Sequence two = encode_capture(capture, options, &two_report);
  const PatchFitReport& fit = one_report.patch_fit;
  ASSERT_GT(fit.frames_patched, 0);
  EXPECT_EQ(fit.frames_unmet, 0);
  EXPECT_LE(fit.worst_after, options.patch_bound);
  // approximate() is never under exact() (patch_measure.hpp), so none the search took was over the bound.
  EXPECT_GT(fit.exact_checks, 0);
  EXPECT_EQ(fit.approximate_misses, 0);
  // The patches are fitted on the encoder's threads, each frame's as a function of its time alone.
  EXPECT_EQ(encode_sequence_file(one, crafted::small_metadata()), encode_sequence_file(two, crafted::small_metadata()));
  EXPECT_EQ(two_report.patch_fit.nodes, fit.nodes);
  // What the decoder shows at each captured frame between keyframes: under the bound (within the
  // reconstruction's tolerance, the margin kPatchBoundMargin), as the fit measured.
  const std::vector<uint8_t> bytes = encode_sequence_file(one, crafted::small_metadata());
  SequenceDecoder decoder(open_sequence_source(bytes, "fast.fmv"));
  DecodeOptions o;
  o.texture = false;
  o.continue_correction = false;
  const std::vector<double> key_times = one.keyframe_times();
  double worst = 0;
  for (size_t j = 0; j < capture.frames.size(); ++j) {
    if (residual_interval(key_times, capture.frames[j].time) < 0) continue;  // a keyframe's own frame, or outside them
    const TriangleMesh captured = read_mesh(capture.mesh_path(j), {.allow_missing_texture = true});
    const SurfaceDistance d = surface_distance(captured, decoder.decode(capture.frames[j].time, o).mesh);
    worst = std::max(worst, d.p99 / d.diagonal);
  }
  EXPECT_GT(fit.worst_before, options.patch_bound);
  EXPECT_LE(worst, options.patch_bound);
}

// A longer capture's frames are decoded again by each pass instead of kept (kept_frames_memory):
// the same patches, since each frame is a function of its time alone.
TEST(PatchFit, FramesDecodedAgainPastTheMemoryBoundGiveTheSamePatches) {
  const testing::TempDir dir;
  const Capture capture = fast_speech(dir.path() / "capture");
  const EncodeOptions options = fast_speech_encode(0, 2);  // the file without patches, fitted below
  EncodeReport report;
  const Sequence plain = encode_capture(capture, options, &report);
  ASSERT_TRUE(plain.patches.empty());
  const auto fit = [&](size_t kept_frames_memory) {
    const std::unique_ptr<StoredSequence> stored = StoredSequence::of(Sequence(plain), SpillMode::kMemory);
    return fit_frame_patches(capture, *stored, report.keyframes, 0.005, nullptr, 2, kept_frames_memory);
  };
  const std::vector<FramePatch> kept = fit(kShownFramesMemory), decoded_again = fit(0);
  ASSERT_FALSE(kept.empty());
  ASSERT_EQ(decoded_again.size(), kept.size());
  for (size_t p = 0; p < kept.size(); ++p) {
    EXPECT_EQ(decoded_again[p].time, kept[p].time);
    EXPECT_EQ(decoded_again[p].lattice, kept[p].lattice);
    EXPECT_EQ(decoded_again[p].nodes, kept[p].nodes);
    EXPECT_EQ(decoded_again[p].displacements, kept[p].displacements);
  }
}

}  // namespace
}  // namespace facemorph
