// The .fmv container (spec/container.md): round trips, the checksum's definition, and every way a
// damaged or foreign file must be refused by name rather than crash or decode wrong.
#include "format/container.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/checksum.hpp"
#include "format/file_io.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>
#include <cstring>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>

#include <sys/resource.h>
#include <csignal>

namespace facemorph {
namespace {

using crafted::grouped_texture_metadata;
using crafted::predicted_metadata;
using crafted::rebuild;
using crafted::small_metadata;
using crafted::small_sequence;

// What a writer can be given: no steps (it takes 16-bit precision itself), or steps; lossless
// textures (TEXR) or lossy ones as one image sequence per group (TGOP, format 2.1).
std::vector<SequenceFileMetadata> codings() { return {small_metadata(), predicted_metadata(), grouped_texture_metadata()}; }

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

double range(const std::vector<double>& v) {
  if (v.empty()) return 0;
  return *std::max_element(v.begin(), v.end()) - *std::min_element(v.begin(), v.end());
}

TEST(Checksum, IsTheCrc32OfPngAndZip) {
  const std::string check = "123456789";
  EXPECT_EQ(format::crc32({reinterpret_cast<const uint8_t*>(check.data()), check.size()}), 0xCBF43926u);
  EXPECT_EQ(format::crc32({}), 0u);
  // Continuing a CRC is the CRC of the concatenation.
  const std::vector<uint8_t> bytes(check.begin(), check.end());
  EXPECT_EQ(format::crc32(std::span(bytes).subspan(4), format::crc32(std::span(bytes).first(4))), 0xCBF43926u);
}

// The writer's chunks wait in a spool until the index is laid out: the same chunks back whether
// kept in memory or in the temporary file, only their sizes where only sizes are kept, and a
// container streamed to a file is the one built in memory.
TEST(ChunkSpool, KeepsChunksInMemorySpilledOrAsSizesOnly) {
  std::vector<format::PreparedChunk> chunks;
  for (size_t n : {0, 1, 1000, 70000}) {
    std::vector<uint8_t> payload(n);
    for (size_t i = 0; i < n; ++i) payload[i] = static_cast<uint8_t>((i * 7919) % 251);
    chunks.push_back(format::prepare_chunk(n % 2 ? "ODDS" : "EVEN", payload, n > 500, n > 500 ? 3 : 0));
  }
  uint64_t payload_bytes = 0;
  for (const format::PreparedChunk& c : chunks) payload_bytes += c.stored.size();
  for (const auto keep : {format::ChunkSpool::Keep::kMemory, format::ChunkSpool::Keep::kSpill, format::ChunkSpool::Keep::kSizes}) {
    SCOPED_TRACE(static_cast<int>(keep));
    format::ChunkSpool spool(keep);
    for (size_t i = 0; i < chunks.size(); ++i) EXPECT_EQ(spool.add(chunks[i]), i);
    EXPECT_EQ(spool.bytes_held(), keep == format::ChunkSpool::Keep::kMemory ? payload_bytes : 0);
    std::ostringstream streamed;
    format::ContainerWriter in_memory, to_stream(streamed);
    for (size_t i = 0; i < chunks.size(); ++i) {
      EXPECT_EQ(spool.total_size(i), chunks[i].total_size());
      if (keep == format::ChunkSpool::Keep::kSizes) {
        EXPECT_THROW(spool.get(i), Error);
        continue;
      }
      const format::PreparedChunk back = spool.get(i);
      EXPECT_EQ(back.type, chunks[i].type);
      EXPECT_EQ(back.flags, chunks[i].flags);
      EXPECT_EQ(back.raw_size, chunks[i].raw_size);
      EXPECT_TRUE(back.stored == chunks[i].stored);
      EXPECT_EQ(in_memory.add(back), to_stream.add(back));
    }
    EXPECT_EQ(in_memory.size(), to_stream.size());
    const std::vector<uint8_t> bytes = in_memory.finish();
    EXPECT_TRUE(to_stream.finish().empty());
    EXPECT_EQ(bytes.size(), in_memory.size());
    const std::string text = streamed.str();
    EXPECT_TRUE(std::vector<uint8_t>(text.begin(), text.end()) == bytes);
  }
}

TEST(Container, RoundTripKeepsEveryQuantityWithinItsQuantisation) {
  const Sequence s = small_sequence();
  SequenceFileInfo info;
  const std::vector<uint8_t> bytes = encode_sequence_file(s, small_metadata());
  const Sequence back = decode_sequence_file(bytes, "small.fmv", &info);
  EXPECT_EQ(back.grid_n, s.grid_n);
  EXPECT_EQ(back.representation, s.representation);
  EXPECT_EQ(back.spline, s.spline);
  EXPECT_EQ(back.fps, s.fps);
  EXPECT_EQ(back.units, "mm");
  EXPECT_EQ(back.pose_centre, s.pose_centre);
  ASSERT_EQ(back.keyframes.size(), s.keyframes.size());
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    const Keyframe& a = s.keyframes[k];
    const Keyframe& b = back.keyframes[k];
    EXPECT_EQ(a.time, b.time);
    // The pose in multiples of the default steps (10⁻⁵ rad, 10 µm = 0.01 mm): half a step in a
    // rotation vector component moves R by at most √3/2 steps, a translation half a step.
    EXPECT_LT((a.pose.rotation - b.pose.rotation).cwiseAbs().maxCoeff(), 0.87e-5);
    EXPECT_LE((a.pose.translation - b.pose.translation).cwiseAbs().maxCoeff(), 0.5e-2 * (1 + 1e-9));
    EXPECT_EQ(a.fields.fixed_nodes, b.fields.fixed_nodes);
    const auto arrays_a = scalar_arrays(a.fields), arrays_b = scalar_arrays(b.fields);
    for (size_t i = 0; i < arrays_a.size(); ++i) {
      // 16-bit precision over the array's range in the whole sequence: half a step at most.
      std::vector<double> all;
      for (const Keyframe& key : s.keyframes) {
        const auto arrays = scalar_arrays(key.fields);
        all.insert(all.end(), arrays[i].begin(), arrays[i].end());
      }
      all.push_back(0);
      EXPECT_LE(max_difference(arrays_a[i], arrays_b[i]), 0.5 * range(all) / 65535 * (1 + 1e-9)) << "array " << i;
    }
    std::vector<double> levels{0};
    for (const Keyframe& key : s.keyframes) levels.insert(levels.end(), key.hole_level.begin(), key.hole_level.end());
    EXPECT_LE(max_difference(a.hole_level, b.hole_level), 0.5 * range(levels) / 65535 * (1 + 1e-9));
    EXPECT_EQ(a.texture.pixels, b.texture.pixels);  // lossless WebP
  }
  EXPECT_EQ(info.major_version, format::kMajorVersion);
  EXPECT_EQ(info.file_bytes, bytes.size());
  EXPECT_EQ(info.metadata.landmark_names, small_metadata().landmark_names);
  EXPECT_EQ(info.metadata.settings, small_metadata().settings);
  EXPECT_EQ(info.metadata.encoder.rfind("facemorph ", 0), 0u);
  EXPECT_EQ(info.texture_size, 16);
  EXPECT_EQ(info.metadata.texture_codec, TextureCodec::kWebp);  // lossless: WebP, whatever the codec asked
  uint64_t total = format::kPreambleBytes + format::kChunkHeaderBytes + 4 + format::kChunkTrailerBytes;  // + the end chunk
  for (const auto& c : info.chunks) total += c.stored_bytes;
  EXPECT_EQ(total, bytes.size());
  // Writing is deterministic: the same sequence gives the same bytes.
  EXPECT_EQ(encode_sequence_file(s, small_metadata()), bytes);
}

TEST(Container, GeometryOnlyAndHoleFreeSequencesRoundTrip) {
  Sequence s = small_sequence();
  for (Keyframe& key : s.keyframes) {
    key.texture = {};
    key.hole_level.clear();
  }
  const Sequence back = decode_sequence_file(encode_sequence_file(s, {}), "plain.fmv");
  EXPECT_FALSE(back.has_texture());
  EXPECT_FALSE(back.has_holes());
  EXPECT_EQ(back.keyframes.size(), 3u);
}

// Every prefix of a file is refused as truncated (or, where the cut lands in the magic, as not a
// container), never read past its end.
TEST(Container, EveryTruncationIsNamed) {
  for (const SequenceFileMetadata& metadata : codings()) {
    const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), metadata);
    for (size_t size = 0; size < bytes.size(); ++size) {
      const std::span<const uint8_t> prefix(bytes.data(), size);
      try {
        decode_sequence_file(prefix, "cut.fmv");
        ADD_FAILURE() << "a file cut at " << size << " bytes was read";
      } catch (const Error& e) {
        EXPECT_TRUE(e.code() == ErrorCode::kTruncated) << size << ": " << e.what();
        EXPECT_NE(std::string(e.what()).find("cut.fmv"), std::string::npos);
      }
    }
  }
}

// Flipping any byte is caught: by a checksum within a chunk, or as an impossible value in the
// preamble and the chunk headers. Never a crash, never a file read as good.
TEST(Container, EveryByteFlipIsNamed) {
  for (const SequenceFileMetadata& metadata : codings()) {
    const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), metadata);
    const format::ContainerReader reader(bytes, "good.fmv");
    for (size_t at = 0; at < bytes.size(); ++at) {
      std::vector<uint8_t> damaged = bytes;
      damaged[at] ^= 0x5A;
      try {
        decode_sequence_file(damaged, "flipped.fmv");
        ADD_FAILURE() << "a flip at byte " << at << " went unnoticed";
      } catch (const Error& e) {
        EXPECT_TRUE(e.code() == ErrorCode::kCorrupt || e.code() == ErrorCode::kTruncated || e.code() == ErrorCode::kUnsupported)
            << at << ": " << error_code_name(e.code()) << " " << e.what();
      }
    }
    // A flip inside a payload is a checksum mismatch naming the chunk.
    for (const format::ChunkView& chunk : reader.chunks()) {
      std::vector<uint8_t> damaged = bytes;
      damaged[chunk.offset + format::kChunkHeaderBytes + chunk.stored.size() / 2] ^= 1;
      testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk " + chunk.type,
                            [&] { decode_sequence_file(damaged, "f.fmv"); });
    }
  }
}

// Values stored as exact multiples of their steps, so what the encoder rounded is what every decoder
// reads, to the bit; keyframes predicted from the previous one only within a group.
TEST(Container, PredictedCodingStoresExactMultiplesOfItsSteps) {
  const SequenceFileMetadata m = predicted_metadata();
  const Sequence s = small_sequence();
  Sequence rounded = s;
  for (Keyframe& key : rounded.keyframes) round_to_field_steps(key, m.field_coding);
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  EXPECT_EQ(encode_sequence_file(rounded, m), bytes);  // rounding twice changes nothing
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "p.fmv", &info);
  EXPECT_EQ(info.minor_version, format::kMinorVersion);
  EXPECT_EQ(info.metadata.field_coding.steps, m.field_coding.steps);
  EXPECT_EQ(info.metadata.field_coding.intra_period, 2);
  EXPECT_EQ(info.metadata.field_coding.rotation_step, m.field_coding.rotation_step);
  EXPECT_EQ(info.metadata.field_coding.translation_step, m.field_coding.translation_step);
  ASSERT_EQ(back.keyframes.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    const auto original = scalar_arrays(s.keyframes[k].fields), stored = scalar_arrays(rounded.keyframes[k].fields),
               read = scalar_arrays(back.keyframes[k].fields);
    for (size_t a = 0; a < kScalarArrayCount; ++a) {
      EXPECT_EQ(read[a], stored[a]) << "keyframe " << k << " array " << a;
      EXPECT_LE(max_difference(original[a], stored[a]), 0.5 * m.field_coding.steps[a] * (1 + 1e-9)) << a;
    }
    EXPECT_EQ(back.keyframes[k].hole_level, rounded.keyframes[k].hole_level);
    // The pose as multiples of the pose steps: what round_to_field_steps left, to the bit, and
    // within that rounding of the original (half a step in a rotation vector component moves R by
    // at most √3/2 steps, a translation component half a step).
    EXPECT_EQ(back.keyframes[k].pose.rotation, rounded.keyframes[k].pose.rotation);
    EXPECT_EQ(back.keyframes[k].pose.translation, rounded.keyframes[k].pose.translation);
    EXPECT_LT((back.keyframes[k].pose.rotation - s.keyframes[k].pose.rotation).cwiseAbs().maxCoeff(), 0.87 * m.field_coding.rotation_step);
    EXPECT_LE((back.keyframes[k].pose.translation - s.keyframes[k].pose.translation).cwiseAbs().maxCoeff(),
              0.5 * m.field_coding.translation_step * (1 + 1e-9));
    if (k > 0) {
      EXPECT_GT((back.keyframes[k].pose.translation - s.keyframes[k].pose.translation).norm(), 0) << "the test's poses must need rounding";
    }
    EXPECT_LE(max_difference(s.keyframes[k].hole_level, back.keyframes[k].hole_level), 0.5e-3 * (1 + 1e-9));
  }
  const format::ContainerReader reader(bytes, "p.fmv");
  std::vector<std::string> types;
  for (const format::ChunkView& c : reader.chunks()) types.push_back(c.type);
  // A chunk per group of (intra period) 2: keyframes 0-1 and 2, each followed by its textures.
  EXPECT_EQ(types, (std::vector<std::string>{"HEAD", "KIDX", "KGOP", "TEXR", "TEXR", "KGOP", "TEXR"}));
  // Steps that cannot code a value are the writer's error, not a broken file.
  SequenceFileMetadata tiny = m;
  tiny.field_coding.steps[10] = 1e-300;
  testing::expect_error(ErrorCode::kInvalidArgument, "2^30 steps", [&] { encode_sequence_file(s, tiny); });
  tiny.field_coding.steps.pop_back();
  testing::expect_error(ErrorCode::kInvalidArgument, "one step per keyframe array", [&] { encode_sequence_file(s, tiny); });
}

// A chunk per group of keyframes, its stream shared by them. A group the index does not expect, a
// stream that ends early or late, pose steps that are not positive are corrupt; a writer with pose
// steps that are not positive, or a pose they cannot code, is refused.
TEST(Container, KeyframeGroupsThatBreakTheirRulesAreCorrupt) {
  const SequenceFileMetadata m = predicted_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), m);
  // The group's stream is divided among its keyframes: every byte counted once, each keyframe some.
  SequenceFileInfo info;
  decode_sequence_file(bytes, "g.fmv", &info);
  uint64_t group_bytes = 0, keyframe_bytes = 0;
  for (const auto& chunk : info.chunks) group_bytes += chunk.type == "KGOP" ? chunk.stored_bytes : 0;
  for (const auto& k : info.keyframes) {
    EXPECT_GT(k.fields, 0u);
    keyframe_bytes += k.fields;
  }
  EXPECT_EQ(keyframe_bytes, group_bytes);
  const auto first_group = [](auto change) {
    return [change](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "KGOP" && payload[0] == 0) change(payload);
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "another group of keyframes",
                        [&] { decode_sequence_file(rebuild(bytes, first_group([](std::vector<uint8_t>& p) { p[0] = 1; })), "n.fmv"); });
  for (int delta : {-3, 2}) {
    const auto resize =
        first_group([delta](std::vector<uint8_t>& p) { p.resize(static_cast<size_t>(static_cast<int64_t>(p.size()) + delta), 0); });
    try {
      decode_sequence_file(rebuild(bytes, resize), "s.fmv");
      ADD_FAILURE() << "a stream resized by " << delta << " was read";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kCorrupt) << e.what();
      EXPECT_NE(std::string(e.what()).find("s.fmv: chunk KGOP"), std::string::npos) << e.what();
    }
  }
  // The header ends with the rotation step and the translation step (f64 each).
  const auto translation_step = [](double step) {
    return [step](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "HEAD") std::memcpy(payload.data() + payload.size() - 8, &step, 8);
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "a pose step that is not positive",
                        [&] { decode_sequence_file(rebuild(bytes, translation_step(-1)), "p.fmv"); });
  // A coarser step is a valid file that decodes the same rotations and other translations.
  const Sequence coarser = decode_sequence_file(rebuild(bytes, translation_step(2 * m.field_coding.translation_step)), "c.fmv");
  const Sequence same = decode_sequence_file(bytes, "g.fmv");
  EXPECT_EQ(coarser.keyframes[1].pose.rotation, same.keyframes[1].pose.rotation);
  EXPECT_EQ(coarser.keyframes[1].pose.translation, 2 * same.keyframes[1].pose.translation);
  SequenceFileMetadata no_steps = m;
  no_steps.field_coding.rotation_step = -1;
  testing::expect_error(ErrorCode::kInvalidArgument, "pose steps", [&] { encode_sequence_file(small_sequence(9, 8), no_steps); });
  Sequence far = small_sequence(9, 8);
  far.keyframes[1].pose.translation.x() = 1e20;  // 1e17 km in mm: beyond 2^40 steps of 10 µm
  testing::expect_error(ErrorCode::kInvalidArgument, "2^40 pose steps", [&] { encode_sequence_file(far, m); });
  // A rotation step so coarse that a rotation of 3.1 rad rounds to a vector beyond 4, which no
  // decoder would accept.
  Sequence turned = small_sequence(9, 8);
  turned.keyframes[1].pose.rotation = Eigen::AngleAxisd(3.1, Vec3(0, 1, 0)).toRotationMatrix();
  SequenceFileMetadata coarse = m;
  coarse.field_coding.rotation_step = 4.5;
  testing::expect_error(ErrorCode::kInvalidArgument, "beyond 4", [&] { encode_sequence_file(turned, coarse); });
  testing::expect_error(ErrorCode::kInvalidArgument, "units", [&] {
    FieldCoding c;
    set_default_pose_steps(c, "inch");
  });
}

TEST(Container, UnknownChunksAreSkippedUnlessCritical) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  const auto same = [](const std::string&, std::vector<uint8_t>&) {};
  EXPECT_EQ(rebuild(bytes, same), bytes);  // the rebuild itself changes nothing
  const Sequence with_extra = decode_sequence_file(rebuild(bytes, same, true, false), "extra.fmv");
  EXPECT_EQ(with_extra.keyframes.size(), 3u);
  testing::expect_error(ErrorCode::kUnsupported, "ZZZ1", [&] { decode_sequence_file(rebuild(bytes, same, true, true), "critical.fmv"); });
}

TEST(Container, TheWriterRefusesStringsAReaderWouldRefuse) {
  // A reader takes header strings of at most 1 MiB (spec/container.md §5, §10.1): the writer
  // refuses longer ones rather than write a file no player opens; at the limit, the file reads.
  SequenceFileMetadata metadata = small_metadata();
  metadata.settings = "\"" + std::string((1u << 20) - 2, 'x') + "\"";
  EXPECT_EQ(decode_sequence_file(encode_sequence_file(small_sequence(9, 8), metadata), "settings.fmv").keyframes.size(), 3u);
  metadata.settings += " ";
  testing::expect_error(ErrorCode::kInvalidArgument, "settings of 1048577 bytes",
                        [&] { encode_sequence_file(small_sequence(9, 8), metadata); });
  metadata = small_metadata();
  metadata.landmark_names = {"nose_tip", std::string((1u << 20) + 1, 'n')};
  testing::expect_error(ErrorCode::kInvalidArgument, "a landmark name", [&] { encode_sequence_file(small_sequence(9, 8), metadata); });
}

TEST(Container, FieldsAppendedByALaterMinorVersionAreIgnored) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  const auto append = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") payload.insert(payload.end(), {9, 9, 9, 9});
  };
  // Stamped with a later minor version, which may append (spec/container.md §12.1); in a file of
  // this decoder's own version the same bytes are corrupt (DecodeLimits.AByteAfterTheHeaderOr...).
  std::vector<uint8_t> newer = rebuild(bytes, append);
  newer[10] = static_cast<uint8_t>(format::kMinorVersion + 1);
  const uint32_t crc = format::crc32(std::span(newer).first(12));
  for (int i = 0; i < 4; ++i) newer[12 + static_cast<size_t>(i)] = static_cast<uint8_t>(crc >> (8 * i));
  EXPECT_EQ(decode_sequence_file(newer, "newer.fmv").keyframes.size(), 3u);
  testing::expect_error(ErrorCode::kCorrupt, "after its last field", [&] { decode_sequence_file(rebuild(bytes, append), "same.fmv"); });
}

TEST(Container, ForeignFilesAndOtherVersionsAreRefused) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  testing::expect_error(ErrorCode::kCorrupt, "not a facemorph container", [&] {
    const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    decode_sequence_file({reinterpret_cast<const uint8_t*>(obj.data()), obj.size()}, "face.obj");
  });
  // Major version 3, with a valid preamble checksum; and 1, the experimental series.
  for (uint8_t major : {uint8_t{3}, uint8_t{1}}) {
    std::vector<uint8_t> other = bytes;
    other[8] = major;
    const uint32_t crc = format::crc32(std::span(other).first(12));
    for (int i = 0; i < 4; ++i) other[12 + static_cast<size_t>(i)] = static_cast<uint8_t>(crc >> (8 * i));
    testing::expect_error(ErrorCode::kUnsupported, "format version " + std::to_string(major) + "." + std::to_string(format::kMinorVersion),
                          [&] { decode_sequence_file(other, "other.fmv"); });
  }
  // A grid built by another rule, or another hash: the file would decode differently here.
  for (size_t at : {size_t{4}, size_t{8}}) {
    const auto other_grid = [at](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "HEAD") payload[at] ^= 1;
    };
    testing::expect_error(ErrorCode::kUnsupported, "not the grid this decoder builds",
                          [&] { decode_sequence_file(rebuild(bytes, other_grid), "g.fmv"); });
  }
  // Bytes after the end chunk.
  std::vector<uint8_t> trailing = bytes;
  trailing.push_back(0);
  testing::expect_error(ErrorCode::kCorrupt, "after the end chunk", [&] { decode_sequence_file(trailing, "t.fmv"); });
}

// Format 1.2: lossy textures in AVIF (the writer's default) or WebP; the reader says which, a
// decoder refuses a codec it does not know and names a damaged image's chunk.
TEST(Container, LossyTexturesRoundTripInEitherCodec) {
  Sequence s = small_sequence(9, 64);
  for (size_t k = 0; k < s.keyframes.size(); ++k) {  // smooth ramps: what lossy codecs are for
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) {
        uint8_t* p = s.keyframes[k].texture.at(x, y);
        p[0] = static_cast<uint8_t>(3 * x + 20 * static_cast<int>(k));
        p[1] = static_cast<uint8_t>(3 * y);
      }
    }
  }
  for (TextureCodec codec : {TextureCodec::kAvif, TextureCodec::kWebp}) {
    SequenceFileMetadata m = small_metadata();
    m.texture_codec = codec;
    m.texture_coding = TextureCoding::kStills;  // format 2.0's TEXR (the sequence coding: TextureGroups* below)
    m.texture_quality = 90;
    const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
    SequenceFileInfo info;
    const Sequence back = decode_sequence_file(bytes, "t.fmv", &info);
    EXPECT_EQ(info.metadata.texture_codec, codec);
    EXPECT_EQ(info.minor_version, format::kMinorVersion);
    for (size_t k = 0; k < s.keyframes.size(); ++k) {
      const Image& a = s.keyframes[k].texture;
      const Image& b = back.keyframes[k].texture;
      ASSERT_EQ(b.width, 64);
      EXPECT_GT(testing::psnr(a, b), 35) << texture_codec_name(codec) << " keyframe " << k;
    }
    EXPECT_EQ(encode_sequence_file(s, m), bytes);  // deterministic in either codec
  }
  SequenceFileMetadata m = small_metadata();
  m.texture_quality = 60;
  m.texture_coding = TextureCoding::kStills;
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  const auto codec_number = [](uint8_t number) {
    return [number](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "TEXR") payload[4] = number;
    };
  };
  testing::expect_error(ErrorCode::kUnsupported, "image codec 3", [&] { decode_sequence_file(rebuild(bytes, codec_number(3)), "c.fmv"); });
  // AVIF bytes announced as WebP, and an AVIF image cut short: corrupt, naming the chunk.
  testing::expect_error(ErrorCode::kCorrupt, "TEXR", [&] { decode_sequence_file(rebuild(bytes, codec_number(1)), "w.fmv"); });
  const auto cut = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "TEXR") payload.resize(payload.size() / 2);
  };
  testing::expect_error(ErrorCode::kCorrupt, "TEXR", [&] { decode_sequence_file(rebuild(bytes, cut), "x.fmv"); });
}

// Smooth ramps over `keyframes` keyframes of size x size, drifting from one keyframe to the next:
// what a face's texture does between keyframes, and what lossy codecs are for.
Sequence ramp_sequence(int keyframes, int size) {
  const Sequence three = small_sequence(9, size);
  Sequence s = three;
  s.keyframes.clear();
  for (int k = 0; k < keyframes; ++k) {
    Keyframe key = three.keyframes[static_cast<size_t>(k % 3)];
    key.time = 0.2 * k;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        uint8_t* p = key.texture.at(x, y);
        p[0] = static_cast<uint8_t>((3 * x + 2 * k) * 64 / size);
        p[1] = static_cast<uint8_t>((3 * y + k) * 64 / size);
        p[2] = static_cast<uint8_t>(96 + ((x + y) * 32 / size));
      }
    }
    s.keyframes.push_back(std::move(key));
  }
  s.last_time = s.keyframes.back().time;
  return s;
}

using testing::psnr;

using testing::chunk_count;

// Format 2.1: lossy AVIF textures as one AV1 image sequence per group of keyframes (TGOP), the
// writer's default; the same bytes every time; each keyframe within its quality.
TEST(Container, TextureGroupsRoundTripWithinTheirQuality) {
  const Sequence s = ramp_sequence(5, 64);  // groups of 2, 2 and 1 keyframes
  const SequenceFileMetadata m = grouped_texture_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "groups.fmv", &info);
  EXPECT_EQ(info.minor_version, format::kMinorVersion);
  EXPECT_EQ(info.metadata.texture_coding, TextureCoding::kSequence);
  EXPECT_EQ(info.metadata.texture_codec, TextureCodec::kAvif);
  EXPECT_EQ(chunk_count(info, "TGOP"), 3);
  EXPECT_EQ(chunk_count(info, "TEXR"), 0);
  uint64_t tgop_bytes = 0, keyframe_bytes = 0;
  for (const auto& c : info.chunks) tgop_bytes += c.type == "TGOP" ? c.stored_bytes : 0;
  for (const auto& k : info.keyframes) keyframe_bytes += k.texture;
  EXPECT_EQ(keyframe_bytes, tgop_bytes);  // the groups' bytes divided among their keyframes, all counted
  EXPECT_GT(info.keyframes[1].texture, 0u);
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    ASSERT_EQ(back.keyframes[k].texture.width, 64);
    EXPECT_GT(psnr(s.keyframes[k].texture, back.keyframes[k].texture), 35) << "keyframe " << k;
  }
  EXPECT_EQ(encode_sequence_file(s, m), bytes);  // deterministic
  // The same textures as stills: TEXR, format 2.0's layout, the same fields.
  SequenceFileMetadata stills = m;
  stills.texture_coding = TextureCoding::kStills;
  SequenceFileInfo still_info;
  const Sequence still_back = decode_sequence_file(encode_sequence_file(s, stills), "stills.fmv", &still_info);
  EXPECT_EQ(still_info.metadata.texture_coding, TextureCoding::kStills);
  EXPECT_EQ(chunk_count(still_info, "TEXR"), 5);
  EXPECT_EQ(chunk_count(still_info, "TGOP"), 0);
  // Lossless or WebP textures stay stills whatever the coding asked for.
  for (const auto& [codec, quality] : {std::pair{TextureCodec::kAvif, 101}, std::pair{TextureCodec::kWebp, 80}}) {
    SequenceFileMetadata other = m;
    other.texture_codec = codec;
    other.texture_quality = quality;
    SequenceFileInfo other_info;
    decode_sequence_file(encode_sequence_file(s, other), "other.fmv", &other_info);
    EXPECT_EQ(chunk_count(other_info, "TGOP"), 0);
    EXPECT_EQ(other_info.metadata.texture_coding, TextureCoding::kStills);
  }
}

// The texture groups a measure of the file coded (sequence_file_size's cache) are what the write
// stores, not coded again; a texture changed since is coded anew (the cache is keyed by its pixels).
TEST(Container, TextureGroupsMeasuredAreWrittenAsCoded) {
  testing::TempDir dir;
  const std::filesystem::path path = dir.path() / "cached.fmv";
  Sequence s = ramp_sequence(5, 64);  // groups of 2, 2 and 1 keyframes
  const SequenceFileMetadata m = grouped_texture_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  TextureGroupCache cache;
  const auto source = memory_source(std::make_shared<const Sequence>(s));
  EXPECT_EQ(sequence_file_size(*source, m, &cache), bytes.size());
  EXPECT_EQ(cache.size(), 3u);
  write_sequence_file(path, *source, m, &cache);
  EXPECT_TRUE(format::read_file(path) == bytes);
  EXPECT_EQ(cache.size(), 3u);  // every group found, none coded again
  // The write takes the payload kept: a marker in group 0's place is what the file holds.
  const TextureGroupCache::Key group0{
      0, m.texture_quality, {image_content_hash(s.keyframes[0].texture), image_content_hash(s.keyframes[1].texture)}};
  ASSERT_TRUE(cache.find(group0).has_value());
  const std::vector<uint8_t> marker = {'c', 'a', 'c', 'h', 'e', 'd', ' ', 'g', 'r', 'o', 'u', 'p', ' ', '0'};
  cache.keep(group0, marker);
  write_sequence_file(path, *source, m, &cache);
  const std::vector<uint8_t> marked = format::read_file(path);
  EXPECT_NE(std::search(marked.begin(), marked.end(), marker.begin(), marker.end()), marked.end());
  // Keyframe 1's texture changed: its group is coded from the new pixels, as without a cache.
  s.keyframes[1].texture.pixels[100] ^= 0x40;
  const auto changed = memory_source(std::make_shared<const Sequence>(s));
  write_sequence_file(path, *changed, m, &cache);
  EXPECT_TRUE(format::read_file(path) == encode_sequence_file(s, m));
  EXPECT_EQ(cache.size(), 4u);
}

// A file written as 2.0 wrote it (stills, the preamble's minor version 0) reads as it did.
TEST(Container, AFileOfFormat2_0StillReads) {
  SequenceFileMetadata m = grouped_texture_metadata();
  m.texture_coding = TextureCoding::kStills;
  const Sequence s = ramp_sequence(3, 16);
  std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  const Sequence now = decode_sequence_file(bytes, "now.fmv");
  bytes = crafted::with_minor_version(bytes, 0);  // its groups coded and its header compressed as 2.0 wrote them
  SequenceFileInfo info;
  const Sequence then = decode_sequence_file(bytes, "then.fmv", &info);
  EXPECT_EQ(info.minor_version, 0);
  for (size_t k = 0; k < s.keyframes.size(); ++k) EXPECT_EQ(then.keyframes[k].texture.pixels, now.keyframes[k].texture.pixels);
  // The same with texture groups is not a 2.0 file: the flag came with 2.1.
  std::vector<uint8_t> grouped = encode_sequence_file(s, grouped_texture_metadata());
  grouped = crafted::with_minor_version(grouped, 0);
  testing::expect_error(ErrorCode::kCorrupt, "texture groups (flag bit 2) in a format 2.0 file",
                        [&] { decode_sequence_file(grouped, "g.fmv"); });
}

// Format 2.2: keyframes whose textures are the same pixels store one TEXR, which each of them
// names; the decoder holds it once, and each keyframe decodes to it.
TEST(Container, KeyframesOfOneTextureStoreItOnce) {
  Sequence s = ramp_sequence(5, 32);
  for (size_t k : {2u, 3u}) s.keyframes[k].texture = s.keyframes[0].texture;  // 0, 2, 3 alike; 1, 4 their own
  SequenceFileMetadata m = grouped_texture_metadata();
  m.texture_coding = TextureCoding::kStills;
  m.keyframe_texture_qualities = {70, 80, 90, 60, 80};  // keyframe 0's texture stored at the finest that shows it, 90
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "shared.fmv", &info);
  EXPECT_EQ(info.minor_version, format::kMinorVersion);  // written as 2.2 added it, stamped with the writer's version
  EXPECT_EQ(chunk_count(info, "TEXR"), 3);
  EXPECT_EQ(info.distinct_textures, 3u);
  EXPECT_GT(info.keyframes[0].texture, 0u);
  EXPECT_EQ(info.keyframes[2].texture, 0u);  // its bytes are keyframe 0's
  EXPECT_EQ(info.keyframes[3].texture, 0u);
  EXPECT_GT(info.keyframes[4].texture, 0u);
  for (size_t k : {2u, 3u}) EXPECT_EQ(back.keyframes[k].texture.pixels, back.keyframes[0].texture.pixels) << k;
  EXPECT_NE(back.keyframes[1].texture.pixels, back.keyframes[0].texture.pixels);
  // At quality 90, finer than keyframe 0's own 70 asked for: closer to the source than at 70.
  SequenceFileMetadata own = m;
  own.keyframe_texture_qualities = {70, 80, 70, 70, 80};
  const Sequence coarse = decode_sequence_file(encode_sequence_file(s, own), "own.fmv");
  EXPECT_GT(psnr(s.keyframes[0].texture, back.keyframes[0].texture), psnr(s.keyframes[0].texture, coarse.keyframes[0].texture));
  // Played on demand: keyframes 0, 2 and 3 hand out the one image, decoded once.
  const auto source = open_sequence_source(bytes, "shared.fmv");
  EXPECT_EQ(source->texture(2).get(), source->texture(0).get());
  EXPECT_EQ(source->texture(3).get(), source->texture(0).get());
  EXPECT_NE(source->texture(1).get(), source->texture(0).get());
  EXPECT_EQ(source->texture(4)->pixels, back.keyframes[4].texture.pixels);
  // Where groups are allowed too, the writer takes whichever holds the textures in fewer bytes.
  const auto texture_bytes = [](const SequenceFileInfo& i) {
    uint64_t b = 0;
    for (const auto& c : i.chunks) b += c.type == "TEXR" || c.type == "TGOP" ? c.stored_bytes : 0;
    return b;
  };
  SequenceFileMetadata either = m;
  either.texture_coding = TextureCoding::kSequence;
  SequenceFileInfo either_info;
  const Sequence either_back = decode_sequence_file(encode_sequence_file(s, either), "either.fmv", &either_info);
  EXPECT_LE(texture_bytes(either_info), texture_bytes(info));
  // Textures all different: one TEXR a keyframe, as 2.0 wrote them.
  SequenceFileInfo distinct;
  decode_sequence_file(encode_sequence_file(ramp_sequence(5, 32), m), "own.fmv", &distinct);
  EXPECT_EQ(chunk_count(distinct, "TEXR"), 5);
  EXPECT_EQ(distinct.distinct_textures, 5u);
}

// A shared texture is format 2.2's: a file stamped 2.1 with the flag is corrupt; so are both
// texture flags at once.
TEST(Container, SharedTexturesInAFileBefore2_2AreCorrupt) {
  Sequence s = ramp_sequence(3, 16);
  s.keyframes[2].texture = s.keyframes[0].texture;
  SequenceFileMetadata m = grouped_texture_metadata();
  m.texture_coding = TextureCoding::kStills;
  std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  ASSERT_NO_THROW(decode_sequence_file(bytes, "good.fmv"));
  bytes = crafted::with_minor_version(bytes, 1);
  testing::expect_error(ErrorCode::kCorrupt, "shared textures (flag bit 3) in a format 2.1 file",
                        [&] { decode_sequence_file(bytes, "old.fmv"); });
  const std::vector<uint8_t> both = rebuild(encode_sequence_file(s, m), [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") payload[18] |= 4;  // the flags byte (after N, rule, hash, representation, spline): groups too
  });
  testing::expect_error(ErrorCode::kCorrupt, "both the texture groups flag (bit 2) and the shared textures flag (bit 3)",
                        [&] { decode_sequence_file(both, "both.fmv"); });
}

// TGOP chunks that pass their checksums but break §8.1, and texture entries at the wrong kind of
// chunk: corrupt (or unsupported), naming the chunk, before any pixel of a wrong sequence.
TEST(Container, CraftedTextureGroupsAreRefusedByName) {
  const Sequence s = ramp_sequence(3, 16);  // groups: keyframes 0-1 and 2
  const std::vector<uint8_t> bytes = encode_sequence_file(s, grouped_texture_metadata());
  ASSERT_NO_THROW(decode_sequence_file(bytes, "good.fmv"));
  // Group 0's AVIF replaced by `avif` (its preamble, keyframe 0 and codec 3, kept).
  const auto group0 = [](std::vector<uint8_t> avif) {
    return [avif](const std::string& type, std::vector<uint8_t>& payload) {
      if (type != "TGOP" || payload[0] != 0) return;
      payload.resize(8);
      payload.insert(payload.end(), avif.begin(), avif.end());
    };
  };
  const Image* one[] = {&s.keyframes[0].texture};
  const Image* three[] = {&s.keyframes[0].texture, &s.keyframes[1].texture, &s.keyframes[2].texture};
  testing::expect_error(ErrorCode::kCorrupt, "TGOP",
                        [&] { decode_sequence_file(rebuild(bytes, group0(encode_avif_sequence(one, 80))), "one.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "an AVIF sequence of 1 images",
                        [&] { decode_sequence_file(rebuild(bytes, group0(encode_avif_sequence(one, 80))), "one.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "TGOP",
                        [&] { decode_sequence_file(rebuild(bytes, group0(encode_avif_sequence(three, 80))), "three.fmv"); });
  Image small(8, 8, 3);
  const Image* two_small[] = {&small, &small};
  testing::expect_error(ErrorCode::kCorrupt, "images of 8 x 8",
                        [&] { decode_sequence_file(rebuild(bytes, group0(encode_avif_sequence(two_small, 80))), "size.fmv"); });
  // A still where a sequence of two belongs: one image.
  testing::expect_error(ErrorCode::kCorrupt, "an AVIF sequence of 1 images",
                        [&] { decode_sequence_file(rebuild(bytes, group0(encode_avif(s.keyframes[0].texture, 80))), "still.fmv"); });
  // Another first keyframe than the index's place; another codec; a sequence cut short.
  const auto patch = [](size_t at, uint8_t value) {
    return [at, value](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "TGOP" && payload[0] == 0) payload[at] = value;
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "starts at keyframe 1, the index places it at keyframe 0",
                        [&] { decode_sequence_file(rebuild(bytes, patch(0, 1)), "first.fmv"); });
  testing::expect_error(ErrorCode::kUnsupported, "image codec 2", [&] { decode_sequence_file(rebuild(bytes, patch(4, 2)), "codec.fmv"); });
  const auto cut = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "TGOP" && payload[0] == 0) payload.resize(payload.size() - 20);
  };
  testing::expect_error(ErrorCode::kCorrupt, "TGOP", [&] { decode_sequence_file(rebuild(bytes, cut), "cut.fmv"); });
  // A TGOP where the index expects a TEXR, and a TEXR where it expects a TGOP.
  SequenceFileMetadata stills = grouped_texture_metadata();
  stills.texture_coding = TextureCoding::kStills;
  const std::vector<uint8_t> still_bytes = encode_sequence_file(s, stills);
  const auto rename = [](const std::string& from, const std::string& to) {
    return [from, to](std::string& type, std::vector<uint8_t>& payload) {
      if (type == from && payload[0] == 0) type = to;
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 0's texture entry points at a TGOP chunk, not TEXR",
                        [&] { decode_sequence_file(rebuild(still_bytes, rename("TEXR", "TGOP")), "t.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 0's texture group entry points at a TEXR chunk, not TGOP",
                        [&] { decode_sequence_file(rebuild(bytes, rename("TGOP", "TEXR")), "t.fmv"); });
  // The flag (header byte 18, bit 2) in a file whose index is 2.0's, one texture offset a
  // keyframe: its first offsets name TEXR chunks, not TGOP. And without textures.
  const auto flag = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") payload[18] |= 4;
  };
  // (The index then holds more offsets than a grouped file's: its last 8 bytes are past the fields
  // of format 2.2, refused before the offsets are followed.)
  testing::expect_error(ErrorCode::kCorrupt, "index: 8 bytes after its last field",
                        [&] { decode_sequence_file(rebuild(still_bytes, flag), "flag.fmv"); });
  Sequence plain = s;
  for (Keyframe& key : plain.keyframes) key.texture = {};
  testing::expect_error(ErrorCode::kCorrupt, "without the textures flag",
                        [&] { decode_sequence_file(rebuild(encode_sequence_file(plain, stills), flag), "plain.fmv"); });
}

// Values that pass every checksum but are impossible: caught by the header's limits and by the
// fields validator, as corrupt.
TEST(Container, ImpossibleValuesWithGoodChecksumsAreCorrupt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  const auto patch_header = [](size_t at, uint8_t value) {
    return [at, value](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "HEAD") payload[at] = value;
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "grid size 4", [&] { decode_sequence_file(rebuild(bytes, patch_header(0, 4)), "n.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe count", [&] { decode_sequence_file(rebuild(bytes, patch_header(20, 0)), "k.fmv"); });
  testing::expect_error(ErrorCode::kUnsupported, "representation 7",
                        [&] { decode_sequence_file(rebuild(bytes, patch_header(16, 7)), "r.fmv"); });
  // Poses in the index beyond their bounds: a code beyond 2^40, a rotation vector component beyond
  // 4 (log R's angle is at most π), a translation beyond 1e9.
  const auto index_pose = [](size_t component, int64_t change) {
    return [=](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "KIDX") payload = crafted::with_pose_change(payload, component, 1, change);
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1: a pose code beyond 2^40",
                        [&] { decode_sequence_file(rebuild(bytes, index_pose(4, int64_t{1} << 40)), "p.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1: a rotation vector component beyond 4",
                        [&] { decode_sequence_file(rebuild(bytes, index_pose(1, 410000)), "p.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "keyframe 1: a pose translation beyond 1e9",
                        [&] { decode_sequence_file(rebuild(bytes, index_pose(5, int64_t{1} << 39)), "p.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "index: a pose number longer than 6 bytes", [&] {
    decode_sequence_file(rebuild(bytes,
                                 [](const std::string& type, std::vector<uint8_t>& payload) {
                                   if (type == "KIDX") payload = crafted::with_pose_change(payload, 0, 0, int64_t{1} << 45);
                                 }),
                         "p.fmv");
  });
  // Just within the bounds: a rotation of 3.9 rad about x decodes (a proper rotation, the time's).
  const Sequence turned = decode_sequence_file(rebuild(bytes, index_pose(0, 390000)), "p.fmv");
  EXPECT_NEAR(Eigen::AngleAxisd(turned.keyframes[1].pose.rotation).angle(), 2 * M_PI - std::hypot(3.9, 0.2), 1e-4);
  // Times out of order.
  const auto same_times = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "KIDX") {
      for (size_t k = 0; k < 3; ++k)
        std::fill(payload.begin() + 4 + 8 * static_cast<long>(k), payload.begin() + 12 + 8 * static_cast<long>(k), 0);
    }
  };
  testing::expect_error(ErrorCode::kCorrupt, "keyframe", [&] { decode_sequence_file(rebuild(bytes, same_times), "t.fmv"); });
}

TEST(Container, WritesAtomicallyAndKeepsThePreviousFileOnFailure) {
  testing::TempDir dir;
  const auto path = dir.path() / "a.fmv";
  const Sequence s = small_sequence(9, 8);
  write_sequence_file(path, s, small_metadata());
  const auto before = std::filesystem::file_size(path);
  EXPECT_EQ(read_sequence_file(path).keyframes.size(), 3u);
  // An invalid sequence is refused before anything is written; the old file stays.
  Sequence bad = s;
  bad.keyframes[1].time = bad.keyframes[0].time;
  EXPECT_THROW(write_sequence_file(path, bad, small_metadata()), Error);
  EXPECT_EQ(std::filesystem::file_size(path), before);
  // An unwritable destination is an I/O error naming it, and leaves no temporary behind.
  testing::expect_error(ErrorCode::kIo, "missing", [&] { write_sequence_file(dir.path() / "missing" / "b.fmv", s, small_metadata()); });
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
  testing::expect_error(ErrorCode::kIo, "nothing.fmv", [&] { read_sequence_file(dir.path() / "nothing.fmv"); });
}

// The decode-path fuzzer's seeds (tests/fuzz/seeds/fmv) are small valid files of the current
// version, of several N and both kinds of steps: each decodes here. FACEMORPH_WRITE_FUZZ_SEEDS=DIR
// writes them again (when the format's version changes).
TEST(Container, TheFuzzSeedsAreFilesOfThisVersion) {
  std::vector<std::pair<std::string, std::vector<uint8_t>>> seeds;
  seeds.emplace_back("n5_sixteen_bit.fmv", encode_sequence_file(small_sequence(5, 8), small_metadata()));
  seeds.emplace_back("n9_groups.fmv", encode_sequence_file(small_sequence(9, 8), predicted_metadata()));
  Sequence plain = small_sequence(13, 8);
  for (Keyframe& key : plain.keyframes) {
    key.texture = {};
    key.hole_level.clear();
  }
  seeds.emplace_back("n13_geometry_only.fmv", encode_sequence_file(plain, predicted_metadata()));
  SequenceFileMetadata alone = predicted_metadata();
  alone.field_coding.intra_period = 1;
  seeds.emplace_back("n17_every_keyframe_alone.fmv", encode_sequence_file(small_sequence(17, 16), alone));
  seeds.emplace_back("n9_texture_groups.fmv", encode_sequence_file(small_sequence(9, 16), grouped_texture_metadata()));
  Sequence shared = small_sequence(9, 16);
  shared.keyframes[2].texture = shared.keyframes[0].texture;
  SequenceFileMetadata shared_stills = grouped_texture_metadata();
  shared_stills.texture_coding = TextureCoding::kStills;
  seeds.emplace_back("n9_shared_textures.fmv", encode_sequence_file(shared, shared_stills));
  // Residual frames (format 2.3): a correction of the blend in each keyframe interval.
  Sequence residuals = small_sequence(9, 8);
  residuals.residuals = {{0.25, {0.25, -0.125, -0.125}}, {0.75, {-0.0625, -0.0625, 0.125}}};
  seeds.emplace_back("n9_residual_frames.fmv", encode_sequence_file(residuals, predicted_metadata()));
  // Frame patches (format 2.4): a lattice displacement in each of two keyframe intervals, one empty.
  Sequence patches = small_sequence(9, 8);
  patches.patches = {{0.25, 5, {12, 13}, {Vec3(0.25, -0.5, 0.125), Vec3(0, 0.0625, 0)}}, {0.75, 3, {}, {}}};
  seeds.emplace_back("n9_frame_patches.fmv", encode_sequence_file(patches, predicted_metadata()));
  // The header compressed against the header dictionary (format 2.5): every file written since is.
  SequenceFileMetadata worded = predicted_metadata();
  worded.settings = R"({"field_rounding":"shaped","grid":"auto","keyframe_fit":true,"registration":"gmf","spline":"catmull-rom"})";
  seeds.emplace_back("n9_header_dictionary.fmv", encode_sequence_file(small_sequence(9, 8), worded));
  // The levels predictor (format 2.6) on H and log λ in a KGLV chunk, the same codes as written.
  const std::shared_ptr<const file_layout::GridFacts> grid17 = file_layout::grid_facts(17);
  seeds.emplace_back("n17_levels.fmv", crafted::with_first_group_by_hand(
                                           encode_sequence_file(small_sequence(17, 8), predicted_metadata()), false,
                                           [&](crafted::HandCodedKeyframe& key) {
                                             for (size_t a : {0, 1}) {
                                               const std::vector<int32_t> codes(key.residuals[a].begin(), key.residuals[a].end());
                                               key.ids[a] = 3;
                                               key.levels[a] = 1;
                                               const std::vector<int64_t> r = format::level_residuals(codes, grid17->interior_levels);
                                               key.residuals[a].assign(r.begin(), r.end());
                                             }
                                           },
                                           true));
  const std::filesystem::path folder = std::filesystem::path(FACEMORPH_TEST_DATA) / ".." / "fuzz" / "seeds" / "fmv";
  if (const char* out = std::getenv("FACEMORPH_WRITE_FUZZ_SEEDS")) {
    for (const auto& [name, bytes] : seeds) format::write_file_atomically(std::filesystem::path(out) / name, bytes);
    GTEST_SKIP() << "wrote the seeds to " << out;
  }
  size_t found = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    SCOPED_TRACE(entry.path().filename().string());
    const std::vector<uint8_t> bytes = format::read_file(entry.path());
    // hostile_*: files of our hostile set (tests/decoder/hostile_corpus.cpp, issue 46), which the
    // fuzzer starts from near the checks they meet: each is refused by name, as a file's fault or
    // a limit, when opened or when its first keyframe's frame is decoded as a player does.
    if (entry.path().filename().string().rfind("hostile_", 0) == 0) {
      try {
        const auto source = open_sequence_source(bytes, entry.path().filename().string());
        SequenceDecoder(source).decode(source->outline().times.front());
        ADD_FAILURE() << "a hostile seed decoded";
      } catch (const Error& e) {
        EXPECT_NE(e.code(), ErrorCode::kInvalidArgument) << e.what();
        EXPECT_NE(std::string(e.what()).find(entry.path().filename().string()), std::string::npos) << e.what();
      }
      continue;
    }
    EXPECT_NO_THROW(decode_sequence_file(bytes, entry.path().string()));
    ++found;
  }
  EXPECT_EQ(found, seeds.size());
}

// A source over a sequence in memory that counts how many of its keyframes and textures are alive
// at once, and may alter a keyframe as it is read (a source that disagrees with its outline).
class WatchedSource final : public KeyframeSource {
 public:
  explicit WatchedSource(const Sequence& sequence)
      : inner_(memory_source(std::make_shared<const Sequence>(sequence))), outline_(inner_->outline()) {}
  std::function<void(size_t, Keyframe&)> alter;
  std::function<void(size_t, Image&)> alter_texture;
  SequenceOutline& outline_to_alter() { return outline_; }
  mutable int keyframes_alive = 0, keyframes_peak = 0, textures_alive = 0, textures_peak = 0;

  const SequenceOutline& outline() const override { return outline_; }
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override {
    auto key = std::make_shared<Keyframe>(*inner_->keyframe(k));
    key->texture = {};  // a source may leave it empty: texture(k)
    if (alter) alter(k, *key);
    return watched(std::move(key), keyframes_alive, keyframes_peak);
  }
  std::shared_ptr<const Image> texture(size_t k) const override {
    auto image = std::make_shared<Image>(*inner_->texture(k));
    if (alter_texture) alter_texture(k, *image);
    return watched(std::move(image), textures_alive, textures_peak);
  }
  size_t surfaces_kept() const override { return 1; }
  uint64_t bytes_held() const override { return 0; }

 private:
  template <typename T>
  static std::shared_ptr<const T> watched(std::shared_ptr<T> item, int& alive, int& peak) {
    peak = std::max(peak, ++alive);
    T* raw = item.get();
    return std::shared_ptr<const T>(raw, [item = std::move(item), &alive](const T*) mutable {
      --alive;
      item.reset();
    });
  }
  std::shared_ptr<const KeyframeSource> inner_;
  SequenceOutline outline_;
};

TEST(Container, TheWriterReadsASourceAKeyframeAtATimeAndWritesWhatTheSequenceWrites) {
  for (const SequenceFileMetadata& metadata : codings()) {
    const Sequence s = ramp_sequence(7, 16);
    const WatchedSource source(s);
    const std::vector<uint8_t> from_source = encode_sequence_file(source, metadata);
    EXPECT_TRUE(from_source == encode_sequence_file(s, metadata)) << "intra period " << metadata.field_coding.intra_period;
    EXPECT_EQ(source.keyframes_alive, 0);
    EXPECT_EQ(source.keyframes_peak, 1) << "the writer held several keyframes at once";
    EXPECT_LE(source.textures_peak, 2) << "the writer held several textures at once (two while it compares them)";
    EXPECT_GE(source.textures_peak, 1);
  }
}

// From a source, a file written is streamed (its chunks spilled until the index is laid out) and a
// file measured keeps only sizes: both are the file made in memory, read a keyframe at a time. A
// source that fails part way leaves the previous file and no temporary behind.
TEST(Container, AStreamedOrMeasuredFileIsTheFileMadeInMemory) {
  testing::TempDir dir;
  const auto path = dir.path() / "a.fmv";
  const Sequence s = ramp_sequence(7, 16);
  for (const SequenceFileMetadata& metadata : codings()) {
    SCOPED_TRACE(metadata.field_coding.intra_period);
    const std::vector<uint8_t> bytes = encode_sequence_file(s, metadata);
    const WatchedSource measured(s), written(s);
    EXPECT_EQ(sequence_file_size(measured, metadata), bytes.size());
    write_sequence_file(path, written, metadata);
    EXPECT_TRUE(format::read_file(path) == bytes);
    for (const WatchedSource* source : {&measured, &written}) {
      EXPECT_EQ(source->keyframes_peak, 1);
      EXPECT_LE(source->textures_peak, 2);
    }
  }
  const std::vector<uint8_t> before = format::read_file(path);
  WatchedSource failing(s);
  failing.alter = [&](size_t k, Keyframe& key) {
    if (k + 1 == s.keyframes.size()) key.pose.translation.x() = std::nan("");
  };
  testing::expect_error(ErrorCode::kInvalidArgument, "the pose", [&] { write_sequence_file(path, failing, codings().back()); });
  EXPECT_TRUE(format::read_file(path) == before);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

// A write that cannot finish: the disk full (a file-size limit stands in for one: the writes past
// it fail with EFBIG) or no temporary folder for the streamed writer's spool. Each is an I/O error
// naming the file, and leaves the previous file and nothing else.
TEST(Container, AWriteThatCannotFinishLeavesThePreviousFile) {
  testing::TempDir dir;
  const auto path = dir.path() / "a.fmv";
  const Sequence s = ramp_sequence(7, 16);
  const SequenceFileMetadata metadata = codings().front();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, metadata);
  format::write_file_atomically(path, std::vector<uint8_t>(16, 7));
  const std::vector<uint8_t> before = format::read_file(path);
  const auto only_the_previous_file = [&] {
    EXPECT_TRUE(format::read_file(path) == before);
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
  };
  {
    rlimit saved{};
    ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
    const auto previous_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limited = saved;
    limited.rlim_cur = bytes.size() - 20;
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limited), 0);
    const WatchedSource source(s);
    testing::expect_error(ErrorCode::kIo, path.string() + ": write failed", [&] { write_sequence_file(path, source, metadata); });
    only_the_previous_file();
    testing::expect_error(ErrorCode::kIo, path.string() + ": write failed", [&] { write_sequence_file(path, s, metadata); });
    only_the_previous_file();
    testing::expect_error(ErrorCode::kIo, path.string() + ": write failed", [&] { format::write_file_atomically(path, bytes); });
    only_the_previous_file();
    setrlimit(RLIMIT_FSIZE, &saved);
    std::signal(SIGXFSZ, previous_handler);
  }
  {
    // The streamed writer spills: without a temporary folder it cannot write, and says so before
    // it opens the file.
    {
      const testing::ScopedEnv no_temporary_folder("TMPDIR", (dir.path() / "no-such-folder").string());
      const WatchedSource source(s);
      testing::expect_error(ErrorCode::kIo,
                            path.string() + ": cannot create a temporary file for the container's chunks: no temporary folder (TMPDIR = ",
                            [&] { write_sequence_file(path, source, metadata); });
    }
    only_the_previous_file();
  }
  write_sequence_file(path, s, metadata);
  EXPECT_TRUE(format::read_file(path) == bytes);
}

TEST(Container, TheWriterChecksEveryKeyframeItReadsFromASource) {
  const Sequence s = small_sequence();
  const SequenceFileMetadata metadata = predicted_metadata();
  const auto refused = [&](const std::function<void(size_t, Keyframe&)>& alter, const std::string& message) {
    WatchedSource source(s);
    source.alter = alter;
    testing::expect_error(ErrorCode::kInvalidArgument, message, [&] { encode_sequence_file(source, metadata); });
  };
  const size_t last = s.keyframes.size() - 1;
  refused(
      [&](size_t k, Keyframe& key) {
        if (k == last) key.time += 1;
      },
      "keyframe " + std::to_string(last) + ": its time is not the outline's");
  refused(
      [](size_t k, Keyframe& key) {
        if (k == 1) key.fields.fixed_nodes.push_back(0);
      },
      "keyframe 1");
  refused(
      [](size_t k, Keyframe& key) {
        if (k == 1) key.hole_level.pop_back();
      },
      "keyframe 1: ");
  refused(
      [](size_t k, Keyframe& key) {
        if (k == 1) key.pose.translation.x() = std::nan("");
      },
      "keyframe 1: the pose");
  refused(
      [](size_t k, Keyframe& key) {
        if (k == 1) key.fields.grid_n += 2;
      },
      "keyframe 1");
  // Fields valid in themselves, but not the sequence's: each would write a file the reader refuses,
  // or index G's arrays out of range.
  refused(
      [](size_t k, Keyframe& key) {
        if (k != 1) return;
        key.fields.fixed_nodes.pop_back();
        key.fields.fixed_laplacian.pop_back();
      },
      "keyframe 1: fixed-frame nodes differ from keyframe 0's");
  const Sequence coarse = small_sequence(9);
  refused(
      [&](size_t k, Keyframe& key) {
        if (k == 1) key.fields = coarse.keyframes[1].fields;
      },
      "keyframe 1: fields of another grid or representation");
  {
    WatchedSource source(s);
    source.alter_texture = [](size_t k, Image& image) {
      if (k == 2) image = Image(image.width, image.height / 2, 3);
    };
    testing::expect_error(ErrorCode::kInvalidArgument, "keyframe 2: the texture is not 16 x 16 RGB",
                          [&] { encode_sequence_file(source, metadata); });
  }
  {
    WatchedSource source(s);
    source.outline_to_alter().times[2] = source.outline_to_alter().times[1];
    testing::expect_error(ErrorCode::kInvalidArgument, "keyframe 2: time does not increase",
                          [&] { encode_sequence_file(source, metadata); });
  }
  for (const SequenceFileMetadata& coding : codings()) {
    WatchedSource source(s);  // unaltered: written, and read back as the sequence's file
    EXPECT_TRUE(encode_sequence_file(source, coding) == encode_sequence_file(s, coding));
  }
}

}  // namespace
}  // namespace facemorph
