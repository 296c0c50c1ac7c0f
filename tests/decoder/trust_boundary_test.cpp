// The decoder as a trust boundary (issue 27, spec/container.md §10): files that pass every checksum
// but state sizes, ranges or fields meant to take the player's machine are refused by name — or
// decoded to finite output — within the default limits, and C API handles cannot be misused into
// memory errors. Every file here is crafted with valid checksums (crafted::rebuild), so each test
// reaches the check it means.
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/decoder/player/decoder.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "facemorph.h"
#include "format/zstd_frame.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace facemorph {
namespace {

using crafted::predicted_metadata;
using crafted::rebuild;
using crafted::small_metadata;
using crafted::small_sequence;

using testing::kGoldenV2_0;

// Seconds `body` takes.
template <typename Body>
double seconds(Body&& body) {
  const auto start = std::chrono::steady_clock::now();
  body();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Resident and peak resident memory of this process (Linux /proc), bytes; 0 where unknown.
uint64_t status_bytes(const std::string& field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind(field + ":", 0) == 0) {
      std::istringstream in(line.substr(field.size() + 1));
      uint64_t kb = 0;
      in >> kb;
      return kb * 1024;
    }
  }
  return 0;
}

// Resets the peak (VmHWM) to the current resident size: what a call allocates is then its peak
// minus the resident size before it.
bool reset_peak() {
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
  return static_cast<bool>(clear);
}

// A zstd frame (RFC 8878) that announces `announced` bytes, holds `blocks` RLE blocks of 128 KiB
// and then a reserved block type: a frame whose announcement passes every size check (padded to
// zstd's largest expansion) but that fails after `blocks` × 128 KiB.
std::vector<uint8_t> lying_zstd_frame(uint64_t announced, int blocks) {
  std::vector<uint8_t> f = {0x28, 0xB5, 0x2F, 0xFD, 0xE0};  // magic; single segment, 8-byte content size
  for (int i = 0; i < 8; ++i) f.push_back(static_cast<uint8_t>(announced >> (8 * i)));
  const auto block_header = [&](uint32_t last, uint32_t type, uint32_t size) {
    const uint32_t h = last | (type << 1) | (size << 3);
    for (int i = 0; i < 3; ++i) f.push_back(static_cast<uint8_t>(h >> (8 * i)));
  };
  for (int b = 0; b < blocks; ++b) {
    block_header(0, 1, 128 << 10);  // RLE: one byte repeated 128 KiB times
    f.push_back(0);
  }
  block_header(1, 3, 0);  // reserved block type: damaged here
  const auto needed = static_cast<size_t>(announced / format::kMaxZstdExpansion + 1);
  if (f.size() < needed) f.resize(needed, 0);
  return f;
}

// ---- Limits: sizes a header states, refused before they are allocated ----

// The header's layout (spec/container.md §5): N at 0, the keyframe count at 20, the pose centre at
// 48, the texture size at 72.
template <typename T>
auto patch_header(size_t at, T value) {
  return [at, value](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") std::memcpy(payload.data() + at, &value, sizeof value);
  };
}

TEST(TrustBoundary, AGridOverTheLimitIsRefusedBeforeItIsBuilt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  // 238 bytes naming N = 4097 took 7 s and 1.2 GB building G to check its hash.
  const std::vector<uint8_t> big = rebuild(bytes, patch_header<uint32_t>(0, 4097));
  const double s = seconds([&] {
    testing::expect_error(ErrorCode::kLimit, "grid size 4097 over the limit of 1025", [&] { decode_sequence_file(big, "n.fmv"); });
  });
  EXPECT_LT(s, 0.1);
  // N = 1025 with its rim count but another grid's hash: the hash comes from a table, so the refusal
  // builds no G (which took 0.12 s and 90 MB at N = 1025).
  const std::vector<uint8_t> wrong_hash = rebuild(bytes, [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "HEAD") return;
    const uint32_t n = 1025, rim = static_cast<uint32_t>(disk_grid_shape(1025).rim_count);
    std::memcpy(payload.data(), &n, 4);
    std::memcpy(payload.data() + 76, &rim, 4);
  });
  // (Under the default budget its solver alone is over the limit: refused before the hash.)
  testing::expect_error(ErrorCode::kLimit, "over the memory limit", [&] { decode_sequence_file(wrong_hash, "h.fmv"); });
  DecoderLimits roomy;
  roomy.max_memory_bytes = uint64_t{4} << 30;
  const bool measured = reset_peak();
  const uint64_t before = status_bytes("VmRSS");
  const double hash_s = seconds([&] {
    testing::expect_error(ErrorCode::kUnsupported, "N = 1025", [&] { decode_sequence_file(wrong_hash, "h.fmv", nullptr, roomy); });
  });
  EXPECT_LT(hash_s, 0.1);
  if (measured && before > 0) {
    EXPECT_LT(status_bytes("VmHWM") - before, uint64_t{64} << 20);
  }
  // A caller may allow more (then the hash decides: N changed, the rim count no longer matches).
  DecoderLimits wide;
  wide.max_grid_n = 4097;
  testing::expect_error(ErrorCode::kCorrupt, "rim nodes",
                        [&] { decode_sequence_file(rebuild(bytes, patch_header<uint32_t>(0, 33)), "n.fmv", nullptr, wide); });
  // Under the limit a smaller one refuses what the default reads.
  DecoderLimits narrow;
  narrow.max_grid_n = 8;
  testing::expect_error(ErrorCode::kLimit, "grid size 9 over the limit of 8",
                        [&] { decode_sequence_file(bytes, "s.fmv", nullptr, narrow); });
}

TEST(TrustBoundary, KeyframesTexturesAndMemoryOverTheLimitsAreRefusedFromTheHeader) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  testing::expect_error(ErrorCode::kLimit, "over the limit of 65536 (max_keyframes)",
                        [&] { decode_sequence_file(rebuild(bytes, patch_header<uint32_t>(20, 70000)), "k.fmv"); });
  testing::expect_error(ErrorCode::kLimit, "texture size 8192 over the limit of 4096",
                        [&] { decode_sequence_file(rebuild(bytes, patch_header<uint32_t>(72, 8192)), "t.fmv"); });
  // 5000 keyframes of 4096² textures: 250 GB decoded from a file of a few kB. Refused from the
  // header, before the index is read, in well under 0.1 s.
  const std::vector<uint8_t> huge = rebuild(rebuild(bytes, patch_header<uint32_t>(20, 5000)), patch_header<uint32_t>(72, 4096));
  const double s = seconds([&] {
    testing::expect_error(ErrorCode::kLimit, "over the memory limit of 256.0 MiB", [&] { decode_sequence_file(huge, "m.fmv"); });
  });
  EXPECT_LT(s, 0.1);
  // The estimate counts every keyframe's fields and texture (all are decoded at open): the default
  // budget holds 20 keyframes of 1024² on a grid of 257, not 40, nor 200 of 4096², nor a grid of 1025.
  const uint64_t fields = 5 * 52000;
  EXPECT_LT(estimated_memory_bytes(257, 20, 1024, fields), kDefaultDecoderLimits.max_memory_bytes);
  EXPECT_GT(estimated_memory_bytes(257, 40, 1024, fields), kDefaultDecoderLimits.max_memory_bytes);
  EXPECT_GT(estimated_memory_bytes(257, 200, 4096, fields), kDefaultDecoderLimits.max_memory_bytes);
  EXPECT_GT(estimated_memory_bytes(1025, 1, 0, 5 * 830000), kDefaultDecoderLimits.max_memory_bytes);
  EXPECT_EQ(estimated_memory_bytes(4097, uint64_t{1} << 62, 16384, fields), std::numeric_limits<uint64_t>::max());  // saturates
}

TEST(TrustBoundary, ACompressedPayloadCostsWhatItHoldsNotWhatItAnnounces) {
  // A HEAD chunk whose zstd frame announces 6 MiB (within what a header may hold at the default
  // grid limit, and a size 200 bytes of zstd could produce) and is damaged after 1 MiB: refused as
  // corrupt, having held about what it held.
  const uint64_t announced = uint64_t{6} << 20;
  format::PreparedChunk head{"HEAD", format::kChunkCompressed | format::kChunkCritical, announced, lying_zstd_frame(announced, 8)};
  const auto file_of = [](const format::PreparedChunk& header) {
    format::ContainerWriter writer;
    writer.add(header);
    writer.add(format::prepare_chunk("KIDX", {0, 0, 0, 0}, true));
    return writer.finish();
  };
  const std::vector<uint8_t> file = file_of(head);
  EXPECT_LT(file.size(), 20000u);
  const bool measured = reset_peak();
  const uint64_t before = status_bytes("VmRSS");
  testing::expect_error(ErrorCode::kCorrupt, "damaged zstd payload", [&] { decode_sequence_file(file, "z.fmv"); });
  if (measured && before > 0) {
    EXPECT_LT(status_bytes("VmHWM") - before, uint64_t{64} << 20);
  }
  // Announcing more than the budget is a limit before anything is allocated; more than zstd can
  // expand the stored bytes to, corrupt.
  DecoderLimits small_budget;
  small_budget.max_memory_bytes = uint64_t{4} << 20;
  testing::expect_error(ErrorCode::kLimit, "over the memory limit", [&] { decode_sequence_file(file, "o.fmv", nullptr, small_budget); });
  head.stored = lying_zstd_frame(announced, 1);
  head.stored.resize(40);  // announces 6 MiB from 40 bytes
  testing::expect_error(ErrorCode::kCorrupt, "more than zstd can expand", [&] { decode_sequence_file(file_of(head), "l.fmv"); });
  // Announcing more than a header can hold (spec/container.md §5: 400 MiB of which 6 MiB could be
  // strings and fixed nodes): corrupt from the chunk's stated size, before a byte is decompressed.
  head.raw_size = uint64_t{400} << 20;
  head.stored = lying_zstd_frame(head.raw_size, 8);
  testing::expect_error(ErrorCode::kCorrupt, "a header holds at most", [&] { decode_sequence_file(file_of(head), "h.fmv"); });
}

// ---- Ranges: every number a file states is bounded where it is read ----

TEST(TrustBoundary, APoseCentreOrTranslationBeyondItsBoundIsCorrupt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  // A finite centre of 1.7e308 overflowed in the pose blend and decoded to -inf with FM_OK.
  testing::expect_error(ErrorCode::kCorrupt, "pose centre coordinate beyond 1e9",
                        [&] { decode_sequence_file(rebuild(bytes, patch_header(48, 1.7e308)), "c.fmv"); });
  // The index's translation of keyframe 1 moved 2^39 steps of 10 µm: 5.5e9 mm.
  const auto far = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "KIDX") payload = crafted::with_pose_change(payload, 3, 1, int64_t{1} << 39);
  };
  testing::expect_error(ErrorCode::kCorrupt, "translation beyond 1e9", [&] { decode_sequence_file(rebuild(bytes, far), "t.fmv"); });
}

TEST(TrustBoundary, KeyframeTimesTooCloseForTheSplineAreCorruptNotAnArgumentError) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  // Times 0, 1e-200, 1: increasing and finite, but the spline's ratios of intervals are not.
  const auto close_times = [](const std::string& type, std::vector<uint8_t>& payload) {
    const double t = 1e-200;
    if (type == "KIDX") std::memcpy(payload.data() + 4 + 8, &t, 8);
  };
  testing::expect_error(ErrorCode::kCorrupt, "1e-9 of the keyframes' span",
                        [&] { decode_sequence_file(rebuild(bytes, close_times), "t.fmv"); });
  fm_file* file = nullptr;
  const std::vector<uint8_t> crafted = rebuild(bytes, close_times);
  EXPECT_EQ(fm_file_open_memory(crafted.data(), crafted.size(), &file), FM_ERROR_CORRUPT) << fm_last_error_message();
  EXPECT_EQ(file, nullptr);
}

TEST(TrustBoundary, ATextureLargerThanTheHeaderSaysIsCorruptBeforeItIsDecoded) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());  // 8² lossless WebP
  const std::vector<uint8_t> big = encode_texture(TextureCodec::kWebp, Image(64, 64, 3), 101);
  const auto swap_image = [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "TEXR") return;
    payload.resize(8);  // keyframe number, image codec 1 (WebP)
    payload.insert(payload.end(), big.begin(), big.end());
  };
  testing::expect_error(ErrorCode::kCorrupt, "64 x 64 pixels is too large",
                        [&] { decode_sequence_file(rebuild(bytes, swap_image), "t.fmv"); });
}

TEST(TrustBoundary, TheDecoderNeverReturnsNonFiniteNumbers) {
  // A sequence built in memory (no file bounds): a translation past float range decodes to
  // positions no float buffer holds. The decoder says so instead of writing infinities.
  auto sequence = std::make_shared<Sequence>(small_sequence(9, 8));
  for (Keyframe& key : sequence->keyframes) key.pose.translation = Vec3(1e300, 0, 0);
  Decoder decoder(sequence);
  std::vector<float> positions(3 * static_cast<size_t>(decoder.info().max_vertex_count));
  FrameBuffers out;
  out.positions = positions;
  testing::expect_error(ErrorCode::kCorrupt, "beyond float range", [&] { decoder.decode(0.25, out); });
}

// Fields that no surface has: the keyframe's reconstruction does not converge (or overflows).
std::shared_ptr<Sequence> unreconstructible() {
  auto sequence = std::make_shared<Sequence>(small_sequence(17, 8));
  GridFields& f = sequence->keyframes[1].fields;
  for (double& h : f.mean_curvature) h = 40;
  for (double& l : f.log_conformal_factor) l = 3;
  return sequence;
}

TEST(TrustBoundary, AKeyframeThatFailsIsRememberedAndFailsAtOnce) {
  Decoder decoder(unreconstructible());
  std::vector<float> positions(3 * static_cast<size_t>(decoder.info().max_vertex_count));
  FrameBuffers out;
  out.positions = positions;
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1 cannot be reconstructed", [&] { decoder.decode(0.5, out); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1 cannot be reconstructed", [&] { decoder.decode(0.6, out); });
  // Keyframe 0 alone (t = 0 weighs only it, with Catmull-Rom) still decodes.
  EXPECT_NO_THROW(decoder.decode(0.0, out));
  // The failure is kept (not timed: the iteration that fails may itself take a millisecond): the
  // second call throws it without reconstructing again.
  SequenceDecoder sequence_decoder(unreconstructible());
  EXPECT_THROW(sequence_decoder.decode(0.6), Error);  // keyframes 0 (made and kept) and 1 (fails)
  const std::string kept = sequence_decoder.keyframe_failure(1);
  EXPECT_NE(kept.find("keyframe 1 cannot be reconstructed"), std::string::npos) << kept;
  EXPECT_EQ(sequence_decoder.keyframe_failure(0), "");
  const size_t tried = sequence_decoder.keyframe_reconstructions();
  // The same failure, at the new t: "sequence: t = 0.7 s: keyframe 1 cannot be reconstructed ...".
  testing::expect_error(ErrorCode::kCorrupt, "sequence: t = 0.7 s: " + kept.substr(kept.find("keyframe 1")),
                        [&] { sequence_decoder.decode(0.7); });
  EXPECT_EQ(sequence_decoder.keyframe_reconstructions(), tried);
}

TEST(TrustBoundary, AnIterationThatStopsFallingIsAbandoned) {
  const std::shared_ptr<Sequence> s = unreconstructible();
  Reconstructor reconstructor(s->grid_n);
  ReconstructOptions options;
  options.throw_on_failure = false;
  options.max_iterations = 200;
  try {
    const ReconstructResult r = reconstructor.reconstruct(s->keyframes[1].fields, options);
    EXPECT_FALSE(r.converged);
    EXPECT_LT(r.iterations, 200) << "ran to the cap";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kNumerical) << e.what();  // an overflow stops it too
  }
}

// ---- The C API's handles: every misuse a named error, never freed memory ----

TEST(TrustBoundary, HandlesAfterCloseAreNamedErrors) {
  fm_file* a = nullptr;
  ASSERT_EQ(fm_file_open(kGoldenV2_0.c_str(), &a), FM_OK) << fm_last_error_message();
  fm_decoder* decoder = nullptr;
  ASSERT_EQ(fm_decoder_create(a, &decoder), FM_OK);
  ASSERT_EQ(fm_decoder_release(decoder), FM_OK);
  fm_frame frame;
  fm_frame_init(&frame);
  // Decode after destroy, double destroy.
  EXPECT_EQ(fm_decoder_decode(decoder, 0.1, 0, &frame), FM_ERROR_CLOSED_HANDLE);
  EXPECT_NE(std::string(fm_last_error_message()).find("already closed"), std::string::npos) << fm_last_error_message();
  EXPECT_EQ(fm_decoder_release(decoder), FM_ERROR_CLOSED_HANDLE);
  fm_decoder_destroy(decoder);  // ignored, and says so
  EXPECT_NE(std::string(fm_last_error_message()).find("already closed"), std::string::npos);
  // get_info after close; a second close of a does not close b, which may reuse a's entry.
  ASSERT_EQ(fm_file_release(a), FM_OK);
  fm_info info;
  fm_info_init(&info);
  EXPECT_EQ(fm_file_get_info(a, &info), FM_ERROR_CLOSED_HANDLE);
  EXPECT_EQ(fm_decoder_create(a, &decoder), FM_ERROR_CLOSED_HANDLE);
  EXPECT_EQ(decoder, nullptr);
  fm_file* b = nullptr;
  ASSERT_EQ(fm_file_open(kGoldenV2_0.c_str(), &b), FM_OK);
  EXPECT_EQ(fm_file_release(a), FM_ERROR_CLOSED_HANDLE);
  fm_file_close(a);
  EXPECT_EQ(fm_file_get_info(b, &info), FM_OK) << fm_last_error_message();
  EXPECT_EQ(info.grid_n, 33u);
  size_t count = 0;
  EXPECT_EQ(fm_file_get_keyframe_times(a, nullptr, 0, &count), FM_ERROR_CLOSED_HANDLE);
  // A handle of one kind is not taken for the other, nor a made-up value for either.
  EXPECT_EQ(fm_decoder_decode(reinterpret_cast<fm_decoder*>(b), 0.1, 0, &frame), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_file_get_info(reinterpret_cast<fm_file*>(uintptr_t{0x12345678}), &info), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_file_release(b), FM_OK);
  EXPECT_STREQ(fm_status_name(FM_ERROR_CLOSED_HANDLE), "closed-handle");
  EXPECT_STREQ(fm_status_name(FM_ERROR_LIMIT), "limit");
}

TEST(TrustBoundary, OptionsSetTheLimitsThroughTheCApi) {
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  EXPECT_EQ(options.struct_size, sizeof options);
  EXPECT_EQ(options.max_grid_n, 1025u);
  EXPECT_EQ(options.max_keyframes, 65536u);
  EXPECT_EQ(options.max_texture_size, 4096u);
  EXPECT_EQ(options.max_memory_bytes, uint64_t{256} << 20);  // 512 MiB before API 1.2
  fm_file* file = nullptr;
  options.max_grid_n = 17;  // the golden file's grid is 33
  EXPECT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_ERROR_LIMIT);
  EXPECT_NE(std::string(fm_last_error_message()).find("grid size 33 over the limit of 17"), std::string::npos) << fm_last_error_message();
  EXPECT_EQ(file, nullptr);
  options.max_grid_n = 33;
  options.max_memory_bytes = 16 << 10;
  EXPECT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_ERROR_LIMIT);
  fm_decoder_options_init(&options);
  ASSERT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_OK);
  fm_file_close(file);
  // Unusable limits are the caller's error.
  options.max_keyframes = 0;
  EXPECT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_ERROR_INVALID_ARGUMENT);
  fm_decoder_options_init(&options);
  options.struct_size = 0;
  EXPECT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_ERROR_INVALID_ARGUMENT);
  // A caller compiled against a shorter struct (only the grid limit) keeps the other defaults.
  fm_decoder_options_init(&options);
  options.struct_size = offsetof(fm_decoder_options, max_keyframes);
  options.max_keyframes = 0;  // not read
  EXPECT_EQ(fm_file_open_with_options(kGoldenV2_0.c_str(), &options, &file), FM_OK) << fm_last_error_message();
  fm_file_close(file);
}

TEST(TrustBoundary, MemoryAfterAHundredCraftedFilesIsThatAfterTheFirst) {
  // Each names another grid N, with that grid's hash and rim count, and keyframes of another grid:
  // each gets as far as decoding its keyframe group (which needs G's lattice for its N) and is
  // refused there. What the reader built for them is not kept (the grid cache held every N a
  // process had seen: about 2 MB for each of these, 200 MB in all). The allowance is the
  // allocator's, well below one file's share.
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), predicted_metadata());
  std::vector<std::vector<uint8_t>> files;
  for (uint32_t i = 0; i < 100; ++i) {
    files.push_back(rebuild(bytes, [i](const std::string& type, std::vector<uint8_t>& payload) {
      if (type != "HEAD") return;
      const uint32_t n = 259 - 2 * i;  // the first the largest
      const uint32_t rim = static_cast<uint32_t>(disk_grid_shape(static_cast<int>(n)).rim_count);
      const uint64_t hash = known_disk_grid_hash(static_cast<int>(n));
      std::memcpy(payload.data(), &n, 4);
      std::memcpy(payload.data() + 8, &hash, 8);
      std::memcpy(payload.data() + 76, &rim, 4);
    }));
  }
  uint64_t after_first = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    // The index holds the poses: each opens, and its first keyframe is refused when asked for.
    const std::shared_ptr<const KeyframeSource> source = open_sequence_source(files[i], "crafted.fmv");
    testing::expect_error(ErrorCode::kCorrupt, "chunk KGOP", [&] { source->keyframe(0); });
    if (i == 0) after_first = status_bytes("VmRSS");
  }
  const uint64_t after_all = status_bytes("VmRSS");
  if (testing::kAddressSanitizer)
    GTEST_SKIP() << "resident memory under AddressSanitizer's quarantine: " << after_first << " -> " << after_all;
  if (after_first > 0) {
    EXPECT_LT(after_all, after_first + (uint64_t{8} << 20)) << after_first << " -> " << after_all;
  }
}

// ---- Tests that notice: each fails on a mutation the older tests let through ----

// The index's rotation vector is bounded by 4 (> π): a step that makes a stored rotation longer is
// corrupt. (Mutation: deleting the index's check.)
TEST(TrustBoundary, AGroupRotationBeyondFourIsCorrupt) {
  Sequence turned = small_sequence(9, 8);
  turned.keyframes[1].pose.rotation = Eigen::AngleAxisd(3.0, Vec3(0, 1, 0)).toRotationMatrix();
  const SequenceFileMetadata m = predicted_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(turned, m);
  EXPECT_NO_THROW(decode_sequence_file(bytes, "g.fmv"));
  // The header ends with the rotation step, then the translation step (f64 each): doubling the
  // rotation step doubles every rotation vector, 3 rad becoming 6.
  const auto doubled = [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") {
      const double step = 2 * m.field_coding.rotation_step;
      std::memcpy(payload.data() + payload.size() - 16, &step, 8);
    }
  };
  testing::expect_error(ErrorCode::kCorrupt, "rotation vector component beyond 4",
                        [&] { decode_sequence_file(rebuild(bytes, doubled), "r.fmv"); });
}

// Convergence is max |ΔS| over the nodes (spec/method.md §5.4), not an RMS. (Mutation: RMS.)
TEST(TrustBoundary, ConvergenceMeasuresTheLargestMoveOfANode) {
  const Sequence s = small_sequence(17, 8);
  const GridFields& fields = s.keyframes[2].fields;
  Reconstructor reconstructor(17);
  const DiskGrid& grid = reconstructor.geometry().grid();
  std::vector<Vec3> start;
  for (const Vec2& w : grid.nodes) start.push_back(Vec3(w.x(), w.y(), 0));
  ReconstructOptions options;
  options.anderson_depth = 0;  // the plain iteration: each result is the step's S⁺
  options.tolerance = 1e-300;
  options.throw_on_failure = false;
  options.start = &start;
  options.max_iterations = 2;
  const ReconstructResult two = reconstructor.reconstruct(fields, options);
  options.max_iterations = 3;
  const ReconstructResult three = reconstructor.reconstruct(fields, options);
  ASSERT_EQ(three.iterations, 3);
  Vec3 lo = fields.rim[0], hi = lo;
  for (const Vec3& p : fields.rim) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  double largest = 0, sum2 = 0;
  for (int v = 0; v < grid.interior_count; ++v) {
    const double d = (three.positions[static_cast<size_t>(v)] - two.positions[static_cast<size_t>(v)]).norm();
    largest = std::max(largest, d);
    sum2 += d * d;
  }
  const double rms = std::sqrt(sum2 / grid.interior_count);
  ASSERT_GT(largest, 1.2 * rms);  // the two measures differ here
  EXPECT_NEAR(three.change, largest / (hi - lo).norm(), 1e-9 * three.change);
}

// Fixed nodes strictly increase: a node listed twice is refused. (Mutation: `<=` → `<`.)
TEST(TrustBoundary, AFixedNodeListedTwiceIsRefused) {
  GridFields f = small_sequence(17, 8).keyframes[0].fields;
  ASSERT_GE(f.fixed_nodes.size(), 2u);
  EXPECT_NO_THROW(validate_fields(f));
  f.fixed_nodes[1] = f.fixed_nodes[0];
  testing::expect_error(ErrorCode::kInvalidArgument, "strictly increasing", [&] { validate_fields(f); });
}

// An indices buffer one triangle short, every other buffer right: refused, nothing written.
// (Mutation: the decoder accepting it — a heap overflow.)
TEST(TrustBoundary, AnIndicesBufferOneTriangleShortIsRefused) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  const FileInfo& info = decoder.info();
  const size_t needed = 3 * static_cast<size_t>(info.max_triangle_count);
  std::vector<uint32_t> indices(needed, 0xdeadbeef);
  std::vector<float> positions(3 * static_cast<size_t>(info.max_vertex_count));
  FrameBuffers out;
  out.positions = positions;
  out.indices = std::span<uint32_t>(indices).first(needed - 3);
  testing::expect_error(ErrorCode::kBufferTooSmall, "indices needs " + std::to_string(needed), [&] { decoder.decode(0.2, out); });
  EXPECT_TRUE(std::all_of(indices.begin(), indices.end(), [](uint32_t x) { return x == 0xdeadbeef; }));
  fm_file* file = nullptr;
  fm_decoder* d = nullptr;
  ASSERT_EQ(fm_file_open(kGoldenV2_0.c_str(), &file), FM_OK);
  ASSERT_EQ(fm_decoder_create(file, &d), FM_OK);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.indices = indices.data();
  frame.indices_bytes = sizeof(uint32_t) * (needed - 3);
  EXPECT_EQ(fm_decoder_decode(d, 0.2, 0, &frame), FM_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(frame.triangle_count, info.max_triangle_count);
  EXPECT_TRUE(std::all_of(indices.begin(), indices.end(), [](uint32_t x) { return x == 0xdeadbeef; }));
  fm_decoder_destroy(d);
  fm_file_close(file);
}

// A pose is a proper rotation: an orthonormal matrix with det −1 (a mirror) is refused.
// (Mutation: removing the det(R) < 0 check.) A file cannot state one: its rotations are exp of a
// rotation vector.
TEST(TrustBoundary, AReflectionIsNoPose) {
  Sequence s = small_sequence(9, 8);
  s.keyframes[1].pose.rotation = Eigen::Vector3d(1, 1, -1).asDiagonal();
  testing::expect_error(ErrorCode::kInvalidArgument, "proper rotation", [&] { validate_sequence(s); });
}

}  // namespace
}  // namespace facemorph
