// Writes facemorph's own hostile set (issue 46): at least one .fmv file per row of the outside
// review's table of files that broke the decoder's limits, and a few more, every checksum valid
// (crafted::rebuild, or chunks laid out here), with a manifest for the scripts that run the tools
// (tests/tools/hostile_files_test.sh) and the WebAssembly decoder (tests/web/hostile.sh) on each and
// hold every run to its bounds (3 s, 256 MB, a named error or a finite result, never a signal).
//   hostile_corpus OUT_DIR
// OUT_DIR/manifest.tsv: one line a file: NAME <tab> TIMES (comma-separated seconds to decode, the
// last near the end of the range) <tab> what it holds <tab> what every tool's error must say, where
// every run must fail (empty: the file may open and decode). Sizes a zstd frame announces are the review's
// (500 MB of zeros) while the generator holds kilobytes: such frames are laid out here by hand, raw
// and RLE blocks (RFC 8878 §3.1.1.2).
#include "codec/core/container/file_layout.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"
#include "format/ranged_patches.hpp"
#include "format/zstd_frame.hpp"
#include "tests/decoder/crafted_files.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;
using crafted::rebuild;

// ---- zstd frames laid out by hand ----

// A frame's content: bytes as they are (raw blocks) or one byte repeated (RLE blocks).
struct Piece {
  Bytes raw;
  uint64_t run = 0;
  uint8_t byte = 0;
};

// One zstd frame of `pieces` that announces its content size: a frame of 500 MB of zeros takes
// 4 bytes per 128 KiB, so the generator never holds what it announces.
Bytes zstd_frame(const std::vector<Piece>& pieces) {
  constexpr uint64_t kBlock = 128 << 10;
  uint64_t content = 0;
  for (const Piece& p : pieces) content += p.raw.size() + p.run;
  Bytes f = {0x28, 0xB5, 0x2F, 0xFD, 0xE0};  // magic; single segment, 8-byte content size
  for (int i = 0; i < 8; ++i) f.push_back(static_cast<uint8_t>(content >> (8 * i)));
  struct Block {
    uint32_t type, size;
    const uint8_t* data;
  };
  std::vector<Block> blocks;
  for (const Piece& p : pieces) {
    for (uint64_t at = 0; at < p.raw.size(); at += kBlock)
      blocks.push_back({0, static_cast<uint32_t>(std::min(kBlock, p.raw.size() - at)), p.raw.data() + at});
    for (uint64_t at = 0; at < p.run; at += kBlock) blocks.push_back({1, static_cast<uint32_t>(std::min(kBlock, p.run - at)), &p.byte});
  }
  if (blocks.empty()) blocks.push_back({0, 0, nullptr});
  for (size_t b = 0; b < blocks.size(); ++b) {
    const uint32_t h = (b + 1 == blocks.size() ? 1u : 0u) | (blocks[b].type << 1) | (blocks[b].size << 3);
    for (int i = 0; i < 3; ++i) f.push_back(static_cast<uint8_t>(h >> (8 * i)));
    if (blocks[b].type == 1)
      f.push_back(*blocks[b].data);
    else
      f.insert(f.end(), blocks[b].data, blocks[b].data + blocks[b].size);
  }
  return f;
}

format::PreparedChunk compressed_chunk(const std::string& type, const std::vector<Piece>& pieces) {
  uint64_t content = 0;
  for (const Piece& p : pieces) content += p.raw.size() + p.run;
  return {type, format::kChunkCompressed | format::kChunkCritical, content, zstd_frame(pieces)};
}

// ---- The index's offsets, for a header or index laid out here ----

// The file with its header replaced by `head` (nullopt: kept) and its index made by `make_index`
// from the index payload, each offset moved to where its chunk now starts. `make_index` must give a
// chunk whose size does not depend on the offsets' values (a stored chunk, or a frame laid out here).
Bytes relaid(const Bytes& bytes, std::optional<format::PreparedChunk> head, const std::function<format::PreparedChunk(Bytes)>& make_index) {
  const format::ContainerReader reader(bytes, "in");
  const std::vector<format::ChunkView>& old = reader.chunks();
  const auto kept = [](const format::ChunkView& c) {
    return format::PreparedChunk{c.type, c.flags, c.raw_size, {c.stored.begin(), c.stored.end()}};
  };
  if (!head) head = kept(old[0]);
  size_t groups = 0, texture_groups = 0;
  bool textured = false;
  for (const format::ChunkView& c : old) {
    groups += c.type == "KGOP" || c.type == "KGLV";
    texture_groups += c.type == "TGOP";
    textured = textured || c.type == "TEXR";
  }
  const Bytes index = reader.payload(old[1]);
  const uint64_t index_size = make_index(index).total_size();
  const int64_t delta =
      static_cast<int64_t>(head->total_size() + index_size) - static_cast<int64_t>(old[0].total_size() + old[1].total_size());
  format::ByteReader r(index, "index");
  format::ByteWriter w;
  const uint32_t count = r.read<uint32_t>("count");
  w.write(count);
  for (uint32_t k = 0; k < count; ++k) w.write(r.read<double>("t"));
  for (uint32_t v = 0; v < 6 * count; ++v) {
    uint8_t byte = 0;
    do {
      byte = r.read<uint8_t>("pose");
      w.write(byte);
    } while ((byte & 0x80) != 0);
  }
  const size_t offsets = groups + (textured && texture_groups == 0 ? count : 0) + texture_groups;
  for (size_t i = 0; i < offsets; ++i) {
    const uint64_t offset = r.read<uint64_t>("offset");
    w.write(offset == 0 ? uint64_t{0} : static_cast<uint64_t>(static_cast<int64_t>(offset) + delta));
  }
  w.bytes(r.bytes(r.remaining(), "appended"));
  const format::PreparedChunk new_index = make_index(w.take());
  if (new_index.total_size() != index_size) throw Error(ErrorCode::kInvalidArgument, "relaid: the index's size moved with its offsets");
  format::ContainerWriter writer;
  writer.add(*head);
  writer.add(new_index);
  for (size_t i = 2; i < old.size(); ++i) writer.add(kept(old[i]));
  return writer.finish();
}

format::PreparedChunk stored_index(Bytes payload) { return format::prepare_chunk("KIDX", std::move(payload), true); }

Bytes payload_of(const Bytes& file, const std::string& type) {
  const format::ContainerReader reader(file, "in");
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == type) return reader.payload(c);
  }
  throw Error(ErrorCode::kInvalidArgument, "no " + type + " chunk");
}

// ---- Edits of decompressed payloads (for crafted::rebuild) ----

// The header's layout (spec/container.md §5): N at 0, the spline at 17, K at 20, the texture size
// at 72; it ends with the intra period, 14 array steps and 2 pose steps (132 bytes).
constexpr size_t kHeaderTail = 4 + 14 * 8 + 2 * 8;

template <typename T>
auto patch(const std::string& type, size_t at, T value) {
  return [type, at, value](const std::string& t, Bytes& payload) {
    if (t == type) std::memcpy(payload.data() + at, &value, sizeof value);
  };
}

auto appending(std::string type, size_t extra, uint8_t value = 0) {
  return [type, extra, value](const std::string& t, Bytes& payload) {
    if (t == type) payload.insert(payload.end(), extra, value);
  };
}

// The header's step of keyframe array `a` (13: the hole level) set to `step`.
auto with_step(size_t a, double step) {
  return [a, step](const std::string& type, Bytes& payload) {
    if (type == "HEAD") std::memcpy(payload.data() + payload.size() - 16 - 8 * (14 - a), &step, sizeof step);
  };
}

// small_metadata's landmark names ("nose_tip", "rim_top") replaced by `count` names of `bytes`
// bytes each, in the header's payload before its tail.
Bytes header_with_names(const Bytes& header, uint32_t count, uint32_t bytes) {
  const size_t names_at = header.size() - kHeaderTail - (4 + 8) - (4 + 7) - 4;
  Bytes out(header.begin(), header.begin() + static_cast<std::ptrdiff_t>(names_at));
  format::ByteWriter w;
  w.write(count);
  for (uint32_t i = 0; i < count; ++i) {
    w.write(bytes);
    for (uint32_t b = 0; b < bytes; ++b) w.write(static_cast<uint8_t>('a' + (b + i) % 26));
  }
  const Bytes names = w.take();
  out.insert(out.end(), names.begin(), names.end());
  out.insert(out.end(), header.end() - kHeaderTail, header.end());
  return out;
}

// The same names as a frame laid out here (each name one byte repeated: RLE), so that 470 names of
// 1 MiB take 20 kB to write and the header announces 470 MiB.
format::PreparedChunk header_with_names_frame(const Bytes& header, uint32_t count, uint32_t bytes) {
  const size_t names_at = header.size() - kHeaderTail - (4 + 8) - (4 + 7) - 4;
  std::vector<Piece> pieces;
  format::ByteWriter w;
  w.write(count);
  w.write(bytes);
  pieces.push_back({Bytes(header.begin(), header.begin() + static_cast<std::ptrdiff_t>(names_at))});
  pieces.push_back({w.take()});
  for (uint32_t i = 0; i < count; ++i) {
    pieces.push_back({{}, bytes, static_cast<uint8_t>('a' + i % 26)});
    format::ByteWriter length;
    if (i + 1 < count) length.write(bytes);
    pieces.push_back({length.take()});
  }
  pieces.push_back({Bytes(header.end() - kHeaderTail, header.end())});
  return compressed_chunk("HEAD", pieces);
}

// ---- Sequences ----

// `count` keyframes at 1/fps apart, cycling through small_sequence(n)'s three, without textures.
Sequence long_sequence(int n, size_t count, double fps = 30) {
  const Sequence three = crafted::small_sequence(n, 16);
  Sequence s = three;
  s.fps = fps;
  s.keyframes.clear();
  for (size_t k = 0; k < count; ++k) {
    Keyframe key = three.keyframes[k % 3];
    key.time = static_cast<double>(k) / fps;
    key.texture = Image();
    s.keyframes.push_back(std::move(key));
  }
  s.first_time = 0;
  s.last_time = s.keyframes.back().time;
  return s;
}

// Fields a reconstruction is slow to settle on: each keyframe's mean curvature with a deterministic
// high-frequency pattern of its own size added (fields of no surface: every iteration moves them).
void roughen(Sequence& s) {
  uint64_t state = 0x9E3779B97F4A7C15ull;
  for (Keyframe& key : s.keyframes) {
    double scale = 0;
    for (double h : key.fields.mean_curvature) scale = std::max(scale, std::abs(h));
    for (double& h : key.fields.mean_curvature) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      h += (static_cast<double>(state >> 11) / 9007199254740992.0 - 0.5) * 4 * std::max(scale, 1.0);
    }
  }
}

SequenceFileMetadata predicted_without_texture() {
  SequenceFileMetadata m = crafted::predicted_metadata();
  m.texture_quality = 101;
  return m;
}

// A file of `count` keyframes at 1/30 s apart on `spline`, laid out here from small_sequence(n)'s
// three coded alone (intra period 1): keyframe k's KGOP is keyframe k mod 3's with k's number, every
// pose the identity. Encoding 200 keyframes at N = 257 took the writer 30 s; this takes the three.
Bytes keyframes_repeated(int n, uint32_t count, SplineKind spline) {
  Sequence s = crafted::small_sequence(n, 16);
  for (Keyframe& key : s.keyframes) key.texture = Image();
  SequenceFileMetadata m = predicted_without_texture();
  m.field_coding.intra_period = 1;
  const Bytes base = encode_sequence_file(s, m);
  const format::ContainerReader reader(base, "base");
  Bytes head = reader.payload(reader.chunks()[0]);
  std::vector<Bytes> groups;
  std::vector<std::string> group_types;  // KGOP, or KGLV where the writer chose the levels predictor (format 2.6)
  for (const format::ChunkView& c : reader.chunks()) {
    if (c.type == "KGOP" || c.type == "KGLV") {
      groups.push_back(reader.payload(c));
      group_types.push_back(c.type);
    }
  }
  const auto put = [&head](size_t at, auto value) { std::memcpy(head.data() + at, &value, sizeof value); };
  put(17, static_cast<uint8_t>(spline));
  put(20, count);
  put(40, (count - 1) / 30.0);
  const format::PreparedChunk head_chunk = format::prepare_chunk("HEAD", head, true, 19);
  std::vector<format::PreparedChunk> chunks;
  for (uint32_t k = 0; k < count; ++k) {
    Bytes payload = groups[k % groups.size()];
    std::memcpy(payload.data(), &k, sizeof k);
    chunks.push_back(format::prepare_chunk(group_types[k % groups.size()], std::move(payload), true));
  }
  format::ByteWriter index;
  index.write(count);
  for (uint32_t k = 0; k < count; ++k) index.write(k / 30.0);
  for (uint32_t v = 0; v < 6 * count; ++v) index.write(uint8_t{0});  // every pose change 0
  uint64_t at = format::kPreambleBytes + head_chunk.total_size() + format::kChunkHeaderBytes + (index.size() + 8 * count) +
                format::kChunkTrailerBytes;
  for (const format::PreparedChunk& c : chunks) {
    index.write(at);
    at += c.total_size();
  }
  format::ContainerWriter writer;
  writer.add(head_chunk);
  writer.add(format::prepare_chunk("KIDX", index.take(), true));
  for (const format::PreparedChunk& c : chunks) writer.add(c);
  return writer.finish();
}

// ---- The set ----

struct Entry {
  std::string name;
  std::vector<double> times;
  std::string what;
  std::string refused;  // what every run's error must say ("": the file may open and decode)
};

class Corpus {
 public:
  explicit Corpus(fs::path dir) : dir_(std::move(dir)) { fs::create_directories(dir_); }

  void add(const std::string& name, const Bytes& bytes, std::vector<double> times, const std::string& what,
           const std::string& refused = "") {
    format::write_file_atomically(dir_ / name, bytes);
    entries_.push_back({name, std::move(times), what, refused});
    const auto now = std::chrono::steady_clock::now();
    std::printf("%-36s %9zu bytes %5.2f s  %s\n", name.c_str(), bytes.size(), std::chrono::duration<double>(now - last_).count(),
                what.c_str());
    last_ = now;
  }

  void finish() const {
    std::ofstream out(dir_ / "manifest.tsv");
    for (const Entry& e : entries_) {
      out << e.name << '\t';
      for (size_t i = 0; i < e.times.size(); ++i) {
        char t[32];
        std::snprintf(t, sizeof t, "%.6g", e.times[i]);
        out << (i ? "," : "") << t;
      }
      out << '\t' << e.what << '\t' << e.refused << '\n';
    }
  }

 private:
  fs::path dir_;
  std::vector<Entry> entries_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

void write_set(Corpus& corpus) {
  const Sequence small = crafted::small_sequence();
  const Bytes plain = encode_sequence_file(small, crafted::small_metadata());  // 2.2, lossless WebP stills
  const Bytes predicted = encode_sequence_file(small, crafted::predicted_metadata());
  const Bytes grouped = encode_sequence_file(crafted::small_sequence(9, 16), crafted::grouped_texture_metadata());  // 2.1, TGOP
  const std::vector<double> three = {0.25, 0.5, 0.97};
  corpus.add("control_plain.fmv", plain, three, "control: a valid file (2.2, lossless WebP stills)");
  corpus.add("control_groups.fmv", grouped, three, "control: a valid file (2.1, AVIF texture groups)");

  // (a) Header strings over budget: 470 landmark names of 1 MiB (the review's 1.68 GB), 5 of 1 MiB
  // (within what a header may hold, over the strings' 4 MiB), and 3 (within: opens).
  const Bytes header = payload_of(plain, "HEAD");
  corpus.add("a_names_470x1MiB.fmv", relaid(plain, header_with_names_frame(header, 470, 1u << 20), stored_index), three,
             "470 landmark names of 1 MiB: a header stating 470 MiB", "a header holds at most");
  corpus.add("a_names_5x1MiB.fmv",
             rebuild(plain,
                     [&](const std::string& t, Bytes& p) {
                       if (t == "HEAD") p = header_with_names(p, 5, 1u << 20);
                     }),
             three, "5 landmark names of 1 MiB: strings over 4 MiB together", "at most 4 MiB together");
  corpus.add("a_names_3x1MiB.fmv",
             rebuild(plain,
                     [&](const std::string& t, Bytes& p) {
                       if (t == "HEAD") p = header_with_names(p, 3, 1u << 20);
                     }),
             three, "3 landmark names of 1 MiB: within the budget (opens)");

  // (b) 500 MB of zeros after the header's and after the index's last field, as zstd frames of RLE
  // blocks; and a later minor version's appended 64 KiB + 1.
  constexpr uint64_t k500MB = 500'000'000;
  corpus.add("b_head_500MB_zeros.fmv", relaid(plain, compressed_chunk("HEAD", {{header}, {{}, k500MB, 0}}), stored_index), three,
             "500 MB of zeros after the header's last field (zstd)", "a header holds at most");
  corpus.add("b_kidx_500MB_zeros.fmv",
             relaid(plain, std::nullopt,
                    [&](Bytes index) {
                      return compressed_chunk("KIDX", {{std::move(index)}, {{}, k500MB, 0}});
                    }),
             three, "500 MB of zeros after the index's last field (zstd)", "an index of 3 keyframes holds at most");
  corpus.add("b_head_1_byte.fmv", rebuild(plain, appending("HEAD", 1)), three, "one byte after the header's last field (format 2.2)",
             "header: 1 bytes after its last field");
  corpus.add("b_kidx_1_byte.fmv", rebuild(plain, appending("KIDX", 1)), three, "one byte after the index's last field (format 2.2)",
             "index: 1 bytes after its last field");
  {
    Bytes later = rebuild(plain, appending("HEAD", (64 << 10) + 1));
    const uint16_t minor = format::kMinorVersion + 1;
    std::memcpy(later.data() + 10, &minor, sizeof minor);
    const uint32_t crc = format::crc32(std::span<const uint8_t>(later.data(), 12));
    std::memcpy(later.data() + 12, &crc, sizeof crc);
    corpus.add("b_later_minor_64KiB_plus_1.fmv", later, three, "format 2.3 appending 64 KiB + 1 to the header",
               "a later minor version appends at most 64 KiB");
  }

  // (c), (g) A 3072² texture, near the largest the default budget admits where a frame blends three
  // keyframes (about 25 M² bytes and a sixteenth of the budget: 3840² needs 368 MiB), as a lossless
  // WebP of one colour (a few hundred bytes for 9.4 Mpixels),
  // stored as it should be, and one stored compressed (padded with 64 KiB of zeros that zstd shrinks).
  constexpr uint32_t kBigTexture = 3072;
  Image solid(kBigTexture, kBigTexture, 3);
  for (size_t i = 0; i < solid.pixels.size(); i += 3) solid.pixels[i] = 200, solid.pixels[i + 1] = 120, solid.pixels[i + 2] = 90;
  const Bytes webp = encode_webp(solid, 101);
  solid = Image();
  const auto big_texture = [&](size_t padding) {
    return [&webp, padding](const std::string& t, Bytes& p) {
      if (t == "HEAD") {
        const uint32_t m = kBigTexture;
        std::memcpy(p.data() + 72, &m, sizeof m);
      }
      if (t == "TEXR") {
        p.resize(8);
        p.insert(p.end(), webp.begin(), webp.end());
        p.insert(p.end(), padding, 0);
      }
    };
  };
  corpus.add("g_texture_3072_webp.fmv", rebuild(plain, big_texture(0)), three,
             "a 3072² texture from a " + std::to_string(webp.size()) + "-byte lossless WebP per keyframe");
  corpus.add("c_compressed_texr_3072.fmv", rebuild(plain, big_texture(64 << 10), false, false, {"TEXR"}), three,
             "a compressed TEXR holding a 3072² lossless WebP", "a texture's chunk never is");

  // (d) One group of 4096 keyframes at N = 17 (intra period = K), frames asked near its end:
  // reaching the last keyframe decodes the whole run.
  {
    const Sequence s = long_sequence(17, 4096);
    SequenceFileMetadata m = predicted_without_texture();
    m.field_coding.intra_period = static_cast<int>(s.keyframes.size());
    const double end = s.last_time;
    corpus.add("d_one_group_4096_keyframes.fmv", encode_sequence_file(s, m), {1.0, end - 0.05, end},
               "one group of 4096 keyframes at N = 17, frames near its end");
  }

  // (e) A not-a-knot spline (global support) over 200 keyframes at N = 257.
  corpus.add("e_not_a_knot_200_keyframes_n257.fmv", keyframes_repeated(257, 200, SplineKind::kNotAKnot), {3.31, 199.0 / 30 - 0.01},
             "not-a-knot spline over 200 keyframes at N = 257");

  // 400 keyframes at N = 257 (Catmull-Rom): a player's decode is bounded by max_work, fminfo's
  // check of every keyframe by nothing but the file's size.
  corpus.add("e_400_keyframes_n257.fmv", keyframes_repeated(257, 400, SplineKind::kCatmullRom), {3.31, 399.0 / 30 - 0.01},
             "400 keyframes at N = 257 (Catmull-Rom)");

  // The most keyframes the default limits admit, each its own group, at the smallest N.
  corpus.add("l_65536_keyframes_n5.fmv", keyframes_repeated(5, 65536, SplineKind::kCatmullRom), {1, 65535.0 / 30 - 0.01},
             "65536 keyframes (the default limit) at N = 5");

  // (f) N = 400, the largest grid the default memory budget of 256 MiB admits (401 needs 256.x MiB),
  // with fields of no surface (slow or never converging).
  {
    Sequence s = crafted::small_sequence(400, 16);
    for (Keyframe& key : s.keyframes) key.texture = Image();
    roughen(s);
    SequenceFileMetadata m = crafted::small_metadata();
    m.field_coding.intra_period = 1;
    corpus.add("f_n400_rough_fields.fmv", encode_sequence_file(s, m), {0.25, 0.97},
               "N = 400 (the largest the default budget admits) with rough fields");
  }

  // (h) Hole levels ±inf and ±1.5e308: the hole level's step scaled so that its codes decode to them.
  corpus.add("h_hole_level_1.5e308.fmv", rebuild(predicted, with_step(13, 1.5e308)), three, "hole levels ±1.5e308 and ±inf (step 1.5e308)",
             "hole level");
  corpus.add("h_hole_level_inf.fmv", rebuild(predicted, with_step(13, std::numeric_limits<double>::max())), three,
             "hole levels ±inf (step DBL_MAX)", "hole level");
  corpus.add("h_hole_level_17.fmv", rebuild(predicted, with_step(13, 1e3)), three, "hole levels beyond 16 (step 1e3)", "hole level");

  // (i) One byte after a KGOP's stream, in a 2.2 file and in a 2.1 file of texture groups.
  corpus.add("i_kgop_extra_byte.fmv", rebuild(predicted, appending("KGOP", 1, 0x5A)), three, "one byte after each KGOP stream (2.2)",
             "1 bytes after the range-coded stream's last value");
  corpus.add("i_kgop_extra_byte_groups.fmv", rebuild(grouped, appending("KGOP", 1, 0x5A)), three,
             "one byte after each KGOP stream (2.1, TGOP)", "1 bytes after the range-coded stream's last value");

  // (j) Settings nested 524,288 levels deep: 1 MiB of brackets, the most a string holds.
  {
    SequenceFileMetadata m = crafted::small_metadata();
    m.settings = std::string(1u << 19, '[') + std::string(1u << 19, ']');
    corpus.add("j_settings_nested_524288.fmv", encode_sequence_file(small, m), three, "settings nested 524,288 levels deep (1 MiB)");
    m.settings = std::string((1u << 20) - 1, '{');
    corpus.add("j_settings_1MiB_open_braces.fmv", encode_sequence_file(small, m), three, "settings of 1 MiB of '{' (not JSON)");
  }

  // More: truncations, claims over the limits, times and poses at their bounds.
  corpus.add("k_truncated_half.fmv", Bytes(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(plain.size() / 2)), three,
             "the file cut in half", "truncated");
  {
    const format::ContainerReader reader(plain, "plain");
    const uint64_t end_chunk = reader.chunks().back().offset + reader.chunks().back().total_size();
    corpus.add("k_truncated_at_end_chunk.fmv", Bytes(plain.begin(), plain.begin() + static_cast<std::ptrdiff_t>(end_chunk)), three,
               "the file cut at a chunk boundary (no end chunk)", "without its end chunk");
  }
  corpus.add("k_keyframes_1M.fmv", rebuild(plain, patch<uint32_t>("HEAD", 20, 1u << 20)), three, "a header claiming 2^20 keyframes",
             "max_keyframes");
  corpus.add("k_texture_16384.fmv", rebuild(plain, patch<uint32_t>("HEAD", 72, 16384)), three, "a header claiming a 16384² texture",
             "max_texture_size");
  corpus.add("k_grid_4097.fmv", rebuild(plain, patch<uint32_t>("HEAD", 0, 4097)), three, "a header claiming N = 4097", "max_grid_n");
  corpus.add("k_grid_1025.fmv", rebuild(plain, patch<uint32_t>("HEAD", 0, 1025)), three, "a header claiming N = 1025", "rim nodes");
  // Keyframe times 0, 1e-200, 1 (closer than 1e-9 of the span) and 0, 2, 1e9 (a gap of 31 years).
  corpus.add("k_times_1e-200.fmv", rebuild(plain, patch<double>("KIDX", 4 + 8, 1e-200)), three, "keyframe times 0, 1e-200, 1",
             "1e-9 of the keyframes' span");
  const auto times_0_2_1e9 = [](const std::string& t, Bytes& p) {
    patch<double>("KIDX", 4 + 8, 2)(t, p);
    patch<double>("KIDX", 4 + 16, 1e9)(t, p);
    patch<double>("HEAD", 40, 1e9)(t, p);
  };
  corpus.add("k_time_gap_1e9.fmv", rebuild(plain, times_0_2_1e9), {1, 5e8, 1e9 - 0.01}, "keyframe times 0, 2, 1e9 s");
  // Keyframe 2 translated to within a step of the bound, 1e9 of the file's units.
  {
    double step = 0;
    const Bytes head = payload_of(predicted, "HEAD");
    std::memcpy(&step, head.data() + head.size() - 8, sizeof step);
    const auto far = [step](const std::string& t, Bytes& p) {
      if (t == "KIDX") p = crafted::with_pose_change(p, 3, 2, std::llround((1e9 - 10) / step) - std::llround(2 / step));
    };
    corpus.add("k_translation_1e9.fmv", rebuild(predicted, far), three, "keyframe 2 translated to 1e9 mm");
  }
  corpus.add("k_spline_7.fmv", rebuild(plain, patch<uint8_t>("HEAD", 17, 7)), three, "an unknown spline kind", "spline kind 7");
  // Frame patches (format 2.4, spec/container.md §7.5), in files stamped 2.4 (the writer writes 2.5's
  // coding; a rebuilt file is stamped with the writer's version, so the stamp comes after): a count
  // its bytes cannot hold, and one patch moving every node of the largest lattice (129²) by 2^40
  // steps of 2^-20 (10^6 units) at 0.25 s.
  Sequence patched = small;
  patched.patches = {{0.25, 3, {4}, {Vec3(0.0625, 0, 0)}}};
  const Bytes with_patch = encode_sequence_file(patched, crafted::small_metadata());
  corpus.add("m_patch_count_2e24.fmv",
             crafted::with_minor_version(rebuild(with_patch,
                                                 [](const std::string& t, Bytes& p) {
                                                   if (t == "PTCH") p = {0, 0, 0, 1, 0, 0xC0, 0x07, 6, 0};
                                                 }),
                                         4),
             three, "a PTCH claiming 2^24 frame patches in 9 bytes (format 2.4)", "frame patches");
  corpus.add("m_patch_129x129_largest.fmv",
             crafted::with_minor_version(rebuild(with_patch,
                                                 [](const std::string& t, Bytes& p) {
                                                   if (t != "PTCH") return;
                                                   format::ByteWriter w;
                                                   w.write(uint32_t{1});
                                                   w.write(int8_t{-20});
                                                   file_layout::write_varint(w, 480);  // 0.25 s in 64ths of a frame period at 30 fps
                                                   file_layout::write_varint(w, 129);
                                                   file_layout::write_varint(w, 129 * 129);
                                                   for (int n = 0; n < 129 * 129; ++n) {
                                                     file_layout::write_varint(w, 0);
                                                     for (int c = 0; c < 3; ++c) file_layout::write_varint(w, int64_t{1} << 40);
                                                   }
                                                   p = w.take();
                                                 }),
                                         4),
             three, "a PTCH moving all 129² lattice nodes by 10^6 units (format 2.4)");
  // Format 2.5's range-coded PTCH (§7.5.1): 2^24 patches stated for a 5-byte stream; every node of
  // the largest lattice moved by 2^34 steps of 2^-20 (16384 units), the most a valid stream holds;
  // and 64 KiB of noise stated to hold 4 patches a byte (their 16 MB within the budget), which the
  // decoder reads until the noise breaks a check: its time is bounded by the bytes.
  corpus.add("m_patch_ranged_count_2e24.fmv",
             rebuild(with_patch,
                     [](const std::string& t, Bytes& p) {
                       if (t == "PTCH") p = {0x80, 0x80, 0x80, 0x10, 0, 10, 0, 0, 0, 0, 0};
                     }),
             three, "a range-coded PTCH claiming 2^24 frame patches in 5 bytes (format 2.5)", "frame patches");
  const auto ranged = [](int64_t count, const Bytes& stream) {
    return [count, stream](const std::string& t, Bytes& p) {
      if (t != "PTCH") return;
      format::ByteWriter w;
      file_layout::write_varint(w, count);
      w.write(int8_t{-20});
      file_layout::write_varint(w, static_cast<int64_t>(stream.size()));
      w.bytes(stream);
      p = w.take();
    };
  };
  {
    format::PatchStreamWriter w;
    format::CodedPatch all{480, 129, {}, {}};
    for (int32_t n = 0; n < 129 * 129; ++n) {
      all.nodes.push_back(n);
      all.codes.push_back({int64_t{1} << 34, -(int64_t{1} << 34), int64_t{1} << 34});
    }
    w.add(all);
    corpus.add("m_patch_ranged_129x129_largest.fmv", rebuild(with_patch, ranged(1, w.finish())), three,
               "a range-coded PTCH moving all 129² lattice nodes by 16384 units (format 2.5)");
  }
  {
    Bytes noise(64 << 10);
    uint64_t state = 0x9E3779B97F4A7C15ull;
    for (uint8_t& b : noise) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      b = static_cast<uint8_t>(state >> 56);
    }
    noise[0] = 0;  // a range-coded stream's first byte
    corpus.add("m_patch_ranged_noise_64k.fmv", rebuild(with_patch, ranged(4 * static_cast<int64_t>(noise.size()), noise)), three,
               "64 KiB of noise as a range-coded PTCH stream of 4 patches a byte (format 2.5)", "frame patches");
  }
  // The range-coded PTCH at the edges of its guards, in a capture whose two intervals hold 4.2
  // million frames (keyframes at 0, 70,000 and 140,000 s at 30 fps) so that a valid file can hold
  // millions of patches: 2.9 million patches with no moving node a frame apart (9 decisions each,
  // about 72 a byte: the count's guard, §7.5.1; 186 MB); 2^24 stated for a stream that could hold
  // them (refused before anything is allocated); the most memory a byte of stream can
  // ask for, 129² moving nodes a patch with codes 0 (4 decisions a node), 400 patches (186 MB); and
  // the lattice changing between 128 and 129 at every patch, times off the frame lattice, every
  // node moving. (Sizes within the bound of tests/tools/hostile_files_test.sh, 256 MB of resident
  // memory, which fminfo's own 61 MB and a file filling the default budget of 256 MiB would pass:
  // 3.9 million patches, 250 MB, peak at 294 MB in fminfo, 248 MB in fmdec.)
  {
    Sequence longer = patched;
    for (size_t k = 0; k < longer.keyframes.size(); ++k) longer.keyframes[k].time = 70000.0 * static_cast<double>(k);
    longer.last_time = 140000;
    const Bytes with_long = encode_sequence_file(longer, crafted::small_metadata());
    const std::vector<double> far = {0.25, 70000.5, 139999.9};
    const auto stream_of = [](int64_t count, const std::function<format::CodedPatch(int64_t)>& patch) {
      format::PatchStreamWriter w;
      for (int64_t p = 0; p < count; ++p) w.add(patch(p));
      return w.finish();
    };
    const int64_t empties = 2'900'000;
    const Bytes empty_stream = stream_of(empties, [](int64_t p) { return format::CodedPatch{p == 2'099'999 ? 128 : 64, 3, {}, {}}; });
    corpus.add("m_patch_ranged_2_9M_empty.fmv", rebuild(with_long, ranged(empties, empty_stream)), far,
               "2.9 million empty range-coded patches a frame apart in " + std::to_string(empty_stream.size()) + " bytes (format 2.5)");
    const int64_t too_many = int64_t{1} << 24;  // 1 GiB natively, 640 MiB in WebAssembly's 32 bits
    corpus.add("m_patch_ranged_2e24_stated.fmv", rebuild(with_long, ranged(too_many, Bytes(too_many / 72 + 1, 0))), far,
               "2^24 range-coded patches stated for a stream of 233,017 bytes that could hold them (format 2.5)",
               "16777216 frame patches need");
    const auto dense = [](int64_t) {
      format::CodedPatch all{64, 129, {}, {}};
      for (int32_t n = 0; n < 129 * 129; ++n) {
        all.nodes.push_back(n);
        all.codes.push_back({0, 0, 0});
      }
      return all;
    };
    corpus.add("m_patch_ranged_dense_400.fmv", rebuild(with_long, ranged(400, stream_of(400, dense))), far,
               "400 range-coded patches moving all 129² nodes by 0: 186 MB of nodes (format 2.5)");
    const auto alternating = [](int64_t p) {
      const int32_t c = p % 2 ? 129 : 128;
      format::CodedPatch all{65, c, {}, {}};
      for (int32_t n = 0; n < c * c; ++n) {
        all.nodes.push_back(n);
        all.codes.push_back({n % 7 - 3, (n * 13) % 5 - 2, p % 3 - 1});
      }
      return all;
    };
    corpus.add("m_patch_ranged_lattice_every_patch.fmv", rebuild(with_long, ranged(200, stream_of(200, alternating))), far,
               "200 range-coded patches at 65/64 of a frame apart, lattice 128 and 129 in turn, every node moving (format 2.5)");
  }
  // Format 2.5's linear predictor along a sequence (spec/container.md §7.2), the first group written
  // by hand: the band's and the rim's x at the widest swing a valid file holds (residuals near 2^33),
  // residuals that lead the rim's prediction past 32 bits, id 2 on the rim in a file stamped 2.4,
  // and id 3 on the rim.
  constexpr size_t kBandX = 4, kRimX = 10;
  corpus.add("n_linear_widest_swing.fmv",
             crafted::with_first_group_by_hand(predicted, true,
                                               [](crafted::HandCodedKeyframe& key) {
                                                 for (size_t a : {kBandX, kRimX}) crafted::linear_swing(key, a);
                                               }),
             three, "linear along the band and the rim, codes zigzag ±(2^30-1), d ±(2^31-2) (format 2.5)");
  const auto rim_by_hand = [&](uint8_t id, std::vector<int64_t> first) {
    return crafted::with_first_group_by_hand(predicted, false, [&](crafted::HandCodedKeyframe& key) {
      key.ids[kRimX] = id;
      if (key.k == 0) std::copy(first.begin(), first.end(), key.residuals[kRimX].begin());
    });
  };
  const int64_t top = std::numeric_limits<int32_t>::max();
  corpus.add("n_linear_rim_past_32_bits.fmv", rim_by_hand(2, {top, -2 * top - 1, -(int64_t{1} << 34)}), three,
             "linear rim residuals 2^31-1, -2^32+1, -2^34: a prediction -3 x 2^31 + 1 and d near -2^34.6 (format 2.5)",
             "outside 32 bits");
  corpus.add("n_linear_rim_in_2_4.fmv", crafted::restamped(rim_by_hand(2, {}), 4), three, "predictor 2 on the rim in a file stamped 2.4",
             "array 10 has predictor 2");
  corpus.add("n_predictor_3_on_rim.fmv", rim_by_hand(3, {}), three, "predictor 3 on the rim (format 2.5)", "array 10 has predictor 3");
  // Format 2.6's levels predictor (spec/container.md §7.2) on H, in a KGLV chunk written by hand: codes
  // zigzagging between ±(2^30 - 1) from node to node (valid: decodes exactly), residuals 2^31 - 1
  // then 2^34 that lead the second coarse node's code past 32 bits through its prediction, and a
  // valid KGLV group in a file stamped 2.5.
  const std::shared_ptr<const file_layout::GridFacts> small_grid = file_layout::grid_facts(small.grid_n);
  const auto levels_by_hand = [&](const std::function<void(std::vector<int64_t>&)>& residuals) {
    return crafted::with_first_group_by_hand(
        predicted, false,
        [&](crafted::HandCodedKeyframe& key) {
          key.ids[0] = 3;
          key.levels[0] = 1;
          residuals(key.residuals[0]);
        },
        true);
  };
  corpus.add("n_levels_widest_swing.fmv", levels_by_hand([&](std::vector<int64_t>& r) {
               std::vector<int32_t> codes(r.size());
               for (size_t e = 0; e < codes.size(); ++e) codes[e] = e % 2 ? (1 << 30) - 1 : 1 - (1 << 30);
               r = format::level_residuals(codes, small_grid->interior_levels);
             }),
             three, "levels predictor on H, codes zigzag ±(2^30-1) from node to node (format 2.6)");
  corpus.add("n_levels_past_32_bits.fmv", levels_by_hand([&](std::vector<int64_t>& r) {
               std::fill(r.begin(), r.end(), int64_t{1} << 34);
               r[0] = top;
             }),
             three, "levels predictor on H, residuals 2^31-1 then 2^34: the second coarse node past 32 bits (format 2.6)",
             "outside 32 bits (levels predictor");
  corpus.add("n_levels_in_2_5.fmv", crafted::restamped(levels_by_hand([](std::vector<int64_t>&) {}), 5), three,
             "a KGLV group (the levels predictor on H) in a file stamped 2.5", "the levels predictor's group chunk is 2.6's");
  corpus.add("k_intra_period_0.fmv",
             rebuild(predicted,
                     [](const std::string& t, Bytes& p) {
                       if (t == "HEAD") std::memset(p.data() + p.size() - kHeaderTail, 0, 4);
                     }),
             three, "intra period 0", "intra period 0");
}

}  // namespace
}  // namespace facemorph

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hostile_corpus OUT_DIR\n");
    return 2;
  }
  try {
    const auto start = std::chrono::steady_clock::now();
    facemorph::Corpus corpus(argv[1]);
    facemorph::write_set(corpus);
    corpus.finish();
    std::printf("hostile_corpus: %s in %.1f s\n", argv[1], std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hostile_corpus: %s\n", e.what());
    return 1;
  }
  return 0;
}
