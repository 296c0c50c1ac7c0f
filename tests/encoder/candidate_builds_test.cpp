// The choice by bytes' builds kept once per N (candidate_builds.hpp): a candidate made from a kept
// build holds exactly the arrays a new build of it holds, in its own representation, and rounding a
// candidate handed out leaves the kept build as it was.
#include "codec/encoder/encode/candidate_builds.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/stage_settings.hpp"

#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

namespace facemorph {
namespace {

// Every array of every keyframe the same, to the bit: fields, hole levels, textures and poses.
void expect_same_keyframes(const StoredSequence& a, const StoredSequence& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  EXPECT_EQ(a.shape().representation, b.shape().representation) << what;
  EXPECT_EQ(a.shape().grid_n, b.shape().grid_n) << what;
  for (size_t k = 0; k < a.size(); ++k) {
    EXPECT_EQ(scalar_arrays(*a.fields(k)), scalar_arrays(*b.fields(k))) << what << ", keyframe " << k << "'s fields";
    EXPECT_EQ(a.fields(k)->fixed_nodes, b.fields(k)->fixed_nodes) << what << ", keyframe " << k;
    EXPECT_EQ(*a.hole_level(k), *b.hole_level(k)) << what << ", keyframe " << k << "'s holes";
    EXPECT_EQ(a.texture(k)->pixels, b.texture(k)->pixels) << what << ", keyframe " << k << "'s texture";
    EXPECT_EQ(a.shape().keyframes[k].pose.rotation, b.shape().keyframes[k].pose.rotation) << what;
    EXPECT_EQ(a.shape().keyframes[k].pose.translation, b.shape().keyframes[k].pose.translation) << what;
  }
}

TEST(CandidateBuilds, ACandidateFromAKeptBuildIsItsOwnBuild) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 10);
  EncodeOptions options;
  options.threads = 2;
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const BuildSettings settings = build_settings(options);
  const std::vector<int> keyframes = {0, 5, 11};
  constexpr int kN = 33;
  CandidateBuilds builds(SpillMode::kSpill, 2);
  EncodeReport report;
  int built = 0;
  const auto build = [&](KeyframeSurfaces* surfaces) {
    ++built;
    return encoder.build(settings, keyframes, kN, nullptr, surfaces);
  };
  encoder.adopt_representation(Representation::kHLT, encoder.report().blend);
  std::unique_ptr<StoredSequence> fields = builds.get(Representation::kHLT, kN, build, report);
  EXPECT_EQ(built, 1);
  EXPECT_TRUE(builds.kept(kN));
  EXPECT_FALSE(builds.kept(65));
  // Rounded in place, as the choice rounds each candidate: the kept build is not.
  FieldPrecisionOptions precision;
  precision.target_error = 0.002;
  precision.threads = 2;
  round_fields(precision, *fields, report);

  // Positions at the same N from the kept surfaces: no build, and what a build of positions holds.
  encoder.adopt_representation(Representation::kXYZ, encoder.report().blend);
  const std::unique_ptr<StoredSequence> positions = builds.get(Representation::kXYZ, kN, build, report);
  EXPECT_EQ(built, 1) << "made from the kept build";
  expect_same_keyframes(*positions, *encoder.build(settings, keyframes, kN), "xyz from the kept hl+t build");

  // The fields again (the coarser step's candidate): unrounded, as built.
  encoder.adopt_representation(Representation::kHLT, encoder.report().blend);
  const std::unique_ptr<StoredSequence> again = builds.get(Representation::kHLT, kN, build, report);
  EXPECT_EQ(built, 1);
  expect_same_keyframes(*again, *encoder.build(settings, keyframes, kN), "hl+t again");
}

// The same where the arrays stay in memory (EncodeOptions::spill_keyframes false, an API caller's
// setting: the copies then share nothing with the kept build through a file) and on a capture with
// holes and textures, whose hole levels and texels the copies carry over: each candidate holds what
// a new build of it holds; a build at another N takes the kept build's textures, as its own sampling
// makes them.
TEST(CandidateBuilds, InMemoryAndWithHolesACandidateIsItsOwnBuild) {
  for (const bool spill : {false, true}) {
    SCOPED_TRACE(spill ? "spilled" : "in memory");
    testing::TempDir dir;
    SynthOptions synth;
    synth.frames = 12;
    synth.vertices = 3000;
    synth.texture_size = 64;
    synth.holes = true;
    write_synthetic_capture(dir.path(), synth);
    const Capture capture = read_capture(dir.path());
    EncodeOptions options;
    options.threads = 2;
    options.spill_keyframes = spill;
    SequenceEncoder encoder(capture, options);
    testing::run_to_selection(encoder);
    const BuildSettings settings = build_settings(options);
    ASSERT_EQ(settings.spill_keyframes, spill);
    const std::vector<int> keyframes = {0, 6, 11};
    constexpr int kN = 41;
    CandidateBuilds builds(spill ? SpillMode::kSpill : SpillMode::kMemory, 2);
    EncodeReport report;
    int built = 0;
    // A build fills the report it is handed (as SequenceEncoder::measure_candidate's fills report_).
    const auto build = [&](KeyframeSurfaces* surfaces) {
      ++built;
      std::unique_ptr<StoredSequence> made = encoder.build(settings, keyframes, kN, nullptr, surfaces);
      report = encoder.report();
      return made;
    };
    encoder.adopt_representation(Representation::kHLT, encoder.report().blend);
    std::unique_ptr<StoredSequence> fields = builds.get(Representation::kHLT, kN, build, report);
    ASSERT_EQ(built, 1);
    ASSERT_GT(report.texture_size, 0);
    // What this test is for: the holes and textures are there to be carried over.
    ASSERT_FALSE(fields->hole_level(0)->empty()) << "the capture's holes are stored";
    ASSERT_FALSE(fields->texture(0)->pixels.empty()) << "the capture's textures are stored";
    FieldPrecisionOptions precision;
    precision.target_error = 0.002;
    precision.threads = 2;
    precision.spill = spill;
    round_fields(precision, *fields, report);

    encoder.adopt_representation(Representation::kXYZ, encoder.report().blend);
    const std::unique_ptr<StoredSequence> positions = builds.get(Representation::kXYZ, kN, build, report);
    EXPECT_EQ(built, 1) << "made from the kept build";
    expect_same_keyframes(*positions, *encoder.build(settings, keyframes, kN), "xyz from the kept hl+t build");
    EXPECT_EQ(report.keyframe_folds, encoder.report().keyframe_folds);
    EXPECT_EQ(report.texture_size, encoder.report().texture_size) << "the copy's report as the build's";

    encoder.adopt_representation(Representation::kHLT, encoder.report().blend);
    const std::unique_ptr<StoredSequence> again = builds.get(Representation::kHLT, kN, build, report);
    EXPECT_EQ(built, 1);
    expect_same_keyframes(*again, *encoder.build(settings, keyframes, kN), "hl+t again, unrounded");

    // Another N: a build of its own, its textures copied from a kept build of the same keyframes on
    // the same disk (any_kept), not sampled again: what a build that samples them holds.
    encoder.adopt_representation(Representation::kXYZ, encoder.report().blend);
    constexpr int kCoarser = 33;
    const auto build_coarser = [&](KeyframeSurfaces* surfaces) {
      ++built;
      return encoder.build(settings, keyframes, kCoarser, nullptr, surfaces, builds.any_kept());
    };
    ASSERT_NE(builds.any_kept(), nullptr);
    const std::unique_ptr<StoredSequence> coarser = builds.get(Representation::kXYZ, kCoarser, build_coarser, report);
    EXPECT_EQ(built, 2) << "a new N is built";
    expect_same_keyframes(*coarser, *encoder.build(settings, keyframes, kCoarser), "xyz at a coarser N, textures from the kept build");
    // Other keyframes: the kept build's textures are not theirs, and are not taken.
    const std::vector<int> others = {0, 5, 11};
    expect_same_keyframes(*encoder.build(settings, others, kCoarser, nullptr, nullptr, builds.any_kept()),
                          *encoder.build(settings, others, kCoarser), "other keyframes, given the kept build's textures");
  }
}

}  // namespace
}  // namespace facemorph
