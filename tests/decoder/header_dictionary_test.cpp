// The header dictionary (format 2.5, spec/container.md §3.4): its frozen bytes, the header the
// writer compresses against it, and every way a chunk that claims it is refused by name.
#include "format/header_dictionary.hpp"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"
#include "format/file_io.hpp"
#include "format/zstd_frame.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <sstream>

namespace facemorph {
namespace {

// SHA-256 (FIPS 180-4), for the dictionary's stated hash: small enough to hold here, where the
// project links no cryptographic library.
std::string sha256_hex(std::span<const uint8_t> message) {
  static constexpr std::array<uint32_t, 64> k = {
      0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5, 0xd807aa98, 0x12835b01, 0x243185be,
      0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa,
      0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85,
      0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3,
      0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f,
      0x682e6ff3, 0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};
  std::array<uint32_t, 8> h = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  std::vector<uint8_t> m(message.begin(), message.end());
  m.push_back(0x80);
  while (m.size() % 64 != 56) m.push_back(0);
  for (int i = 7; i >= 0; --i) m.push_back(static_cast<uint8_t>((uint64_t{message.size()} * 8) >> (8 * i)));
  const auto rotr = [](uint32_t x, int n) { return (x >> n) | (x << (32 - n)); };
  for (size_t block = 0; block < m.size(); block += 64) {
    std::array<uint32_t, 64> w{};
    for (int t = 0; t < 16; ++t) {
      const uint8_t* p = &m[block + 4 * static_cast<size_t>(t)];
      w[t] = (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
    }
    for (int t = 16; t < 64; ++t) {
      const uint32_t s0 = rotr(w[t - 15], 7) ^ rotr(w[t - 15], 18) ^ (w[t - 15] >> 3);
      const uint32_t s1 = rotr(w[t - 2], 17) ^ rotr(w[t - 2], 19) ^ (w[t - 2] >> 10);
      w[t] = w[t - 16] + s0 + w[t - 7] + s1;
    }
    std::array<uint32_t, 8> v = h;
    for (int t = 0; t < 64; ++t) {
      const uint32_t t1 = v[7] + (rotr(v[4], 6) ^ rotr(v[4], 11) ^ rotr(v[4], 25)) + ((v[4] & v[5]) ^ (~v[4] & v[6])) + k[t] + w[t];
      const uint32_t t2 = (rotr(v[0], 2) ^ rotr(v[0], 13) ^ rotr(v[0], 22)) + ((v[0] & v[1]) ^ (v[0] & v[2]) ^ (v[1] & v[2]));
      for (int i = 7; i > 0; --i) v[i] = v[i - 1];
      v[4] += t1;
      v[0] = t1 + t2;
    }
    for (int i = 0; i < 8; ++i) h[i] += v[i];
  }
  std::string hex;
  for (uint32_t word : h) {
    char text[9];
    std::snprintf(text, sizeof text, "%08x", word);
    hex += text;
  }
  return hex;
}

std::string text_of(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::filesystem::path kRepository = std::filesystem::path(FACEMORPH_TEST_DATA) / ".." / "..";

// What fmenc writes into a header's settings (abridged): the keys the dictionary holds.
SequenceFileMetadata realistic_metadata() {
  SequenceFileMetadata m = crafted::predicted_metadata();
  m.settings =
      R"({"conformal_fallbacks":[],"density_equalising":0.0,"dropped_frames":[],"face_orientation":null,"field_error":0.0009,)"
      R"("field_error_auto":true,"field_rounding":"shaped","grid":"auto","grid_chosen":17,"inter_dead_zone":"auto",)"
      R"("keyframe_fit":true,"keyframes":0.1,"registration":"gmf","representation":"auto","spline":"catmull-rom","warnings":[]})";
  m.landmark_names = {"nose_tip", "nose_bridge", "between_eyes", "chin_bottom_midline", "mouth_corner_right", "mouth_corner_left"};
  return m;
}

// The file's chunk `type` (the first), as the container reads it.
format::ChunkView chunk_of(const std::vector<uint8_t>& bytes, const std::string& type) {
  const format::ContainerReader reader(bytes, "file");
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == type) return c;
  }
  ADD_FAILURE() << "no " << type;
  return {};
}

// `bytes` with its header chunk stored as `alter` leaves it (flags, sizes, frame), every offset and
// checksum made right.
std::vector<uint8_t> with_header_chunk(const std::vector<uint8_t>& bytes, const std::function<void(format::PreparedChunk&)>& alter) {
  return crafted::rebuild(bytes, [](const std::string&, std::vector<uint8_t>&) {}, false, false, {}, alter);
}

TEST(HeaderDictionary, IsTheFrozenFileWhoseHashTheSpecStates) {
  // The hash itself first: the standard's test vectors ("abc" and the 56-byte message, two blocks).
  const std::string abc = "abc";
  EXPECT_EQ(sha256_hex({reinterpret_cast<const uint8_t*>(abc.data()), abc.size()}),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  const std::string two = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  EXPECT_EQ(sha256_hex({reinterpret_cast<const uint8_t*>(two.data()), two.size()}),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  // Frozen: every 2.5 file's header was compressed against exactly these bytes.
  const std::span<const uint8_t> embedded = format::header_dictionary();
  EXPECT_EQ(embedded.size(), 2291u);
  EXPECT_EQ(sha256_hex(embedded), "10802765cbc988f0a160f39dad0392283aab712981e555587b0135ec352caee8");
  EXPECT_EQ(sha256_hex(embedded), format::kHeaderDictionarySha256);
  const std::vector<uint8_t> file = format::read_file(kRepository / "format" / "header_dictionary.bin");
  EXPECT_TRUE(std::equal(file.begin(), file.end(), embedded.begin(), embedded.end())) << "the library embeds other bytes than the file";
  const std::string spec = text_of(kRepository / "spec" / "container.md");
  EXPECT_NE(spec.find(std::string(format::kHeaderDictionarySha256)), std::string::npos) << "spec/container.md §3.4 states another hash";
}

TEST(HeaderDictionary, TheWriterCompressesTheHeaderAgainstItWhereThatIsSmaller) {
  const Sequence s = crafted::small_sequence(17, 8);
  const SequenceFileMetadata m = realistic_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  const format::ContainerReader reader(bytes, "file");
  EXPECT_EQ(reader.minor_version(), format::kMinorVersion);  // the writer's version, 2.5 or later
  const format::ChunkView& header = reader.chunks()[0];
  ASSERT_EQ(header.type, "HEAD");
  EXPECT_EQ(header.flags, format::kChunkCritical | format::kChunkCompressed | format::kChunkDictionary);
  const std::vector<uint8_t> payload = reader.payload(header);
  EXPECT_LT(header.stored.size() + 100, format::compress_frame(payload, 19).size()) << "the dictionary saves little";
  // Read back whole: the header's strings as written, the geometry as without the dictionary.
  SequenceFileInfo info;
  decode_sequence_file(bytes, "file", &info);
  EXPECT_EQ(info.metadata.settings, m.settings);
  EXPECT_EQ(info.metadata.landmark_names, m.landmark_names);
  EXPECT_EQ(info.chunks[0].against_dictionary, 1);
  // Only the header: the index and the other chunks are numbers the dictionary's words do not help.
  for (size_t i = 1; i < reader.chunks().size(); ++i) EXPECT_FALSE(reader.chunks()[i].against_dictionary()) << reader.chunks()[i].type;
  // A payload the dictionary does not help keeps the plain frame: the flag says which.
  std::vector<uint8_t> noise(4000);
  uint32_t x = 1;
  for (uint8_t& b : noise) b = static_cast<uint8_t>((x = x * 1664525u + 1013904223u) >> 24);
  std::vector<uint8_t> repeated;
  for (int i = 0; i < 8; ++i) repeated.insert(repeated.end(), noise.begin(), noise.end());
  const format::PreparedChunk plain = format::prepare_chunk("TEST", repeated, false, 19, format::Dictionary::kHeader);
  EXPECT_EQ(plain.flags & format::kChunkDictionary, 0u);
  EXPECT_NE(plain.flags & format::kChunkCompressed, 0u);
}

TEST(HeaderDictionary, AFileBefore2_5MayNotUseIt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(9, 8), realistic_metadata());
  ASSERT_NO_THROW(decode_sequence_file(bytes, "good.fmv"));
  // Flag bit 2 is reserved in 2.0-2.4, as a 2.4 decoder refuses it (the preamble alone stamped 2.4).
  std::vector<uint8_t> old = bytes;
  old[10] = 4;
  const uint32_t crc = format::crc32(std::span(old).first(12));
  std::memcpy(old.data() + 12, &crc, sizeof crc);
  testing::expect_error(ErrorCode::kCorrupt, "chunk HEAD at offset 16 sets reserved flags", [&] { decode_sequence_file(old, "old.fmv"); });
  // As 2.4's writer wrote it, the header without the dictionary, the same file reads.
  EXPECT_NO_THROW(decode_sequence_file(crafted::with_minor_version(bytes, 4), "plain.fmv"));
  // The staged encode's part file (spec/part-file.md) never may.
  format::ContainerKind part{{0x89, 'F', 'M', 'S', '\r', '\n', 0x1A, '\n'}, 1, 0, "part file"};
  format::ContainerWriter writer(part);
  const std::vector<uint8_t> words(format::header_dictionary().begin(), format::header_dictionary().end());
  const format::PreparedChunk chunk = format::prepare_chunk("PHDR", words, true, 19, format::Dictionary::kHeader);
  ASSERT_NE(chunk.flags & format::kChunkDictionary, 0u);
  writer.add(chunk);
  const std::vector<uint8_t> file = writer.finish();
  testing::expect_error(ErrorCode::kCorrupt, "sets reserved flags", [&] { format::ContainerReader(file, "part.fms", UINT64_MAX, part); });
}

TEST(HeaderDictionary, AHeaderThatDoesNotDecompressAgainstItIsCorrupt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(9, 8), realistic_metadata());
  const std::vector<uint8_t> payload = format::ContainerReader(bytes, "good").payload(chunk_of(bytes, "HEAD"));
  SCOPED_TRACE("plain");
  // The dictionary's frame read as a plain one: its matches reach before its start.
  testing::expect_error(ErrorCode::kCorrupt, "chunk HEAD at offset 16: damaged zstd payload", [&] {
    decode_sequence_file(with_header_chunk(bytes, [](format::PreparedChunk& c) { c.flags &= ~format::kChunkDictionary; }), "plain.fmv");
  });
  SCOPED_TRACE("other");
  // A frame made against other bytes (the header itself, so that it copies all of it from there):
  // against the dictionary it decompresses to other bytes, which its checksum tells.
  const std::vector<uint8_t> other = payload;
  testing::expect_error(ErrorCode::kCorrupt, "does not decompress against the header dictionary", [&] {
    decode_sequence_file(with_header_chunk(bytes, [&](format::PreparedChunk& c) { c.stored = format::compress_frame(payload, 19, other); }),
                         "other.fmv");
  });
  SCOPED_TRACE("unchecked");
  // The flag on a frame without zstd's content checksum, which alone tells such a frame apart.
  testing::expect_error(ErrorCode::kCorrupt, "against the header dictionary without its content checksum", [&] {
    decode_sequence_file(with_header_chunk(bytes, [&](format::PreparedChunk& c) { c.stored = format::compress_frame(payload, 19); }),
                         "unchecked.fmv");
  });
  SCOPED_TRACE("stored");
  // The flag on a payload stored as it is.
  testing::expect_error(ErrorCode::kCorrupt, "sets the dictionary flag (bit 2) on a payload that is not compressed", [&] {
    decode_sequence_file(with_header_chunk(bytes,
                                           [&](format::PreparedChunk& c) {
                                             c.flags = format::kChunkCritical | format::kChunkDictionary;
                                             c.stored = payload;
                                           }),
                         "stored.fmv");
  });
  SCOPED_TRACE("big");
  // The header's bound holds before anything is decompressed, against the dictionary as without it.
  testing::expect_error(ErrorCode::kCorrupt, "a header holds at most", [&] {
    decode_sequence_file(with_header_chunk(bytes, [&](format::PreparedChunk& c) { c.raw_size = uint64_t{1} << 29; }), "big.fmv");
  });
}

// RFC 8878 §3.1.1.1: a frame's header is the magic, the descriptor, a window descriptor unless the
// frame is a single segment, the dictionary ID and the content size, sized by the descriptor.
struct FrameHeader {
  size_t window = 0, dictionary = 0, content_size = 0;  // offsets of those fields
  size_t content_size_bytes = 0, end = 0;
};
FrameHeader frame_header(const std::vector<uint8_t>& frame) {
  const uint8_t d = frame.at(4);
  const bool single = (d & 0x20) != 0;
  static constexpr size_t kDictionaryBytes[4] = {0, 1, 2, 4}, kSizeBytes[4] = {0, 2, 4, 8};
  FrameHeader h;
  h.window = 5;
  h.dictionary = h.window + (single ? 0 : 1);
  h.content_size = h.dictionary + kDictionaryBytes[d & 3];
  h.content_size_bytes = (d >> 6) == 0 ? (single ? 1 : 0) : kSizeBytes[d >> 6];
  h.end = h.content_size + h.content_size_bytes;
  return h;
}

// Every other frame a chunk with flag bit 2 may hold but the one zstd frame §3.2 and §3.4 allow is
// corrupt, named, at open: a damaged checksum, a frame that names a dictionary ID (zstd's
// dictionary_wrong: the prefix has none), one whose content size lies or is not announced, a
// skippable frame before or after it, two frames.
TEST(HeaderDictionary, AnythingButOneCheckedFrameOfTheAnnouncedSizeIsCorrupt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(9, 8), realistic_metadata());
  const format::ChunkView header = chunk_of(bytes, "HEAD");
  ASSERT_TRUE(header.against_dictionary());
  const std::vector<uint8_t> frame(header.stored.begin(), header.stored.end());
  const FrameHeader h = frame_header(frame);
  ASSERT_EQ(frame[4] & 3, 0) << "the writer's frame names no dictionary ID";
  const auto corrupt = [&](const std::string& name, const std::vector<uint8_t>& stored, const std::string& fragment) {
    SCOPED_TRACE(name);
    testing::expect_error(ErrorCode::kCorrupt, "chunk HEAD at offset 16" + fragment, [&] {
      decode_sequence_file(with_header_chunk(bytes, [&](format::PreparedChunk& c) { c.stored = stored; }), name + ".fmv");
    });
  };
  const std::string damaged = ": does not decompress against the header dictionary";
  const std::string announce = ": the zstd frame does not announce the chunk's size";  // §10.2 step 2, before the checksum's
  std::vector<uint8_t> f = frame;
  f.back() ^= 1;
  corrupt("checksum", f, damaged);
  f = frame;
  f[4] |= 1;
  f.insert(f.begin() + static_cast<ptrdiff_t>(h.dictionary), uint8_t{42});
  corrupt("dictionary_id", f, damaged);
  for (int by : {-1, 1}) {
    f = frame;
    ASSERT_GE(h.content_size_bytes, 1u);
    f[h.content_size] = static_cast<uint8_t>(f[h.content_size] + by);
    corrupt("size_" + std::to_string(by), f, announce);
  }
  // Not a single segment, with a window of 128 KiB and no content size: decompresses to the raw
  // size, but announces none.
  f = frame;
  f.erase(f.begin() + static_cast<ptrdiff_t>(h.content_size), f.begin() + static_cast<ptrdiff_t>(h.end));
  f[4] = static_cast<uint8_t>(f[4] & 0x1F & ~0x20);
  f.insert(f.begin() + 5, uint8_t{7 << 3});
  ASSERT_FALSE(format::announced_size(f).has_value());
  corrupt("no_size", f, announce);
  const std::vector<uint8_t> skippable = {0x50, 0x2A, 0x4D, 0x18, 4, 0, 0, 0, 1, 2, 3, 4};
  f = skippable;
  f.insert(f.end(), frame.begin(), frame.end());
  corrupt("skippable_before", f, announce);  // zstd gives a skippable frame's content size as 0
  f = frame;
  f.insert(f.end(), skippable.begin(), skippable.end());
  corrupt("skippable_after", f, damaged);
  f = frame;
  f.insert(f.end(), frame.begin(), frame.end());
  corrupt("two_frames", f, damaged);
}

// The reader decodes flag bit 2 on any compressed chunk of a 2.5 file (§3.4), though the writer
// sets it on the header alone: the patches against the dictionary read as without.
TEST(HeaderDictionary, AReaderDecodesItOnAnyCompressedChunk) {
  Sequence s = crafted::small_sequence(9, 8);
  s.patches = {{0.25, 3, {4}, {Vec3(0.0625, 0, 0)}}};
  const std::vector<uint8_t> bytes = encode_sequence_file(s, realistic_metadata());
  const Sequence plain = decode_sequence_file(bytes, "plain.fmv");
  const std::vector<uint8_t> raw = crafted::chunk_payload(bytes, "PTCH");
  const std::vector<uint8_t> against = crafted::rebuild(
      bytes, [](const std::string&, std::vector<uint8_t>&) {}, false, false, {}, {}, [&](format::PreparedChunk& c) {
        if (c.type != "PTCH") return;
        c.stored = format::compress_frame(raw, 19, format::header_dictionary());
        c.flags |= format::kChunkCompressed | format::kChunkDictionary;
        c.raw_size = raw.size();
      });
  SequenceFileInfo info;
  const Sequence read = decode_sequence_file(against, "against.fmv", &info);
  int flagged = 0;
  for (const auto& c : info.chunks) flagged += c.against_dictionary;
  EXPECT_EQ(flagged, 2);  // HEAD and PTCH
  ASSERT_EQ(read.patches.size(), 1u);
  EXPECT_EQ(read.patches[0].nodes, plain.patches[0].nodes);
  EXPECT_EQ(read.patches[0].displacements, plain.patches[0].displacements);
}

}  // namespace
}  // namespace facemorph
