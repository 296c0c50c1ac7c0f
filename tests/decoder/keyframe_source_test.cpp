// Decoding on demand (open_sequence_source, spec/container.md §10.1): an opened file holds what the
// budget allows whatever its length, and decodes every frame exactly as the file decoded whole.
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/player/decoder.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <thread>

namespace facemorph {
namespace {

constexpr int kKeyframes = 60;

// The crafted small sequence's three surfaces, poses, holes and textures repeated over 60 keyframes
// (intra every second one: runs of two), so that a file is long next to the budget a test gives it.
std::vector<uint8_t> long_file(SplineKind spline = SplineKind::kCatmullRom, int keyframes = kKeyframes,
                               const SequenceFileMetadata& metadata = crafted::predicted_metadata(), int texture = 16) {
  const Sequence three = crafted::small_sequence(17, texture);
  Sequence s = three;
  s.spline = spline;
  s.keyframes.clear();
  for (int k = 0; k < keyframes; ++k) {
    Keyframe key = three.keyframes[static_cast<size_t>(k % 3)];
    key.time = k / 10.0;
    key.pose.translation.x() += 0.01 * k;
    for (uint8_t& p : key.texture.pixels) p = static_cast<uint8_t>(p + 3 * k);
    s.keyframes.push_back(std::move(key));
  }
  s.last_time = s.keyframes.back().time;
  return encode_sequence_file(s, metadata);
}

// The same with 64² textures as one AV1 sequence per group of 8 keyframes (TGOP, format 2.1).
std::vector<uint8_t> long_grouped_file() {
  SequenceFileMetadata m = crafted::grouped_texture_metadata();
  m.field_coding.intra_period = 8;
  return long_file(SplineKind::kCatmullRom, kKeyframes, m, 64);
}

DecoderLimits with_memory(uint64_t bytes) {
  DecoderLimits limits;
  limits.max_memory_bytes = bytes;
  return limits;
}

struct Decoded {
  std::vector<Vec3> positions;
  std::vector<uint8_t> texture;
  std::vector<double> holes;
};

Decoded decode_at(SequenceDecoder& decoder, double t) {
  const DecodedFrame frame = decoder.decode(t);
  return {frame.grid_positions, frame.texture.pixels, frame.hole_level};
}

void expect_same(const Decoded& a, const Decoded& b, double t) {
  ASSERT_EQ(a.positions.size(), b.positions.size()) << "t = " << t;
  for (size_t v = 0; v < a.positions.size(); ++v) ASSERT_EQ(a.positions[v], b.positions[v]) << "t = " << t << ", node " << v;
  EXPECT_EQ(a.texture, b.texture) << "t = " << t;
  EXPECT_EQ(a.holes, b.holes) << "t = " << t;
}

TEST(KeyframeSource, ALongFileDecodesOnDemandWithinABudgetItsWholeDecodeExceeds) {
  const std::vector<uint8_t> bytes = long_file();
  const uint64_t budget = crafted::smallest_budget(bytes);
  // Decoded whole, the same file needs more than that budget holds.
  testing::expect_error(ErrorCode::kLimit, "over the memory limit",
                        [&] { decode_sequence_file(bytes, "long", nullptr, with_memory(budget)); });
  // One step less and a frame's four keyframes no longer fit: refused by name, at open.
  testing::expect_error(ErrorCode::kLimit, "--max-memory", [&] { open_sequence_source(bytes, "long", with_memory(budget - (16 << 10))); });

  const auto source = open_sequence_source(bytes, "long", with_memory(budget));
  EXPECT_GE(source->surfaces_kept(), 4u);
  EXPECT_LT(source->surfaces_kept(), static_cast<size_t>(kKeyframes));
  EXPECT_LE(source->bytes_held(), budget);
  SequenceDecoder lazy(source);
  SequenceDecoder whole(std::make_shared<const Sequence>(decode_sequence_file(bytes, "long")));
  // Forwards as a player plays, then backwards: the cache drops and decodes keyframes again, and
  // every frame is the one the whole file gives (keyframe surfaces are made cold: the same bits).
  std::vector<double> times;
  for (int i = 0; i <= 30 * 59 / 10; i += 2) times.push_back(i / 30.0);
  for (int i = 30 * 59 / 10; i >= 0; i -= 7) times.push_back(i / 30.0);
  for (double t : times) {
    expect_same(decode_at(lazy, t), decode_at(whole, t), t);
    ASSERT_LE(source->bytes_held(), budget) << "t = " << t;
    ASSERT_LE(lazy.surfaces_held(), source->surfaces_kept()) << "t = " << t;
  }
  // It kept what the budget allows, not the whole file, and made dropped surfaces again.
  EXPECT_GE(lazy.surfaces_held(), 4u);
  EXPECT_EQ(whole.surfaces_held(), static_cast<size_t>(kKeyframes));
  EXPECT_EQ(whole.keyframe_reconstructions(), static_cast<size_t>(kKeyframes));
  EXPECT_GT(lazy.keyframe_reconstructions(), static_cast<size_t>(kKeyframes));
}

TEST(KeyframeSource, DecodersOnThreadsShareOneSmallCache) {
  const std::vector<uint8_t> bytes = long_file();
  const uint64_t budget = crafted::smallest_budget(bytes);
  const auto source = open_sequence_source(bytes, "long", with_memory(budget));
  SequenceDecoder whole(std::make_shared<const Sequence>(decode_sequence_file(bytes, "long")));
  std::vector<double> times;
  for (int i = 0; i < 40; ++i) times.push_back(0.147 * i);
  std::vector<Decoded> expected;
  for (double t : times) expected.push_back(decode_at(whole, t));
  std::vector<std::thread> threads;
  std::vector<int> mismatches(3, 0);
  for (size_t i = 0; i < mismatches.size(); ++i) {
    threads.emplace_back([&, i] {
      SequenceDecoder decoder(source);
      // Each thread walks the times in another order, so their keyframes evict each other's.
      for (size_t j = 0; j < times.size(); ++j) {
        const size_t at = (j * (2 * i + 1) + 7 * i) % times.size();
        const Decoded d = decode_at(decoder, times[at]);
        if (d.positions != expected[at].positions || d.texture != expected[at].texture) ++mismatches[i];
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(mismatches, std::vector<int>(mismatches.size(), 0));
  EXPECT_LE(source->bytes_held(), budget);
}

TEST(KeyframeSource, OpeningDescribesTheFileAsTheWholeDecodeDoes) {
  const std::vector<uint8_t> bytes = long_file();
  SequenceFileInfo lazy_info, whole_info;
  const auto source = open_sequence_source(bytes, "long", kDefaultDecoderLimits, &lazy_info);
  testing::TempDir dir;
  format::write_file_atomically(dir.path() / "long.fmv", bytes);
  const SequenceFileInfo inspected = inspect_sequence_file(dir.path() / "long.fmv");
  const Sequence whole = decode_sequence_file(bytes, "long", &whole_info);
  const SequenceOutline expected = outline_of(whole);
  const SequenceOutline& outline = source->outline();
  EXPECT_EQ(outline.times, expected.times);
  ASSERT_EQ(outline.poses.size(), expected.poses.size());
  for (size_t k = 0; k < expected.poses.size(); ++k) {
    EXPECT_EQ(outline.poses[k].rotation, expected.poses[k].rotation);
    EXPECT_EQ(outline.poses[k].translation, expected.poses[k].translation);
  }
  EXPECT_EQ(outline.fixed_node_count, expected.fixed_node_count);
  EXPECT_EQ(outline.texture_size, expected.texture_size);
  EXPECT_EQ(outline.has_holes, expected.has_holes);
  EXPECT_EQ(lazy_info.file_bytes, whole_info.file_bytes);
  EXPECT_EQ(lazy_info.metadata.texture_codec, whole_info.metadata.texture_codec);
  ASSERT_EQ(lazy_info.keyframes.size(), whole_info.keyframes.size());
  ASSERT_EQ(inspected.keyframes.size(), whole_info.keyframes.size());
  for (size_t k = 0; k < whole_info.keyframes.size(); ++k) {
    EXPECT_EQ(lazy_info.keyframes[k].fields, 0u);  // nothing decoded at open
    EXPECT_EQ(lazy_info.keyframes[k].texture, whole_info.keyframes[k].texture);
    EXPECT_GT(inspected.keyframes[k].fields, 0u);
    EXPECT_EQ(inspected.keyframes[k].fields, whole_info.keyframes[k].fields);
    EXPECT_EQ(inspected.keyframes[k].texture, whole_info.keyframes[k].texture);
  }
  EXPECT_EQ(file_info(*source).keyframe_times, file_info(whole).keyframe_times);
  // fminfo's description (no keyframe decoded): each group's bytes are the sum of its keyframes'
  // shares, which only a decode divides, and the groups cover every keyframe once, in order.
  const SequenceFileInfo described = describe_sequence_file(dir.path() / "long.fmv");
  ASSERT_EQ(described.keyframes.size(), whole_info.keyframes.size());
  ASSERT_GT(described.field_groups.size(), 1u);
  size_t next = 0;
  for (const SequenceFileInfo::FieldGroup& group : described.field_groups) {
    EXPECT_EQ(group.first, next);
    uint64_t shares = 0;
    for (size_t k = group.first; k < group.first + group.count; ++k) {
      EXPECT_EQ(described.keyframes[k].fields, 0u);
      EXPECT_EQ(described.keyframes[k].texture, whole_info.keyframes[k].texture);
      shares += whole_info.keyframes[k].fields;
    }
    EXPECT_EQ(group.bytes, shares) << "the group from keyframe " << group.first;
    next = group.first + group.count;
  }
  EXPECT_EQ(next, whole_info.keyframes.size());
  EXPECT_EQ(described.chunks.size(), whole_info.chunks.size());
}

TEST(KeyframeSource, ATextureThatDoesNotDecodeFailsTheFramesThatShowItNotTheFile) {
  // A texture whose image bytes are replaced by others of the same length: its checksum is made
  // right, so the file opens (textures are decoded when a frame first needs them).
  const std::vector<uint8_t> bytes = crafted::rebuild(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()),
                                                      [](const std::string& type, std::vector<uint8_t>& payload) {
                                                        if (type == "TEXR" && payload.size() > 12 && payload[0] == 1) {
                                                          std::fill(payload.begin() + 8, payload.end(), 0x5A);
                                                        }
                                                      });
  const auto source = open_sequence_source(bytes, "broken texture");
  SequenceDecoder decoder(source);
  DecodeOptions no_texture;
  no_texture.texture = false;
  EXPECT_NO_THROW(decoder.decode(0.5, no_texture));  // keyframe 1's fields are fine
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1", [&] { decoder.decode(0.5); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1", [&] { source->texture(1); });
  EXPECT_NO_THROW(source->texture(0));
}

// A file padded before its end chunk with empty ancillary chunks (ignored by a reader): each takes
// 28 bytes of the file and a ChunkView of about 80 in the walk's list, which opening builds before
// the header is read.
std::vector<uint8_t> with_empty_chunks(const std::vector<uint8_t>& bytes, size_t count) {
  const format::ContainerReader reader(bytes, "in");
  format::ContainerWriter writer;
  for (const format::ChunkView& c : reader.chunks()) writer.add({c.type, c.flags, c.raw_size, {c.stored.begin(), c.stored.end()}});
  for (size_t i = 0; i < count; ++i) writer.add({"ZZZ1", 0, 0, {}});
  return writer.finish();
}

TEST(KeyframeSource, AFileOfManyEmptyChunksIsRefusedBeforeItsChunkListOutgrowsTheBudget) {
  // 28 MB of chunks under a 32 MiB budget: walked, their list alone would take about 80 MB.
  const std::vector<uint8_t> bytes =
      with_empty_chunks(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()), 1'000'000);
  ASSERT_LE(bytes.size(), uint64_t{32} << 20);
  testing::expect_error(ErrorCode::kLimit, "chunks", [&] { open_sequence_source(bytes, "many chunks", with_memory(uint64_t{32} << 20)); });
  // Mapped from disk, the file's size is no longer held to the budget: the same count refuses it.
  testing::TempDir dir;
  const auto path = dir / "many.fmv";
  format::write_file_atomically(path, bytes);
  testing::expect_error(ErrorCode::kLimit, "chunks", [&] { open_sequence_source(path, with_memory(uint64_t{4} << 20)); });
  // A file with a few unknown chunks still opens.
  EXPECT_NO_THROW(
      open_sequence_source(with_empty_chunks(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()), 100), "some"));
}

TEST(KeyframeSource, AStoredPayloadOverTheBudgetIsRefusedNotCopied) {
  // A texture chunk stored (not compressed) with 8 MiB after its image: a file mapped from disk is
  // not held to the budget as a whole, so each payload must be, before it is copied to decode. The
  // largest payload is counted when the file opens (§10.1), so it is refused there.
  const std::vector<uint8_t> bytes = crafted::rebuild(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()),
                                                      [](const std::string& type, std::vector<uint8_t>& payload) {
                                                        if (type == "TEXR" && payload.size() > 12 && payload[0] == 2)
                                                          payload.resize(payload.size() + (8 << 20));
                                                      });
  testing::TempDir dir;
  const auto path = dir / "padded.fmv";
  format::write_file_atomically(path, bytes);
  testing::expect_error(ErrorCode::kLimit, "over the memory limit", [&] { open_sequence_source(path, with_memory(uint64_t{4} << 20)); });
}

TEST(KeyframeSource, ATextureFailureKeepsItsErrorCodeWhenAskedAgain) {
  // Keyframe 1's texture names image codec 7: unsupported, not corrupt, the first time and after.
  const std::vector<uint8_t> bytes = crafted::rebuild(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()),
                                                      [](const std::string& type, std::vector<uint8_t>& payload) {
                                                        if (type == "TEXR" && payload.size() > 12 && payload[0] == 1) payload[4] = 7;
                                                      });
  const auto source = open_sequence_source(bytes, "codec 7");
  testing::expect_error(ErrorCode::kUnsupported, "image codec 7", [&] { source->texture(1); });
  testing::expect_error(ErrorCode::kUnsupported, "image codec 7", [&] { source->texture(1); });
}

// The budget split of spec/container.md §10.1, recomputed from its table: how many keyframes a
// source keeps under `budget`, and that its cache, played through, fills to their fields and
// textures and no further.
void expect_the_plan_of_section_10_1(const std::vector<uint8_t>& bytes, uint64_t budget) {
  const auto source = open_sequence_source(bytes, "plan", with_memory(budget));
  const Sequence whole = decode_sequence_file(bytes, "plan");
  const SequenceOutline& o = source->outline();
  const DiskGridShape shape = disk_grid_shape(o.grid_n);
  const auto n = static_cast<uint64_t>(shape.interior_count + shape.rim_count);
  uint64_t values = whole.keyframes[0].hole_level.size();
  for (const std::vector<double>& a : scalar_arrays(whole.keyframes[0].fields)) values += a.size();
  const auto m = static_cast<uint64_t>(o.texture_size);
  SequenceFileInfo info;
  decode_sequence_file(bytes, "plan", &info);
  // With texture groups (format 2.1), the AV1 decoder's 8 reference frames and the frame it decodes.
  const uint64_t av1_decoder = info.metadata.texture_coding == TextureCoding::kSequence && o.texture_size > 0 ? 9 * 3 * m * m : 0;
  const uint64_t f = 8 * values + 4 * n + 1024, s = 24 * n, x = 3 * m * m;
  const KeyframeSpline spline(o.times, o.spline);
  const auto w = static_cast<uint64_t>(spline.max_keys());
  const uint64_t fixed = estimated_memory_bytes(o.grid_n, 0, o.texture_size, values) + 256 * o.keyframe_count() + bytes.size() +
                         spline.memory_bytes() + w * (f + x) + budget / 16;
  uint64_t largest_payload = 0;
  const format::ContainerReader reader(bytes, "plan");
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == "KGOP" || c.type == "TEXR" || c.type == "TGOP") largest_payload = std::max(largest_payload, c.raw_size);
  }
  const uint64_t kept = (budget - fixed - 24 * values - largest_payload - av1_decoder) / (f + x + s);
  ASSERT_GE(kept, w);
  EXPECT_EQ(source->surfaces_kept(), kept);
  SequenceDecoder decoder(source);
  for (double t = o.times.front(); t <= o.times.back(); t += 0.05) {
    decoder.decode(t);
    ASSERT_LE(source->bytes_held(), kept * (f + x)) << "t = " << t;
  }
  if (kept < o.keyframe_count()) {
    EXPECT_GE(source->bytes_held() + f + x, kept * (f + x));
  }
}

TEST(KeyframeSource, TheBudgetIsSplitAsSection10_1Says) {
  const std::vector<uint8_t> bytes = long_file();
  expect_the_plan_of_section_10_1(bytes, crafted::smallest_budget(bytes));
  expect_the_plan_of_section_10_1(bytes, crafted::smallest_budget(bytes) + (256 << 10));
  // Not-a-knot: each keyframe's row of second-derivative weights is up to 124 values, held by a
  // decoder: with many keyframes, more than the index (measured before it was counted: 65536
  // keyframes at N = 5 under a 24 MiB budget, fmdec --null peaked at 82 MB RSS, 49 MB with
  // Catmull-Rom).
  expect_the_plan_of_section_10_1(long_file(SplineKind::kNotAKnot, 200), uint64_t{8} << 20);
  // Texture groups: the AV1 decoder's frames counted.
  const std::vector<uint8_t> grouped = long_grouped_file();
  expect_the_plan_of_section_10_1(grouped, crafted::smallest_budget(grouped));
}

// The whole run of a group's textures is kept only where the cache holds it twice over: under the
// smallest budget, asking for keyframe 5 keeps keyframe 5's texture (and no more of its group than
// the cache holds); under a large one, the group's 8.
TEST(KeyframeSource, AGroupsTexturesAreKeptWholeOnlyWhereTheCacheHoldsThemTwice) {
  const std::vector<uint8_t> bytes = long_grouped_file();
  const uint64_t texture = 3 * 64 * 64;
  const auto small = open_sequence_source(bytes, "grouped", with_memory(crafted::smallest_budget(bytes)));
  small->texture(5);
  EXPECT_EQ(small->bytes_held(), texture);
  const auto large = open_sequence_source(bytes, "grouped", with_memory(uint64_t{256} << 20));
  large->texture(5);
  EXPECT_EQ(large->bytes_held(), 8 * texture);
}

// A group's textures decoded on demand: keyframe k from its group's first frame up to k, kept as
// the cache allows (the whole group where it holds it twice over, else k alone), forwards and
// backwards, the same pixels as the file decoded whole; and every frame as the whole file's.
TEST(KeyframeSource, TextureGroupsDecodeOnDemandAsTheWholeFileDoes) {
  const std::vector<uint8_t> bytes = long_grouped_file();
  const Sequence whole = decode_sequence_file(bytes, "grouped");
  ASSERT_TRUE(whole.has_texture());
  std::vector<size_t> order;
  for (size_t k = 0; k < static_cast<size_t>(kKeyframes); ++k) order.push_back(k);
  for (size_t k = static_cast<size_t>(kKeyframes); k-- > 0;) order.push_back(k);
  for (size_t k = 5; k < static_cast<size_t>(kKeyframes); k += 11) order.push_back(k);  // jumps into groups
  const uint64_t budget = crafted::smallest_budget(bytes);
  for (uint64_t memory : {budget, uint64_t{256} << 20}) {
    SCOPED_TRACE(memory);
    const auto source = open_sequence_source(bytes, "grouped", with_memory(memory));
    for (size_t k : order) {
      ASSERT_EQ(source->texture(k)->pixels, whole.keyframes[k].texture.pixels) << "keyframe " << k;
      ASSERT_LE(source->bytes_held(), memory);
    }
  }
  // Under the smallest budget, frames as a player decodes them.
  const auto source = open_sequence_source(bytes, "grouped", with_memory(budget));
  SequenceDecoder lazy(source);
  SequenceDecoder all(std::make_shared<const Sequence>(whole));
  for (double t : {0.0, 0.45, 1.25, 3.3, 5.9, 2.0, 0.7}) expect_same(decode_at(lazy, t), decode_at(all, t), t);
}

// Opening reads the header and index only: a damaged group of keyframes opens, and its keyframes
// fail when asked for, naming the chunk, and at once every later time; the other group decodes.
TEST(KeyframeSource, ADamagedKeyframeGroupFailsItsKeyframesNotTheFile) {
  const std::vector<uint8_t> good = encode_sequence_file(crafted::small_sequence(), crafted::predicted_metadata());
  std::vector<uint8_t> bytes = good;
  const format::ContainerReader reader(good, "in");
  uint64_t at = 0;
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == "KGOP" && at == 0) at = c.offset + format::kChunkHeaderBytes + c.stored.size() / 2;  // keyframes 0-1's
  }
  ASSERT_GT(at, 0u);
  bytes[at] ^= 0x40;
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk KGOP", [&] { decode_sequence_file(bytes, "flipped"); });
  const auto source = open_sequence_source(bytes, "flipped");
  EXPECT_EQ(source->outline().poses.size(), 3u);
  testing::expect_error(ErrorCode::kCorrupt, "flipped: checksum mismatch in chunk KGOP", [&] { source->keyframe(1); });
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk KGOP", [&] { source->keyframe(1); });
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk KGOP", [&] { source->keyframe(0); });
  EXPECT_EQ(source->keyframe(2)->time, 1.0);
  SequenceDecoder decoder(source);
  EXPECT_THROW(decoder.decode(0.25), Error);
  EXPECT_TRUE(decoder.decode(1.0).converged);  // Catmull-Rom at a keyframe weighs only it
}

TEST(KeyframeSource, TheLargestChunkIsCountedAtOpen) {
  // A texture padded after its image (the image decoder reads only the image) to half the budget
  // that the plain file needs, in a file on disk: mapped, its size counts nowhere else. Decoding
  // that texture copies the payload on top of a full cache, so the file is refused at open.
  const std::vector<uint8_t> plain = encode_sequence_file(crafted::small_sequence(), crafted::small_metadata());
  const uint64_t budget = crafted::smallest_budget(plain);
  const std::vector<uint8_t> padded = crafted::rebuild(plain, [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "TEXR" && payload.size() > 12 && payload[0] == 1) payload.resize(payload.size() + budget / 2, 0);
  });
  testing::TempDir dir;
  const std::filesystem::path path = dir.path() / "padded.fmv";
  format::write_file_atomically(path, padded);
  testing::expect_error(ErrorCode::kLimit, "--max-memory", [&] { open_sequence_source(path, with_memory(budget)); });
  EXPECT_NO_THROW(open_sequence_source(path, with_memory(2 * budget)));
}

TEST(KeyframeSource, ATextureWithABadChecksumFailsWhenFirstShown) {
  // A texture's checksum is verified when the texture is first decoded (opening reads the header
  // and index only); inspect_sequence_file checks every chunk.
  std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(), crafted::small_metadata());
  uint64_t at = 0;
  const format::ContainerReader reader(bytes, "in");  // named: the chunks are views into it
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == "TEXR") at = c.offset + format::kChunkHeaderBytes + c.stored.size() - 1;
  }
  ASSERT_GT(at, 0u);
  bytes[at] ^= 0x40;
  const auto source = open_sequence_source(bytes, "bad crc");
  testing::expect_error(ErrorCode::kCorrupt, "bad crc: checksum mismatch in chunk TEXR", [&] { source->texture(2); });
  EXPECT_NO_THROW(source->texture(0));
  testing::TempDir dir;
  format::write_file_atomically(dir.path() / "bad.fmv", bytes);
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk TEXR", [&] { inspect_sequence_file(dir.path() / "bad.fmv"); });
  // fminfo's description decodes nothing, and verifies every checksum all the same.
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk TEXR", [&] { describe_sequence_file(dir.path() / "bad.fmv"); });
}

// G is built once per opened file: every decoder on a source shares its grid geometry.
TEST(KeyframeSource, DecodersOnOneSourceShareOneGrid) {
  const auto source = open_sequence_source(encode_sequence_file(crafted::small_sequence(), crafted::small_metadata()), "shared");
  const std::shared_ptr<const GridGeometry> grid = source->grid_geometry();
  ASSERT_TRUE(grid);
  EXPECT_EQ(grid->grid().n, source->outline().grid_n);
  const long held = grid.use_count();
  SequenceDecoder first(source), second(source);
  EXPECT_EQ(source->grid_geometry().get(), grid.get());
  EXPECT_EQ(grid.use_count(), held + 2);  // each decoder holds the source's G, not one of its own
  EXPECT_EQ(first.decode(0.25).grid_positions, second.decode(0.25).grid_positions);
}

}  // namespace
}  // namespace facemorph
