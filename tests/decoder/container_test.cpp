// The .fmv container (spec/container.md): round trips, the checksum's definition, and every way a
// damaged or foreign file must be refused by name rather than crash or decode wrong.
#include "facemorph/sequence_file.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <cstring>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

namespace facemorph {
namespace {

using crafted::predicted_metadata;
using crafted::rebuild;
using crafted::small_metadata;
using crafted::small_sequence;


SequenceFileMetadata zstd_predicted_metadata() { return predicted_metadata(FieldCoding::Residuals::kZstdVarints); }

// Every predicted coding a writer can choose, newest first.
std::vector<SequenceFileMetadata> predicted_codings() {
  return {predicted_metadata(), predicted_metadata(FieldCoding::Residuals::kRangeCodedV14), predicted_metadata(FieldCoding::Residuals::kRangeCodedV13),
          zstd_predicted_metadata()};
}

std::string coding_name(const SequenceFileMetadata& m) {
  switch (m.field_coding.residuals) {
    case FieldCoding::Residuals::kRangeCoded: return "field coding 4";
    case FieldCoding::Residuals::kRangeCodedV14: return "field coding 3";
    case FieldCoding::Residuals::kRangeCodedV13: return "field coding 2";
    case FieldCoding::Residuals::kZstdVarints: break;
  }
  return "field coding 1";
}

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
    EXPECT_EQ(a.pose.rotation, b.pose.rotation);  // poses are stored as doubles
    EXPECT_EQ(a.pose.translation, b.pose.translation);
    EXPECT_EQ(a.fields.fixed_nodes, b.fields.fixed_nodes);
    const auto arrays_a = scalar_arrays(a.fields), arrays_b = scalar_arrays(b.fields);
    for (size_t i = 0; i < arrays_a.size(); ++i) {
      // 16-bit fixed point over the array's own range: half a step at most.
      EXPECT_LE(max_difference(arrays_a[i], arrays_b[i]), 0.5 * range(arrays_a[i]) / 65535 * (1 + 1e-9)) << "array " << i;
    }
    EXPECT_LE(max_difference(a.hole_level, b.hole_level), 0.5 * range(a.hole_level) / 65535 * (1 + 1e-9));
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
  std::vector<SequenceFileMetadata> codings = predicted_codings();
  codings.insert(codings.begin(), small_metadata());
  for (const SequenceFileMetadata& metadata : codings) {
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
  std::vector<SequenceFileMetadata> codings = predicted_codings();
  codings.insert(codings.begin(), small_metadata());
  for (const SequenceFileMetadata& metadata : codings) {
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
    testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk " + chunk.type, [&] { decode_sequence_file(damaged, "f.fmv"); });
  }
  }
}

// Format 1.1 on: values stored as exact multiples of their steps, so what the encoder rounded is
// what every decoder reads, to the bit, with either residual coder; keyframes predicted from the
// previous one only between intra keyframes.
TEST(Container, PredictedCodingStoresExactMultiplesOfItsSteps) {
  for (const SequenceFileMetadata& m : predicted_codings()) {
  SCOPED_TRACE(coding_name(m));
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
  EXPECT_EQ(info.metadata.field_coding.residuals, m.field_coding.residuals);
  ASSERT_EQ(back.keyframes.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    const auto original = scalar_arrays(s.keyframes[k].fields), stored = scalar_arrays(rounded.keyframes[k].fields),
               read = scalar_arrays(back.keyframes[k].fields);
    for (size_t a = 0; a < kScalarArrayCount; ++a) {
      EXPECT_EQ(read[a], stored[a]) << "keyframe " << k << " array " << a;
      EXPECT_LE(max_difference(original[a], stored[a]), 0.5 * m.field_coding.steps[a] * (1 + 1e-9)) << a;
    }
    EXPECT_EQ(back.keyframes[k].hole_level, rounded.keyframes[k].hole_level);
    // Field coding 3 stores the pose in float32, 4 as multiples of the pose steps: what
    // round_to_field_steps left, to the bit, and within that rounding of the original (1e-7 of the
    // values here in float32; half a step in a rotation vector component moves R by at most
    // √3/2 steps, a translation component half a step).
    EXPECT_EQ(back.keyframes[k].pose.rotation, rounded.keyframes[k].pose.rotation);
    EXPECT_EQ(back.keyframes[k].pose.translation, rounded.keyframes[k].pose.translation);
    const bool quantised = m.field_coding.residuals == FieldCoding::Residuals::kRangeCoded;
    const double rotation_tolerance = quantised ? 0.87 * m.field_coding.rotation_step : 1e-6;
    const double translation_tolerance = quantised ? 0.5 * m.field_coding.translation_step * (1 + 1e-9) : 1e-6 * s.keyframes[k].pose.translation.norm() + 1e-12;
    EXPECT_LT((back.keyframes[k].pose.rotation - s.keyframes[k].pose.rotation).cwiseAbs().maxCoeff(), rotation_tolerance);
    EXPECT_LE((back.keyframes[k].pose.translation - s.keyframes[k].pose.translation).cwiseAbs().maxCoeff(), translation_tolerance);
    if (quantised && k > 0) {
      EXPECT_GT((back.keyframes[k].pose.translation - s.keyframes[k].pose.translation).norm(), 0) << "the test's poses must need rounding";
    }
    EXPECT_LE(max_difference(s.keyframes[k].hole_level, back.keyframes[k].hole_level), 0.5e-3 * (1 + 1e-9));
  }
  const format::ContainerReader reader(bytes, "p.fmv");
  int predicted_chunks = 0;
  const std::string chunk_type = m.field_coding.residuals == FieldCoding::Residuals::kRangeCoded ? "KGOP" : "KEYP";
  for (const format::ChunkView& c : reader.chunks()) {
    EXPECT_NE(c.type, "KEYF");
    EXPECT_NE(c.type, chunk_type == "KGOP" ? "KEYP" : "KGOP");
    if (c.type != chunk_type) continue;
    const std::vector<uint8_t> payload = reader.payload(c);
    if (payload[0] == 2 && chunk_type == "KEYP") {
      const size_t reference_at = m.field_coding.residuals == FieldCoding::Residuals::kRangeCodedV14 ? 36 : 108;
      EXPECT_EQ(payload[reference_at], 0) << "keyframe 2 starts a period: intra";
    }
    ++predicted_chunks;
  }
  // A chunk per keyframe, or per group of (intra period) 2: keyframes 0-1 and 2.
  EXPECT_EQ(predicted_chunks, chunk_type == "KGOP" ? 2 : 3);
  // Steps that cannot code a value are the writer's error, not a broken file.
  SequenceFileMetadata tiny = m;
  tiny.field_coding.steps[10] = 1e-300;
  testing::expect_error(ErrorCode::kInvalidArgument, "2^30 steps", [&] { encode_sequence_file(s, tiny); });
  tiny.field_coding.steps.pop_back();
  testing::expect_error(ErrorCode::kInvalidArgument, "one step per keyframe array", [&] { encode_sequence_file(s, tiny); });
  }
}

// Each newer predicted coding spends fewer bytes on the same keyframes: the range coder fewer than
// zstd (the reason for field coding 2); carried models and the compact pose fewer again (3); one
// stream per group, a quantised pose and a packed index fewer again (4). All decode to the same
// values. Counted: every byte but the textures'.
TEST(Container, NewerPredictedCodingsTakeFewerBytes) {
  const Sequence s = small_sequence(17, 8);
  std::vector<uint64_t> geometry_bytes;
  std::vector<Sequence> decoded;
  for (const SequenceFileMetadata& m : predicted_codings()) {
    SequenceFileInfo info;
    const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
    decoded.push_back(decode_sequence_file(bytes, "p.fmv", &info));
    geometry_bytes.push_back(bytes.size());
    for (const auto& chunk : info.chunks) {
      if (chunk.type == "TEXR") geometry_bytes.back() -= chunk.stored_bytes;
    }
  }
  ASSERT_EQ(geometry_bytes.size(), 4u);
  for (size_t c = 1; c < geometry_bytes.size(); ++c) EXPECT_LT(geometry_bytes[c - 1], geometry_bytes[c]) << c;
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    for (size_t c = 1; c < decoded.size(); ++c) EXPECT_EQ(scalar_arrays(decoded[c].keyframes[k].fields), scalar_arrays(decoded[0].keyframes[k].fields));
  }
}

TEST(Container, PredictedKeyframesThatBreakTheirRulesAreCorrupt) {
  for (const SequenceFileMetadata& m : predicted_codings()) {
  const FieldCoding::Residuals coder = m.field_coding.residuals;
  if (coder == FieldCoding::Residuals::kRangeCoded) continue;  // no KEYP chunks: KeyframeGroupsThatBreakTheirRulesAreCorrupt
  SCOPED_TRACE(coding_name(m));
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), m);
  // Payload layout. Field coding 3: number (4), time (8), pose (24), reference (1) at 36, the
  // predictors packed in a u32 at 37 (array a's in bits 2a, 2a + 1), the coded size at 41.
  // Codings 2 and 1: number (4), time (8), rotation (72), translation (24), reference (1) at 108;
  // then 2: a predictor (1) per array, array a's at 109 + a, and the coded size at 123;
  // 1: the array count (4), then per array a length (4) and a predictor (1), array a's at
  // 117 + 5a, and the coded size at 183.
  const bool chained = coder == FieldCoding::Residuals::kRangeCodedV14;
  const size_t reference_at = chained ? 36 : 108;
  const auto predictor_at = [&](size_t a) { return coder == FieldCoding::Residuals::kRangeCodedV13 ? 109 + a : 117 + 5 * a; };
  const size_t size_at = chained ? 41 : coder == FieldCoding::Residuals::kRangeCodedV13 ? 123 : 183;
  const auto patch_first = [](size_t at, uint8_t value) {
    return [at, value](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "KEYP" && payload[0] == 0) payload[at] = value;
    };
  };
  testing::expect_error(ErrorCode::kCorrupt, "refers to the previous one", [&] { decode_sequence_file(rebuild(bytes, patch_first(reference_at, 1)), "r.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "unknown reference 7", [&] { decode_sequence_file(rebuild(bytes, patch_first(reference_at, 7)), "r.fmv"); });
  if (chained) {
    // Bits 28 to 31 hold no array's predictor; array 4's (bits 8, 9) is byte 38's low two bits.
    const auto patch_packed = [](size_t at, uint8_t clear, uint8_t set) {
      return [=](const std::string& type, std::vector<uint8_t>& payload) {
        if (type == "KEYP" && payload[0] == 0) payload[at] = static_cast<uint8_t>((payload[at] & ~clear) | set);
      };
    };
    testing::expect_error(ErrorCode::kCorrupt, "unused predictor bits", [&] { decode_sequence_file(rebuild(bytes, patch_packed(40, 0, 0x10)), "p.fmv"); });
    testing::expect_error(ErrorCode::kCorrupt, "array 4 has predictor 2", [&] { decode_sequence_file(rebuild(bytes, patch_packed(38, 3, 2)), "p.fmv"); });
    // A pose that is no number.
    testing::expect_error(ErrorCode::kCorrupt, "the pose is not finite", [&] {
      decode_sequence_file(rebuild(bytes, [](const std::string& type, std::vector<uint8_t>& payload) {
                             if (type == "KEYP" && payload[0] == 1) std::fill(payload.begin() + 12, payload.begin() + 16, uint8_t{0xFF});
                           }),
                           "p.fmv");
    });
    testing::expect_error(ErrorCode::kCorrupt, "a rotation vector component beyond 4", [&] {
      decode_sequence_file(rebuild(bytes, [](const std::string& type, std::vector<uint8_t>& payload) {
                             const float far = 1e30f;
                             if (type == "KEYP" && payload[0] == 1) std::memcpy(payload.data() + 16, &far, 4);
                           }),
                           "p.fmv");
    });
  } else {
    testing::expect_error(ErrorCode::kCorrupt, "predictor 9", [&] { decode_sequence_file(rebuild(bytes, patch_first(predictor_at(0), 9)), "p.fmv"); });
    // The band vectors (array 4) are no lattice: a lattice predictor there cannot be decoded.
    testing::expect_error(ErrorCode::kCorrupt, "array 4 has predictor 2", [&] { decode_sequence_file(rebuild(bytes, patch_first(predictor_at(4), 2)), "p.fmv"); });
  }
  // Residuals that end early or leave bytes over (the chunk's checksum is made right by the rebuild).
  const auto resize_stream = [&](int delta) {
    return [=](const std::string& type, std::vector<uint8_t>& payload) {
      if (type != "KEYP" || payload[0] != 0) return;
      uint32_t size = 0;
      std::memcpy(&size, payload.data() + size_at, 4);
      size = static_cast<uint32_t>(static_cast<int64_t>(size) + delta);
      std::memcpy(payload.data() + size_at, &size, 4);
      if (delta > 0) payload.insert(payload.begin() + static_cast<std::ptrdiff_t>(size_at + 4 + size - delta), static_cast<size_t>(delta), uint8_t{0});
      if (delta < 0) payload.erase(payload.begin() + static_cast<std::ptrdiff_t>(size_at + 4 + size), payload.begin() + static_cast<std::ptrdiff_t>(size_at + 4 + size - delta));
    };
  };
  for (int delta : {-3, 2}) {
    try {
      decode_sequence_file(rebuild(bytes, resize_stream(delta)), "s.fmv");
      ADD_FAILURE() << "residuals resized by " << delta << " were read";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kCorrupt) << e.what();
      EXPECT_NE(std::string(e.what()).find("s.fmv: chunk KEYP"), std::string::npos) << e.what();
    }
  }
  }
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), predicted_metadata(FieldCoding::Residuals::kRangeCodedV14));
  // A 1.0 keyframe chunk where the header announces the predicted coding.
  const std::vector<uint8_t> planes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  const auto predicted_header = [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "HEAD") return;
    const format::ContainerReader predicted(bytes, "p");
    payload = predicted.payload(predicted.chunks()[0]);
  };
  testing::expect_error(ErrorCode::kCorrupt, "not KEYP", [&] { decode_sequence_file(rebuild(planes, predicted_header), "mixed.fmv"); });
  // A field coding this decoder does not know (5) is unsupported, not corrupt.
  const auto coding_5 = [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "HEAD") return;
    const format::ContainerReader predicted(bytes, "p");
    payload = predicted.payload(predicted.chunks()[0]);
    payload[payload.size() - 4 - 8 * kKeyframeArrayCount - 1] = 5;
  };
  testing::expect_error(ErrorCode::kUnsupported, "field coding 5", [&] { decode_sequence_file(rebuild(bytes, coding_5), "c5.fmv"); });
}

// Field coding 4 (format 1.5): a chunk per group of keyframes, its stream shared by them. A group
// the index does not expect, a stream that ends early or late, pose steps that are not positive are
// corrupt; a writer without pose steps, or a pose they cannot code, is refused.
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
  testing::expect_error(ErrorCode::kCorrupt, "another group of keyframes", [&] {
    decode_sequence_file(rebuild(bytes, first_group([](std::vector<uint8_t>& p) { p[0] = 1; })), "n.fmv");
  });
  for (int delta : {-3, 2}) {
    const auto resize = first_group([delta](std::vector<uint8_t>& p) { p.resize(static_cast<size_t>(static_cast<int64_t>(p.size()) + delta), 0); });
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
  testing::expect_error(ErrorCode::kCorrupt, "a pose step that is not positive", [&] { decode_sequence_file(rebuild(bytes, translation_step(-1)), "p.fmv"); });
  // A coarser step is a valid file that decodes the same rotations and other translations.
  const Sequence coarser = decode_sequence_file(rebuild(bytes, translation_step(2 * m.field_coding.translation_step)), "c.fmv");
  const Sequence same = decode_sequence_file(bytes, "g.fmv");
  EXPECT_EQ(coarser.keyframes[1].pose.rotation, same.keyframes[1].pose.rotation);
  EXPECT_EQ(coarser.keyframes[1].pose.translation, 2 * same.keyframes[1].pose.translation);
  SequenceFileMetadata no_steps = m;
  no_steps.field_coding.rotation_step = 0;
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

TEST(Container, FieldsAppendedByALaterMinorVersionAreIgnored) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  const auto append = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "HEAD") payload.insert(payload.end(), {9, 9, 9, 9});
  };
  EXPECT_EQ(decode_sequence_file(rebuild(bytes, append), "newer.fmv").keyframes.size(), 3u);
}

TEST(Container, ForeignFilesAndOtherVersionsAreRefused) {
  const std::vector<uint8_t> bytes = encode_sequence_file(small_sequence(9, 8), small_metadata());
  testing::expect_error(ErrorCode::kCorrupt, "not a facemorph container", [&] {
    const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    decode_sequence_file({reinterpret_cast<const uint8_t*>(obj.data()), obj.size()}, "face.obj");
  });
  // Major version 2, with a valid preamble checksum.
  std::vector<uint8_t> v2 = bytes;
  v2[8] = 2;
  const uint32_t crc = format::crc32(std::span(v2).first(12));
  for (int i = 0; i < 4; ++i) v2[12 + static_cast<size_t>(i)] = static_cast<uint8_t>(crc >> (8 * i));
  testing::expect_error(ErrorCode::kUnsupported, "format version 2." + std::to_string(format::kMinorVersion), [&] { decode_sequence_file(v2, "v2.fmv"); });
  // A grid built by another rule, or another hash: the file would decode differently here.
  for (size_t at : {size_t{4}, size_t{8}}) {
    const auto other_grid = [at](const std::string& type, std::vector<uint8_t>& payload) {
      if (type == "HEAD") payload[at] ^= 1;
    };
    testing::expect_error(ErrorCode::kUnsupported, "not the grid this decoder builds", [&] { decode_sequence_file(rebuild(bytes, other_grid), "g.fmv"); });
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
      double squared = 0;
      for (size_t i = 0; i < a.pixels.size(); ++i) squared += std::pow(double(a.pixels[i]) - double(b.pixels[i]), 2);
      const double psnr = 10 * std::log10(255.0 * 255.0 * static_cast<double>(a.pixels.size()) / squared);
      EXPECT_GT(psnr, 35) << texture_codec_name(codec) << " keyframe " << k;
    }
    EXPECT_EQ(encode_sequence_file(s, m), bytes);  // deterministic in either codec
  }
  SequenceFileMetadata m = small_metadata();
  m.texture_quality = 60;
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
  testing::expect_error(ErrorCode::kUnsupported, "representation 7", [&] { decode_sequence_file(rebuild(bytes, patch_header(16, 7)), "r.fmv"); });
  // A NaN pose, and times out of order.
  const auto nan_pose = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "KEYF") std::fill(payload.begin() + 12, payload.begin() + 20, 0xFF);
  };
  testing::expect_error(ErrorCode::kCorrupt, "rotation is not finite", [&] { decode_sequence_file(rebuild(bytes, nan_pose), "p.fmv"); });
  const auto same_times = [](const std::string& type, std::vector<uint8_t>& payload) {
    if (type == "KEYF") std::fill(payload.begin() + 4, payload.begin() + 12, 0);
    if (type == "KIDX") {
      for (size_t k = 0; k < 3; ++k) std::fill(payload.begin() + 4 + 24 * static_cast<long>(k), payload.begin() + 12 + 24 * static_cast<long>(k), 0);
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

}  // namespace
}  // namespace facemorph
