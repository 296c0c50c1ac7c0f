// The decoder's limits end to end (issue 46, spec/container.md §5, §6, §9, §10): the header and the
// index decompress to no more than the format lets them hold, their strings within one budget, no
// byte after their last field in a file of a known version, no compressed TEXR; a decode call's
// work bounded (DecodeOptions::max_work, DecoderLimits::max_work) and resumed by the next call to
// the same bits; hole levels checked where they are read; a group's stream read to its end before
// any of its keyframes is shown; failures naming the file and t. Every file is crafted with valid
// checksums (crafted::rebuild), so each test reaches the check it means.
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/decoder/container/chunk_readers.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/zstd_frame.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>

namespace facemorph {
namespace {

using crafted::rebuild;
using crafted::small_metadata;
using crafted::small_sequence;
using crafted::with_minor_version;

// An edit that appends `extra` bytes to the payload of chunks of `type`.
auto appending(std::string type, size_t extra, uint8_t value = 0) {
  return [type, extra, value](const std::string& t, std::vector<uint8_t>& payload) {
    if (t == type) payload.insert(payload.end(), extra, value);
  };
}

std::vector<uint8_t> small_file() { return encode_sequence_file(small_sequence(), small_metadata()); }

void open_bytes(const std::vector<uint8_t>& bytes, const DecoderLimits& limits = kDefaultDecoderLimits) {
  open_sequence_source(bytes, "crafted.fmv", limits);
}

// ---- One budget: the header and the index hold what the format lets them, no more ----

TEST(DecodeLimits, AByteAfterTheHeaderOrIndexIsCorruptInAKnownVersion) {
  const std::vector<uint8_t> good = small_file();
  open_bytes(good);
  testing::expect_error(ErrorCode::kCorrupt, "header: 1 bytes after its last field",
                        [&] { open_bytes(rebuild(good, appending("HEAD", 1))); });
  testing::expect_error(ErrorCode::kCorrupt, "index: 1 bytes after its last field",
                        [&] { open_bytes(rebuild(good, appending("KIDX", 1))); });
  // fminfo's path says the same.
  testing::expect_error(ErrorCode::kCorrupt, "after its last field",
                        [&] { decode_sequence_file(rebuild(good, appending("HEAD", 1)), "crafted.fmv"); });
}

TEST(DecodeLimits, ALaterMinorVersionMayAppendAtMost64KiB) {
  const std::vector<uint8_t> good = small_file();
  // What a later minor version appends is skipped (spec/container.md §12.1)...
  open_bytes(with_minor_version(rebuild(good, appending("HEAD", 100)), format::kMinorVersion + 1));
  open_bytes(with_minor_version(rebuild(good, appending("KIDX", 100)), format::kMinorVersion + 1));
  // ...up to 64 KiB: more is a chunk making the reader decompress what it ignores.
  testing::expect_error(ErrorCode::kCorrupt, "at most 64 KiB", [&] {
    open_bytes(with_minor_version(rebuild(good, appending("HEAD", (64 << 10) + 1)), format::kMinorVersion + 1));
  });
  testing::expect_error(ErrorCode::kCorrupt, "at most 64 KiB", [&] {
    open_bytes(with_minor_version(rebuild(good, appending("KIDX", (64 << 10) + 1)), format::kMinorVersion + 1));
  });
}

// The header payload's landmark names replaced by `count` names of `bytes` bytes each (the names
// are followed by the intra period, 14 steps and 2 pose steps: 132 bytes).
auto with_landmark_names(uint32_t count, uint32_t bytes) {
  return [count, bytes](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "HEAD") return;
    constexpr size_t kTail = 4 + 14 * 8 + 2 * 8;
    const std::vector<uint8_t> tail(payload.end() - kTail, payload.end());
    // small_metadata's names: "nose_tip" and "rim_top", after their count.
    const size_t names_at = payload.size() - kTail - (4 + 8) - (4 + 7) - 4;
    payload.resize(names_at);
    format::ByteWriter w;
    w.write(count);
    for (uint32_t i = 0; i < count; ++i) {
      w.write(bytes);
      for (uint32_t b = 0; b < bytes; ++b) w.write(static_cast<uint8_t>('a' + b % 26));
    }
    const std::vector<uint8_t> names = w.take();
    payload.insert(payload.end(), names.begin(), names.end());
    payload.insert(payload.end(), tail.begin(), tail.end());
  };
}

TEST(DecodeLimits, TheHeadersStringsTakeAtMostFourMiBTogether) {
  const std::vector<uint8_t> good = small_file();
  open_bytes(rebuild(good, with_landmark_names(3, 1u << 20)));  // 3 MiB of names and the rest: within
  // 470 names of 1 MiB took 1.68 GB against a 512 MiB budget.
  testing::expect_error(ErrorCode::kCorrupt, "at most 4 MiB together",
                        [&] { open_bytes(rebuild(good, with_landmark_names(5, 1u << 20))); });
  // The writer refuses what a reader would.
  SequenceFileMetadata metadata = small_metadata();
  metadata.landmark_names.assign(5, std::string(1u << 20, 'x'));
  testing::expect_error(ErrorCode::kInvalidArgument, "at most 4 MiB together", [&] { encode_sequence_file(small_sequence(), metadata); });
}

// A HEAD chunk whose zstd frame announces `announced` bytes (a frame zstd could expand to that) and
// is a valid header followed by zeros up to it.
std::vector<uint8_t> with_header_announcing(const std::vector<uint8_t>& good, uint64_t announced) {
  const format::ContainerReader reader(good, "good");
  std::vector<uint8_t> header = reader.payload(reader.chunks()[0]);
  header.resize(static_cast<size_t>(announced), 0);
  bool first = true;
  return rebuild(good, [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD" && first) payload = header;
    first = false;
  });
}

TEST(DecodeLimits, AHeaderStatingMoreThanItCanHoldIsRefusedBeforeItIsDecompressed) {
  const std::vector<uint8_t> good = small_file();
  // 500 MB of zeros after the header took 773 MB and 9 s: now refused from the chunk's stated size.
  // (Made here at 64 MiB: the check is the same, the test's own buffers smaller.)
  const std::vector<uint8_t> padded = with_header_announcing(good, uint64_t{64} << 20);
  EXPECT_LT(padded.size(), 100000u);
  const auto start = std::chrono::steady_clock::now();
  testing::expect_error(ErrorCode::kCorrupt, "a header holds at most", [&] { open_bytes(padded); });
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
  // Within the format's bound (N = 4097's fixed nodes) but over what the caller's grid limit lets
  // a header hold: a limit, naming it.
  DecoderLimits small_grid;
  small_grid.max_grid_n = 17;
  testing::expect_error(ErrorCode::kLimit, "max_grid_n", [&] { open_bytes(with_header_announcing(good, uint64_t{6} << 20), small_grid); });
  // The bound is what a header can hold: one at the bound less the appended 64 KiB is not refused
  // for its size (it is for its bytes after the last field).
  testing::expect_error(ErrorCode::kCorrupt, "after its last field",
                        [&] { open_bytes(with_header_announcing(good, file_layout::max_header_bytes(17) - (64 << 10)), small_grid); });
}

TEST(DecodeLimits, AnIndexStatingMoreThanItsEntriesCanHoldIsRefusedBeforeItIsDecompressed) {
  const std::vector<uint8_t> good = small_file();
  const std::vector<uint8_t> padded = rebuild(good, appending("KIDX", 8u << 20));
  testing::expect_error(ErrorCode::kCorrupt, "an index of 3 keyframes holds at most", [&] { open_bytes(padded); });
}

TEST(DecodeLimits, ACompressedTextureIsCorruptAtOpen) {
  // A TEXR stored as a zstd frame (spec/container.md §8 stores it as it is): 17 kB of file held
  // 300 MB of texture to decode. Padded with zeros so that zstd makes it smaller and keeps it so.
  const std::vector<uint8_t> bytes = rebuild(small_file(), appending("TEXR", 1 << 16), false, false, {"TEXR"});
  const format::ContainerReader reader(bytes, "crafted");
  ASSERT_TRUE(
      std::any_of(reader.chunks().begin(), reader.chunks().end(), [](const auto& c) { return c.type == "TEXR" && c.compressed(); }));
  testing::expect_error(ErrorCode::kCorrupt, "a texture's chunk never is", [&] { open_bytes(bytes); });
}

// ---- Every value read is checked where it is read ----

// The header's step for array `a` (§5: 14 steps then 2 pose steps end the payload) set to `step`.
auto with_step(size_t a, double step) {
  return [a, step](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") std::memcpy(payload.data() + payload.size() - 16 - 8 * (14 - a), &step, sizeof step);
  };
}

TEST(DecodeLimits, AHoleLevelBeyondItsBoundIsCorruptNamingTheKeyframeAndTheFile) {
  // The hole level's step (array 13) scaled so that its codes decode to levels beyond 16, or to
  // infinity: fminfo accepted these, and fmdec failed in the hole cut naming neither file nor keyframe.
  for (const double step : {1e3, 1e305}) {
    const std::vector<uint8_t> bytes = rebuild(small_file(), with_step(file_layout::kKeyframeArrays - 1, step));
    testing::expect_error(ErrorCode::kCorrupt, "hole level", [&] { decode_sequence_file(bytes, "holes.fmv"); });
    const auto source = open_sequence_source(bytes, "holes.fmv");
    SequenceDecoder decoder(source);
    testing::expect_error(ErrorCode::kCorrupt, "holes.fmv: t = 0.25 s: ", [&] { decoder.decode(0.25); });
    testing::expect_error(ErrorCode::kCorrupt, "(keyframe 0): hole level", [&] { decoder.decode(0.25); });
  }
}

// ---- A group's stream is read to its end before any keyframe of it is shown ----

TEST(DecodeLimits, AByteAfterAGroupsStreamFailsEveryFrameOfTheGroup) {
  // Groups of two keyframes (predicted_metadata), each stream followed by one byte.
  const std::vector<uint8_t> bytes =
      rebuild(encode_sequence_file(small_sequence(), crafted::predicted_metadata()), appending("KGOP", 1, 0x5A));
  testing::expect_error(ErrorCode::kCorrupt, "", [&] { decode_sequence_file(bytes, "tail.fmv"); });  // fminfo's path
  // Playing: at the default budget (the whole run kept) and under the smallest that opens the file,
  // which keeps too few keyframes for a whole run (decoded only as far as the keyframe asked for,
  // which skipped this check), every time fails.
  for (const uint64_t budget : {kDefaultDecoderLimits.max_memory_bytes, crafted::smallest_budget(bytes)}) {
    DecoderLimits limits;
    limits.max_memory_bytes = budget;
    const auto source = open_sequence_source(bytes, "tail.fmv", limits);
    SequenceDecoder decoder(source);
    for (const double t : {0.0, 0.5, 1.0, 0.25}) {
      testing::expect_error(ErrorCode::kCorrupt, "tail.fmv: t = ", [&] { decoder.decode(t); });
    }
    for (size_t k = 0; k < 3; ++k) EXPECT_THROW(source->keyframe(k), Error);
  }
}

// ---- A bound on the work of one call ----

// The frame at t decoded with a work limit of `limit` units a call, calling again after each stop:
// the calls it took. `frame` gets the frame.
int decode_in_calls(SequenceDecoder& decoder, double t, uint64_t limit, DecodedFrame& frame) {
  DecodeOptions options;
  options.max_work = limit;
  for (int calls = 1; calls <= 1000; ++calls) {
    try {
      frame = decoder.decode(t, options);
      return calls;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kLimit) << e.what();
      EXPECT_NE(std::string(e.what()).find("max_work"), std::string::npos) << e.what();
      if (e.code() != ErrorCode::kLimit) return -1;
    }
  }
  return -1;
}

TEST(DecodeLimits, AStoppedCallGoesOnInTheNextToTheSameBits) {
  // N = 65, every keyframe its own group: a call decodes a keyframe's values (a group's stream is
  // decoded in one call, spec/container.md §10.3) and iterates; a surface goes on across calls.
  SequenceFileMetadata alone = crafted::predicted_metadata();
  alone.field_coding.intra_period = 1;
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(65, 16), alone);
  const auto unbounded_source = open_sequence_source(bytes, "f.fmv");
  SequenceDecoder unbounded(unbounded_source);
  DecodeOptions no_limit;
  no_limit.max_work = 0;
  const DecodedFrame expected = unbounded.decode(0.3, no_limit);

  const auto source = open_sequence_source(bytes, "f.fmv");
  SequenceDecoder decoder(source);
  DecodedFrame frame;
  // Room for a keyframe's values (about 5 a node of G's interior) and one iteration (4 a node), or
  // two iterations, never three: every surface that takes three or more goes on across calls.
  const auto interior = static_cast<uint64_t>(disk_grid_shape(65).interior_count);
  const uint64_t limit = 10 * interior;
  static_assert(WorkMeter::kPerNodeIteration == 4, "the limit above allows two iterations, not three");
  const int calls = decode_in_calls(decoder, 0.3, limit, frame);
  EXPECT_GT(calls, 4) << "the limit should have stopped the first calls";
  ASSERT_EQ(frame.grid_positions.size(), expected.grid_positions.size());
  for (size_t v = 0; v < frame.grid_positions.size(); ++v) ASSERT_EQ(frame.grid_positions[v], expected.grid_positions[v]) << "node " << v;
  EXPECT_EQ(frame.iterations, expected.iterations);
  EXPECT_EQ(frame.texture.pixels, expected.texture.pixels);
  // Each keyframe's surface was reconstructed once, though it took several calls.
  EXPECT_EQ(decoder.keyframe_reconstructions(), unbounded.keyframe_reconstructions());
  // The next frame of the clip decodes in one call under the same limit: the surfaces are kept.
  DecodedFrame next;
  EXPECT_EQ(decode_in_calls(decoder, 0.3 + 1.0 / 30, 40 * 3000 * WorkMeter::kPerNodeIteration, next), 1);
}

TEST(DecodeLimits, TheWorkLimitComesFromTheLimitsTheFileWasOpenedWith) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(65, 16), small_metadata());
  DecoderLimits limits;
  limits.max_work = 1000;  // less than one keyframe's values
  const auto source = open_sequence_source(bytes, "f.fmv", limits);
  SequenceDecoder decoder(source);
  // No progress is possible: every call stops at the same step, naming it, and nothing is
  // remembered as the file's fault.
  for (int i = 0; i < 3; ++i)
    testing::expect_error(ErrorCode::kLimit, "f.fmv: t = 0.3 s: decoding keyframe 0's", [&] { decoder.decode(0.3); });
  DecodeOptions raised;
  raised.max_work = 0;
  EXPECT_NO_THROW(decoder.decode(0.3, raised));
  // A texture of M² pixels is paid before it is decoded, and a stop leaves it to the next call.
  const auto textured = open_sequence_source(bytes, "f.fmv");
  WorkMeter short_of_a_texture(16 * 16 * WorkMeter::kPerPixel - 1, "f.fmv");
  testing::expect_error(ErrorCode::kLimit, "decoding keyframe 1's texture of 16² pixels",
                        [&] { textured->texture(1, short_of_a_texture); });
  EXPECT_TRUE(short_of_a_texture.stopped());
  WorkMeter enough(16 * 16 * WorkMeter::kPerWebpPixel, "f.fmv");  // lossless stills: WebP
  EXPECT_EQ(textured->texture(1, enough)->width, 16);
}

// Calls source.keyframe(k) or source.texture(k) (`get`) with a fresh meter of `limit` until one
// returns; the number of calls (-1: none returned in 100, or a failure other than the meter's).
template <typename Get>
int fetch_in_calls(const Get& get, uint64_t limit) {
  for (int calls = 1; calls <= 100; ++calls) {
    WorkMeter meter(limit, "g.fmv");
    try {
      get(meter);
      return calls;
    } catch (const Error& e) {
      EXPECT_TRUE(meter.stopped()) << e.what();
      if (!meter.stopped()) return -1;
    }
  }
  return -1;
}

TEST(DecodeLimits, ARunCostingMoreThanOneCallDecodesOverSeveral) {
  // One group of three keyframes (fields and an AV1 texture sequence), each call affording one
  // keyframe's values or one texture frame's pixels: the last keyframe takes three calls, each
  // going on where the one before stopped (before, every call began the run again and none ended).
  SequenceFileMetadata grouped = crafted::grouped_texture_metadata();
  grouped.field_coding.intra_period = 3;
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(17, 16), grouped);
  const auto whole = open_sequence_source(bytes, "g.fmv");
  WorkMeter counted(0);
  const std::shared_ptr<const Keyframe> expected = whole->keyframe(2, counted);
  const std::shared_ptr<const Image> expected_texture = whole->texture(2);
  const uint64_t one_keyframe = counted.spent() / 3;  // the run was read to its end: three keyframes
  ASSERT_GT(one_keyframe, 0u);

  const auto source = open_sequence_source(bytes, "g.fmv");
  std::shared_ptr<const Keyframe> key;
  EXPECT_EQ(fetch_in_calls([&](WorkMeter& meter) { key = source->keyframe(2, meter); }, one_keyframe), 3);
  ASSERT_TRUE(key);
  EXPECT_EQ(scalar_arrays(key->fields), scalar_arrays(expected->fields));
  EXPECT_EQ(key->hole_level, expected->hole_level);
  std::shared_ptr<const Image> texture;
  EXPECT_EQ(fetch_in_calls([&](WorkMeter& meter) { texture = source->texture(2, meter); }, 16 * 16 * WorkMeter::kPerPixel), 3);
  ASSERT_TRUE(texture);
  EXPECT_EQ(texture->pixels, expected_texture->pixels);

  // A stopped run is another keyframe's too: asking for keyframe 1 after a stop at keyframe 1 of
  // the run for keyframe 2 goes on, and a fault of the file still fails the whole group.
  const auto other = open_sequence_source(bytes, "g.fmv");
  WorkMeter one(one_keyframe, "g.fmv");
  EXPECT_THROW(other->keyframe(2, one), Error);
  EXPECT_EQ(fetch_in_calls([&](WorkMeter& meter) { key = other->keyframe(1, meter); }, 2 * one_keyframe), 1);
  EXPECT_EQ(scalar_arrays(key->fields), scalar_arrays(whole->keyframe(1)->fields));
  const auto damaged = open_sequence_source(rebuild(bytes, appending("KGOP", 1)), "g.fmv");
  WorkMeter stop(one_keyframe, "g.fmv");
  EXPECT_THROW(damaged->keyframe(0, stop), Error);
  EXPECT_TRUE(stop.stopped());
  testing::expect_error(ErrorCode::kCorrupt, "g.fmv", [&] { damaged->keyframe(0); });
  testing::expect_error(ErrorCode::kCorrupt, "g.fmv", [&] { damaged->keyframe(2); });
}

TEST(DecodeLimits, LargeResidualsAreChargedByTheDecisionsTheyTake) {
  // A group of two keyframes whose array 0 zigzags between codes ±(2^30 - 1) under predictor 0 (a
  // hostile file's residuals, valid: it decodes). Each such residual takes 69 decisions and direct
  // bits (zero, sign, 8 unary, 30 escape prefix, 29 suffix; every other value at least 1), where
  // a value's own unit pays for 2 (spec/container.md §10.3): the call is charged for the rest, a
  // unit per kDecisionsPerUnit.
  const std::vector<uint8_t> plain = encode_sequence_file(small_sequence(), crafted::predicted_metadata());
  const std::vector<uint8_t> bytes = crafted::with_first_group_by_hand(plain, false, [](crafted::HandCodedKeyframe& key) {
    for (size_t i = 0; i < key.residuals[0].size(); ++i) key.residuals[0][i] = (i % 2 ? 1 : -1) * (int64_t{1} << 30) + (i % 2 ? -1 : 1);
  });
  const Sequence decoded = decode_sequence_file(bytes, "w.fmv");
  uint64_t values = 0;
  for (const std::vector<double>& array : file_layout::keyframe_arrays(decoded.keyframes[0])) values += array.size();
  const uint64_t large = file_layout::keyframe_arrays(decoded.keyframes[0])[0].size();
  ASSERT_GT(large, 0u);
  EXPECT_NEAR(std::abs(file_layout::keyframe_arrays(decoded.keyframes[1])[0][1]) / 1e-4, (1 << 30) - 1, 1e-3);  // decoded as written

  WorkMeter counted(0);
  open_sequence_source(bytes, "w.fmv")->keyframe(1, counted);  // the group's two keyframes
  const uint64_t decisions_at_least = 69 * large + (values - large);
  const uint64_t charged_at_least =
      values * WorkMeter::kPerValue + (decisions_at_least - WorkMeter::kDecisionsInValue * values) / WorkMeter::kDecisionsPerUnit;
  EXPECT_GE(counted.spent(), 2 * charged_at_least);

  // The decisions are learnt as the keyframe is decoded: they are counted after it, and the call
  // stops before its next step: a limit of two keyframes' values decodes keyframe 0, then stops
  // (one unit a value would decode both in one call).
  const auto source = open_sequence_source(bytes, "w.fmv");
  EXPECT_EQ(fetch_in_calls([&](WorkMeter& meter) { source->keyframe(1, meter); }, 2 * values), 2);
}

TEST(DecodeLimits, AFrameOfALongGroupDecodesOverSeveralCallsToTheSameBits) {
  // The decoder's view: a frame whose keyframes lie late in a group that costs more than a call.
  SequenceFileMetadata grouped = crafted::grouped_texture_metadata();
  grouped.field_coding.intra_period = 3;
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(33, 16), grouped);
  SequenceDecoder unbounded(open_sequence_source(bytes, "g.fmv"));
  DecodeOptions no_limit;
  no_limit.max_work = 0;
  const DecodedFrame expected = unbounded.decode(0.9, no_limit);
  SequenceDecoder decoder(open_sequence_source(bytes, "g.fmv"));
  DecodedFrame frame;
  const auto interior = static_cast<uint64_t>(disk_grid_shape(33).interior_count);
  const int calls = decode_in_calls(decoder, 0.9, 8 * interior, frame);  // under two keyframes' values
  EXPECT_GT(calls, 2);
  ASSERT_EQ(frame.grid_positions.size(), expected.grid_positions.size());
  for (size_t v = 0; v < frame.grid_positions.size(); ++v) ASSERT_EQ(frame.grid_positions[v], expected.grid_positions[v]) << "node " << v;
  EXPECT_EQ(frame.texture.pixels, expected.texture.pixels);
}

}  // namespace
}  // namespace facemorph
