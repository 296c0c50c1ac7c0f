// The encoder's keyframe store: a spilled surface or set of fields reads back as the same numbers,
// the encoder holds a few keyframes' arrays at once whatever the number of keyframes, and spilling
// leaves the output as it was (spec/method.md §7.15).
#include "codec/encoder/encode/keyframe_store.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace facemorph {
namespace {

using crafted::small_metadata;
using crafted::small_sequence;

// Every array of GridFields filled (no representation uses them all: the store must not care),
// with seeded values that no two arrays share.
GridFields every_field(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  auto numbers = [&](size_t n) {
    std::vector<double> v(n);
    for (double& x : v) x = u(rng);
    return v;
  };
  auto vectors = [&](size_t n) {
    std::vector<Vec3> v(n);
    for (Vec3& x : v) x = Vec3(u(rng), u(rng), u(rng));
    return v;
  };
  GridFields f;
  f.representation = Representation::kHLT;
  f.grid_n = 17;
  f.mean_curvature = numbers(101);
  f.log_conformal_factor = numbers(102);
  f.tangential_u = numbers(103);
  f.tangential_v = numbers(104);
  f.fixed_nodes = {2, 3, 5, 7, 11};
  f.fixed_laplacian = vectors(5);
  f.positions = vectors(106);
  f.rim = vectors(64);
  return f;
}

void expect_same(const GridFields& a, const GridFields& b) {
  EXPECT_EQ(a.representation, b.representation);
  EXPECT_EQ(a.grid_n, b.grid_n);
  EXPECT_EQ(a.mean_curvature, b.mean_curvature);
  EXPECT_EQ(a.log_conformal_factor, b.log_conformal_factor);
  EXPECT_EQ(a.tangential_u, b.tangential_u);
  EXPECT_EQ(a.tangential_v, b.tangential_v);
  EXPECT_EQ(a.fixed_nodes, b.fixed_nodes);
  EXPECT_EQ(a.fixed_laplacian, b.fixed_laplacian);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.rim, b.rim);
}

TEST(KeyframeStore, SpilledFieldsAndSurfacesReadBackAsTheSameNumbers) {
  FieldsStore fields(FieldsStore::Mode::kSpill);
  fields.reset(3);
  std::vector<GridFields> given;
  for (unsigned k = 0; k < 3; ++k) {
    given.push_back(every_field(k));
    fields.put(k, GridFields(given.back()));
  }
  EXPECT_GT(fields.spilled_bytes(), 0u);
  EXPECT_EQ(fields.held(), 0);  // nothing in memory once written
  for (size_t k = 3; k-- > 0;) {
    const auto back = fields.get(k);
    EXPECT_EQ(fields.held(), 1);
    expect_same(given[k], *back);
  }
  EXPECT_EQ(fields.held(), 0);
  EXPECT_EQ(fields.peak_held(), 1);
  // Stored again, an item reads back as its last version.
  given[1] = every_field(7);
  fields.put(1, GridFields(given[1]));
  expect_same(given[1], *fields.get(1));
  testing::expect_error(ErrorCode::kInternal, "keyframe 3", [&] { fields.get(3); });
  testing::expect_error(ErrorCode::kInternal, "keyframe 3", [&] { fields.put(3, GridFields(given[0])); });
  // Bytes cut short are an error, not fields of zeros; bytes left over too.
  std::vector<char> bytes = FieldsStore::serialize(given[0]);
  expect_same(given[0], FieldsStore::deserialize(bytes.data(), bytes.size()));
  testing::expect_error(ErrorCode::kInternal, "cut short", [&] { FieldsStore::deserialize(bytes.data(), bytes.size() - 1); });
  bytes.push_back(0);
  testing::expect_error(ErrorCode::kInternal, "left over", [&] { FieldsStore::deserialize(bytes.data(), bytes.size()); });

  // Surfaces, two stores counting together (as one step's stores do).
  const auto count = std::make_shared<ResidentCount>();
  SurfaceStore a(SurfaceStore::Mode::kSpill, count), b(SurfaceStore::Mode::kSpill, count);
  a.reset(1);
  b.reset(1);
  const std::vector<Vec3> surface = given[2].positions;
  a.put(0, std::vector<Vec3>(surface));
  b.put(0, std::vector<Vec3>(given[2].rim));
  {
    const auto x = a.get(0), y = b.get(0);
    EXPECT_EQ(*x, surface);
    EXPECT_EQ(*y, given[2].rim);
    EXPECT_EQ(count->now.load(), 2);
  }
  EXPECT_EQ(count->now.load(), 0);
  EXPECT_EQ(a.peak_held(), 2);

  // In memory: the item itself, counted while stored.
  SurfaceStore memory(SurfaceStore::Mode::kMemory);
  memory.reset(2);
  memory.put(0, std::vector<Vec3>(surface));
  memory.put(1, std::vector<Vec3>(surface));
  EXPECT_EQ(memory.held(), 2);
  EXPECT_EQ(memory.spilled_bytes(), 0u);
  EXPECT_EQ(memory.get(1).get(), memory.get(1).get());
  EXPECT_EQ(*memory.get(0), surface);
}

// A capture of many keyframes: the encoder holds one keyframe array a thread (two threads here)
// spilled, and every keyframe's arrays in memory; the file is the same bytes either way. Spilled,
// its arrays went to the file: the fitted surfaces twice each, the field precision's exact surfaces
// once (decoded once, shared by every dead zone it tries) and its exact fields once.
TEST(StoredSequence, GivesBackTheSequencePutInAndWhatReplacedIt) {
  const Sequence s = small_sequence(17, 16);
  for (const SpillMode mode : {SpillMode::kSpill, SpillMode::kMemory}) {
    const std::unique_ptr<StoredSequence> stored = StoredSequence::of(Sequence(s), mode);
    ASSERT_EQ(stored->size(), s.keyframes.size());
    const Sequence back = stored->to_sequence();
    for (size_t k = 0; k < s.keyframes.size(); ++k) {
      EXPECT_EQ(back.keyframes[k].time, s.keyframes[k].time);
      EXPECT_TRUE(back.keyframes[k].pose.rotation == s.keyframes[k].pose.rotation);
      EXPECT_EQ(back.keyframes[k].hole_level, s.keyframes[k].hole_level);
      EXPECT_EQ(back.keyframes[k].texture.pixels, s.keyframes[k].texture.pixels);
      EXPECT_EQ(FieldsStore::serialize(back.keyframes[k].fields), FieldsStore::serialize(s.keyframes[k].fields));
    }
    const SequenceOutline expected = outline_of(s), outline = stored->outline();
    EXPECT_EQ(outline.times, expected.times);
    EXPECT_EQ(outline.fixed_node_count, expected.fixed_node_count);
    EXPECT_EQ(outline.has_holes, expected.has_holes);
    EXPECT_EQ(outline.texture_size, expected.texture_size);
    EXPECT_TRUE(stored->keyframe(1)->texture.empty()) << "the writer reads textures apart";
    EXPECT_EQ(stored->keyframe(1)->hole_level, s.keyframes[1].hole_level);
    EXPECT_TRUE(encode_sequence_file(*stored, small_metadata()) == encode_sequence_file(s, small_metadata()));
    // A put replaces what was there; a pose set is the shape's.
    stored->put_texture(1, Image(s.keyframes[0].texture));
    EXPECT_EQ(stored->texture(1)->pixels, s.keyframes[0].texture.pixels);
    RigidPose moved = s.keyframes[2].pose;
    moved.translation.x() += 0.5;
    stored->set_pose(2, moved);
    EXPECT_EQ(stored->to_sequence().keyframes[2].pose.translation.x(), moved.translation.x());
    EXPECT_EQ(stored->outline().poses[2].translation.x(), moved.translation.x()) << "the outline keeps the pose set";
    EXPECT_EQ(stored->keyframe(2)->pose.translation.x(), moved.translation.x());
  }
  Sequence unordered = s;
  unordered.keyframes[1].time = unordered.keyframes[0].time;
  testing::expect_error(ErrorCode::kInvalidArgument, "time does not increase",
                        [&] { StoredSequence::of(std::move(unordered), SpillMode::kMemory); });
  const StoredSequence empty(s, SpillMode::kSpill);  // the shape only: nothing put yet
  testing::expect_error(ErrorCode::kInternal, "never stored", [&] { empty.fields(0); });
}

// What choose_field_coding gives back is what the file holds: the hole levels too, in whole steps.
TEST(StoredSequence, TheFieldPrecisionGivesBackTheHoleLevelsAsTheFileHoldsThem) {
  Sequence s = small_sequence(17, 16);
  ASSERT_TRUE(s.has_holes());
  const FieldCoding coding = choose_field_coding(s, {1e-4, 2});
  const double step = coding.steps[kScalarArrayCount];
  for (const Keyframe& key : s.keyframes) {
    ASSERT_FALSE(key.hole_level.empty());
    for (double v : key.hole_level) ASSERT_EQ(v, step * std::nearbyint(v / step)) << "a hole level not rounded";
  }
}

// The encoder's steps on a Sequence move it into a store and back, also when they throw.
TEST(StoredSequence, TheStepsOnASequenceGiveItBackWhenTheyThrow) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 6;
  synth.vertices = 500;
  synth.texture_size = 16;
  write_synthetic_capture(dir.path(), synth);
  SequenceEncoder encoder(read_capture(dir.path()), {});
  const Sequence original = small_sequence(17, 16);
  const std::vector<uint8_t> file = encode_sequence_file(original, small_metadata());
  Sequence s = original;
  const TextureSettings texture = texture_settings(encoder.options());
  testing::expect_error(ErrorCode::kInvalidArgument, "not the sequence's", [&] {
    share_textures(texture.share, texture.coding.min_psnr, texture_frames(encoder), s, {0}, encoder.report());
  });
  EXPECT_TRUE(encode_sequence_file(s, small_metadata()) == file) << "share_textures lost the sequence";
  encoder.options().auto_field_error = false;
  encoder.options().field_precision.target_error = -1;
  testing::expect_error(ErrorCode::kInvalidArgument, "target error",
                        [&] { round_fields(field_precision_options(encoder.options(), KeyframeSelection{}), s, encoder.report()); });
  EXPECT_TRUE(encode_sequence_file(s, small_metadata()) == file) << "round_fields lost the sequence";
}

TEST(KeyframeStore, TheEncoderHoldsAFewKeyframesAtOnceAndWritesTheSameFile) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 24;
  synth.vertices = 1000;
  synth.head_motion_degrees = 10;
  synth.texture_size = 32;
  write_synthetic_capture(dir.path(), synth);
  const Capture capture = read_capture(dir.path());
  constexpr int kGrid = 33;
  std::vector<uint8_t> files[2];
  int peaks[2] = {0, 0}, stored_peaks[2] = {0, 0};
  size_t keys = 0;
  for (const bool spill : {true, false}) {
    EncodeOptions options;
    options.threads = 2;
    options.keyframe_fraction = 0.5;
    options.grid = kGrid;
    options.texture_size = 32;
    options.spill_keyframes = spill;
    // The half of the frames as keyframes, which residual frames would trade for fewer.
    options.residual_frames = false;
    EncodeReport report;
    const std::unique_ptr<StoredSequence> stored = encode_capture_stored(capture, options, &report);
    keys = stored->size();
    ASSERT_GE(keys, 12u);
    SequenceFileMetadata metadata;
    metadata.field_coding = report.field_coding;
    metadata.keyframe_texture_qualities = report.texture_qualities;
    // The file as fmenc writes it, from the store a keyframe at a time, and as the in-memory API
    // writes the same keyframes read back whole.
    files[spill] = encode_sequence_file(*stored, metadata);
    const Sequence sequence = stored->to_sequence();
    EXPECT_TRUE(files[spill] == encode_sequence_file(sequence, metadata)) << "the store's file is not the sequence's";
    peaks[spill] = report.peak_keyframes_in_memory;
    stored_peaks[spill] = stored->peak_held();
    if (spill) {
      const DiskGrid grid = make_disk_grid(kGrid);
      const uint64_t on_g = 8 + 24 * grid.nodes.size(), interior = 8 + 24 * static_cast<uint64_t>(grid.interior_count);
      const uint64_t fields = FieldsStore::serialize(sequence.keyframes[0].fields).size();
      const uint64_t texture = TextureStore::serialize(sequence.keyframes[0].texture).size();
      EXPECT_GE(report.keyframes_spilled_bytes, keys * (2 * on_g + interior + 2 * fields + texture))
          << "some keyframe arrays stayed in memory";
    } else {
      EXPECT_EQ(report.keyframes_spilled_bytes, 0u);
    }
  }
  EXPECT_LE(peaks[1], 2) << "spilled: one keyframe array a thread";
  EXPECT_GE(peaks[1], 1);
  // Spilled, the output's fields, hole levels and textures come back a few at a time: the texture
  // quality's blend reads four keyframes' textures on each of two threads, the writer two.
  EXPECT_LE(stored_peaks[1], 10) << "spilled: the output read back a few arrays at a time";
  EXPECT_GE(stored_peaks[1], 1);
  // In memory the field precision holds every keyframe's exact surface at once, and the output
  // every keyframe's fields, hole level and texture.
  EXPECT_GE(peaks[0], static_cast<int>(keys)) << "in memory: every keyframe's exact surface";
  EXPECT_GE(stored_peaks[0], 3 * static_cast<int>(keys)) << "in memory: every keyframe's arrays";
  ASSERT_FALSE(files[1].empty());
  EXPECT_TRUE(files[0] == files[1]) << "spilling the keyframes' arrays changed the file";
}

}  // namespace
}  // namespace facemorph
