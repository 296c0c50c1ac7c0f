// Hostile files for format 2.1: crafted with good checksums (crafted::rebuild, or chunks written by
// hand), each refused by name when opened or when the keyframe it breaks is decoded, without
// decoding another keyframe's data as its own, allocating past the claimed size or decoding a
// failed keyframe again.
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <fstream>

namespace facemorph {
namespace {

using crafted::rebuild;

// Where the index's offsets start (after the count, times and pose varints).
size_t offsets_at(const std::vector<uint8_t>& index) {
  format::ByteReader r(index, "index");
  const uint32_t count = r.read<uint32_t>("count");
  for (uint32_t k = 0; k < count; ++k) r.read<double>("t");
  for (uint32_t v = 0; v < 6 * count; ++v) {
    while ((r.read<uint8_t>("pose") & 0x80) != 0) {}
  }
  return index.size() - r.remaining();
}

uint64_t get64(const std::vector<uint8_t>& p, size_t at) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= uint64_t{p[at + static_cast<size_t>(i)]} << (8 * i);
  return v;
}
void put64(std::vector<uint8_t>& p, size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[at + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * i));
}

// An index edit: offset slot `to` takes slot `from`'s value (slots: G group offsets, then texture ones).
auto alias(size_t to, size_t from) {
  return [to, from](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "KIDX") return;
    const size_t at = offsets_at(payload);
    put64(payload, at + 8 * to, get64(payload, at + 8 * from));
  };
}

void put32be(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + static_cast<size_t>(i)] = static_cast<uint8_t>(v >> (8 * (3 - i)));
}
// An AVIF whose container claims `size` × `size` (ispe, tkhd, av01 entry), whatever its AV1 frames are.
std::vector<uint8_t> claiming(std::vector<uint8_t> avif, uint32_t size) {
  const auto find_all = [&](const char* tag) {
    std::vector<size_t> at;
    for (size_t i = 4; i + 4 <= avif.size(); ++i) {
      if (std::memcmp(&avif[i], tag, 4) == 0) at.push_back(i - 4);
    }
    return at;
  };
  const auto box_size = [&](size_t at) {
    return (uint32_t{avif[at]} << 24) | (uint32_t{avif[at + 1]} << 16) | (uint32_t{avif[at + 2]} << 8) | avif[at + 3];
  };
  for (size_t at : find_all("ispe")) {
    put32be(avif, at + 12, size);
    put32be(avif, at + 16, size);
  }
  for (size_t at : find_all("tkhd")) {
    const size_t end = at + box_size(at);
    put32be(avif, end - 8, size << 16);
    put32be(avif, end - 4, size << 16);
  }
  return avif;
}

auto tgop_of(uint32_t first, std::vector<uint8_t> avif) {
  return [first, avif](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "TGOP" || payload[0] != first) return;
    payload.resize(8);
    payload.insert(payload.end(), avif.begin(), avif.end());
  };
}

// Group offsets that alias: group 1's KGOP entry at group 0's chunk, group 1's TGOP entry at group
// 0's (and the reverse), and a stills file's keyframe 1 at keyframe 0's TEXR. Each names a chunk of
// its kind, so the file opens; the keyframe or texture fails when decoded, naming the chunk's own
// first keyframe, not decoding another keyframe's data as its own (spec/container.md §7, §8, §8.1).
TEST(Hostile, AliasedGroupAndTextureOffsetsFailTheirKeyframesByName) {
  const Sequence s = crafted::small_sequence(9, 16);  // 3 keyframes: groups 0-1 and 2
  const std::vector<uint8_t> bytes = encode_sequence_file(s, crafted::grouped_texture_metadata());
  // Index offset slots: the two KGOP offsets, then the two TGOP offsets.
  const auto kgop = open_sequence_source(rebuild(bytes, alias(1, 0)), "kgop");
  EXPECT_NO_THROW(kgop->keyframe(1));
  testing::expect_error(ErrorCode::kCorrupt, "holds another group of keyframes than the index says", [&] { kgop->keyframe(2); });
  testing::expect_error(ErrorCode::kCorrupt, "holds another group of keyframes than the index says",
                        [&] { decode_sequence_file(rebuild(bytes, alias(0, 1)), "kgop"); });
  const auto tgop = open_sequence_source(rebuild(bytes, alias(3, 2)), "tgop");
  EXPECT_NO_THROW(tgop->texture(1));
  testing::expect_error(ErrorCode::kCorrupt, "starts at keyframe 0, the index places it at keyframe 2", [&] { tgop->texture(2); });
  testing::expect_error(ErrorCode::kCorrupt, "starts at keyframe 2, the index places it at keyframe 0",
                        [&] { decode_sequence_file(rebuild(bytes, alias(2, 3)), "tgop"); });
  // A stills file (TEXR, one offset a keyframe): slots 0-1 KGOP, 2-4 TEXR.
  SequenceFileMetadata stills = crafted::grouped_texture_metadata();
  stills.texture_coding = TextureCoding::kStills;
  const auto texr = open_sequence_source(rebuild(encode_sequence_file(s, stills), alias(3, 2)), "texr");
  EXPECT_NO_THROW(texr->texture(0));
  testing::expect_error(ErrorCode::kCorrupt, "holds another keyframe's texture than the index says", [&] { texr->texture(1); });
}

// A file of shared textures (format 2.2) whose entries name a TEXR that is not the first naming
// keyframe's: keyframe 0 at keyframe 1's still, keyframe 2 at keyframe 0's. Every keyframe whose
// still's number is not the first keyframe naming it fails by name, none shows another's texture.
TEST(Hostile, ASharedTextureNamedFirstByAnotherKeyframeFailsByName) {
  Sequence s = crafted::small_sequence(9, 16);
  s.keyframes[2].texture = s.keyframes[0].texture;  // keyframes 0 and 2 share one TEXR
  SequenceFileMetadata m = crafted::grouped_texture_metadata();
  m.texture_coding = TextureCoding::kStills;
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  const auto good = open_sequence_source(bytes, "good");
  ASSERT_EQ(good->texture(2).get(), good->texture(0).get());
  // Index offset slots: the two KGOP offsets, then a TEXR offset a keyframe (2, 3, 4).
  const auto crafted = open_sequence_source(rebuild(bytes, alias(2, 3)), "crafted");
  for (size_t k : {0u, 1u, 2u}) {
    testing::expect_error(ErrorCode::kCorrupt, "holds another keyframe's texture than the index says", [&] { crafted->texture(k); });
  }
}

// AV1 frames of 32² in a TGOP whose AVIF container claims the header's 16²: the AV1 decoder is held
// to the claimed size (libavif's imageSizeLimit, dav1d's frame size limit), so the frame is refused
// as it is decoded, not allocated at its own size and compared afterwards (spec/container.md §8.1).
TEST(Hostile, AnAv1FrameLargerThanItsContainerClaimsIsRefusedBeforeItIsAllocated) {
  const Sequence s = crafted::small_sequence(9, 16);
  const std::vector<uint8_t> bytes = encode_sequence_file(s, crafted::grouped_texture_metadata());
  Image big(32, 32, 3);
  for (size_t i = 0; i < big.pixels.size(); ++i) big.pixels[i] = static_cast<uint8_t>(i * 7);
  const Image* two_big[] = {&big, &big};
  const Image* one_big[] = {&big};
  for (const auto& file : {rebuild(bytes, tgop_of(0, claiming(encode_avif_sequence(two_big, 80), 16))),
                           rebuild(bytes, tgop_of(2, claiming(encode_avif_sequence(one_big, 80), 16))),
                           rebuild(bytes, tgop_of(2, claiming(encode_avif(big, 80), 16)))}) {
    testing::expect_error(ErrorCode::kCorrupt, "frame 0 of the AVIF sequence is damaged",
                          [&] { decode_sequence_file(file, "claims.fmv"); });
  }
  // A TGOP too short for its own fields: truncated, naming the field.
  testing::expect_error(ErrorCode::kTruncated, "the image codec", [&] {
    decode_sequence_file(rebuild(bytes,
                                 [](const std::string& type, std::vector<uint8_t>& p) {
                                   if (type == "TGOP" && p[0] == 0) p.resize(4);
                                 }),
                         "short.fmv");
  });
}

// A TGOP stored compressed (spec/container.md §6, §9): corrupt at open. Group 1's TGOP is the file's
// last chunk, so compressing it moves no other chunk.
TEST(Hostile, ACompressedTextureGroupIsRefusedAtOpen) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(9, 16), crafted::grouped_texture_metadata());
  const format::ContainerReader reader(bytes, "in");
  format::ContainerWriter writer;
  const std::vector<format::ChunkView>& chunks = reader.chunks();
  ASSERT_EQ(chunks.back().type, "TGOP");
  for (const format::ChunkView& c : chunks) {
    if (&c != &chunks.back()) {
      writer.add(format::PreparedChunk{c.type, c.flags, c.raw_size, {c.stored.begin(), c.stored.end()}});
      continue;
    }
    std::vector<uint8_t> payload = reader.payload(c);
    payload.resize(payload.size() + 4096);  // zeros after the AVIF: compressed, it is smaller
    const format::PreparedChunk compressed = format::prepare_chunk("TGOP", payload, true, 19);
    ASSERT_LT(compressed.stored.size(), payload.size());
    writer.add(compressed);
  }
  const std::vector<uint8_t> file = writer.finish();
  testing::expect_error(ErrorCode::kCorrupt, "is compressed; a texture group's chunk never is",
                        [&] { open_sequence_source(file, "compressed"); });
}

// Writes `bytes` over the file at `path` in place (same length: no truncation, so a mapping of it
// stays valid and, its pages released, reads the new bytes).
void overwrite_in_place(const std::filesystem::path& path, const std::vector<uint8_t>& bytes) {
  std::fstream out(path, std::ios::binary | std::ios::in | std::ios::out);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// A keyframe's fields or texture that failed fails again with the same error, without decoding
// again (spec/container.md §9 "When", §10.1). Observed without a clock: after the first failure
// the file on disk is overwritten in place by the good file of the same length, so a decode that
// ran again would read other bytes (and fail their checksum against the walk's); the remembered
// failure is the first one, word for word.
TEST(Hostile, AFailedKeyframeOrTextureIsRememberedNotDecodedAgain) {
  const std::vector<uint8_t> good = encode_sequence_file(crafted::small_sequence(9, 16), crafted::grouped_texture_metadata());
  const std::vector<uint8_t> bad = rebuild(good, [](const std::string& type, std::vector<uint8_t>& p) {
    if (type == "TGOP" && p[0] == 0) p[4] = 7;  // image codec 7: unsupported
    if (type == "KGOP" && p[0] == 0) p[0] = 9;  // another first keyframe: corrupt
  });
  ASSERT_EQ(bad.size(), good.size());
  testing::TempDir dir;
  const auto path = dir / "repaired.fmv";
  format::write_file_atomically(path, bad);
  const auto source = open_sequence_source(path);
  testing::expect_error(ErrorCode::kUnsupported, "image codec 7", [&] { source->texture(0); });
  testing::expect_error(ErrorCode::kCorrupt, "holds another group of keyframes", [&] { source->keyframe(0); });
  overwrite_in_place(path, good);
  testing::expect_error(ErrorCode::kUnsupported, "image codec 7", [&] { source->texture(0); });
  testing::expect_error(ErrorCode::kCorrupt, "holds another group of keyframes", [&] { source->keyframe(0); });
  // Keyframe 1 had not failed: it is decoded now, from the bytes as they are.
  testing::expect_error(ErrorCode::kCorrupt, "checksum mismatch in chunk TGOP", [&] { source->texture(1); });
}

// An index of K entries whose payload holds fewer bytes than K entries need: truncated, naming the
// entries, before they are allocated (spec/container.md §10.2 step 5).
TEST(Hostile, AnIndexShorterThanItsEntriesIsTruncatedBeforeTheyAreAllocated) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(9, 16), crafted::grouped_texture_metadata());
  const format::ContainerReader reader(bytes, "in");
  format::ContainerWriter writer;
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type != "KIDX") {
      writer.add(format::PreparedChunk{c.type, c.flags, c.raw_size, {c.stored.begin(), c.stored.end()}});
      continue;
    }
    std::vector<uint8_t> payload = reader.payload(c);
    payload.resize(4 + 3 * 8 + 6 * 3);  // the count, the times and one byte a pose number: no offsets
    writer.add(format::prepare_chunk("KIDX", payload, true, 0));
  }
  testing::expect_error(ErrorCode::kTruncated, "index: truncated: the entries",
                        [&] { open_sequence_source(writer.finish(), "short index"); });
}

// A TGOP stored with 8 MiB after its AVIF, in a file mapped from disk under a 4 MiB budget: the
// largest payload is counted at open (spec/container.md §10.1), a TGOP's as a KGOP's or TEXR's.
TEST(Hostile, ATextureGroupPayloadOverTheBudgetIsRefusedAtOpen) {
  const std::vector<uint8_t> bytes = rebuild(encode_sequence_file(crafted::small_sequence(9, 16), crafted::grouped_texture_metadata()),
                                             [](const std::string& type, std::vector<uint8_t>& payload) {
                                               if (type == "TGOP" && payload[0] == 0) payload.resize(payload.size() + (8 << 20));
                                             });
  testing::TempDir dir;
  const auto path = dir / "padded.fmv";
  format::write_file_atomically(path, bytes);
  DecoderLimits limits;
  limits.max_memory_bytes = uint64_t{4} << 20;
  testing::expect_error(ErrorCode::kLimit, "over the memory limit", [&] { open_sequence_source(path, limits); });
  limits.max_memory_bytes = uint64_t{64} << 20;
  EXPECT_NO_THROW(open_sequence_source(path, limits));
}

// AV1 frames smaller than the AVIF container claims (16² frames whose ispe and tkhd say 32², in a
// file of 32² textures): libavif scales each frame to the stated size, so the texture is 32² with
// every texel written, the frame's pattern upscaled (spec/container.md §8.2). Uninitialised or
// out-of-frame texels would show as a mismatch here and under ASan/valgrind.
TEST(Hostile, AnAv1FrameSmallerThanItsContainerClaimsIsScaledToIt) {
  const std::vector<uint8_t> large = encode_sequence_file(crafted::small_sequence(9, 32), crafted::grouped_texture_metadata());
  Image small(16, 16, 3);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 16; ++x) {
      for (int c = 0; c < 3; ++c)
        small.pixels[(static_cast<size_t>(y) * 16 + x) * 3 + c] = static_cast<uint8_t>(x < 8 ? 40 + 60 * c : 200 - 50 * c);
    }
  }
  const Image* two_small[] = {&small, &small};
  const std::vector<uint8_t> smaller = rebuild(large, tgop_of(0, claiming(encode_avif_sequence(two_small, 80), 32)));
  const Sequence decoded = decode_sequence_file(smaller, "smaller.fmv");
  for (int k : {0, 1}) {
    const Image& texture = decoded.keyframes[static_cast<size_t>(k)].texture;
    ASSERT_EQ(texture.width, 32);
    ASSERT_EQ(texture.height, 32);
    ASSERT_EQ(texture.pixels.size(), size_t{32} * 32 * 3);
    // Away from the edge between the halves, each texel is its half's colour (lossy: a few units).
    for (int y = 0; y < 32; ++y) {
      for (int x : {2, 10, 21, 29}) {
        for (int c = 0; c < 3; ++c) {
          const int expected = x < 16 ? 40 + 60 * c : 200 - 50 * c;
          EXPECT_NEAR(texture.pixels[(static_cast<size_t>(y) * 32 + x) * 3 + c], expected, 12)
              << "keyframe " << k << " texel " << x << "," << y;
        }
      }
    }
  }
  // The on-demand source gives the same texture.
  const auto source = open_sequence_source(smaller, "smaller.fmv");
  EXPECT_EQ(source->texture(1)->pixels, decoded.keyframes[1].texture.pixels);
}

}  // namespace
}  // namespace facemorph
