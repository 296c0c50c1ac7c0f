// Crafted .fmv files for tests: a small sequence with everything a file can hold, its metadata,
// and a rebuild that edits a file's payloads (decompressed) and keeps every checksum and index
// offset right, so that a test reaches the check it means, past the CRCs.
#pragma once

#include "codec/core/container/keyframe_group_coding.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/chunk_writers.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace facemorph::crafted {

// A small sequence with everything a file can hold: hl+t fields of three surfaces, a turning pose,
// a hole that grows, a texture.
inline Sequence small_sequence(int n = 17, int texture = 16) {
  const GridGeometry geometry(make_disk_grid(n));
  Sequence s;
  s.grid_n = n;
  s.fps = 30;
  s.first_time = 0;
  s.last_time = 1;
  s.units = "mm";
  s.pose_centre = Vec3(0.1, 0.2, 0.3);
  for (int k = 0; k < 3; ++k) {
    Keyframe key;
    key.time = 0.5 * k;
    const double a = 0.2 + 0.1 * k;
    std::vector<Vec3> positions;
    for (const Vec2& w : geometry.grid().nodes) positions.push_back(Vec3(w.x(), w.y(), a * (w.x() * w.x() - 0.5 * w.y() * w.y())));
    key.fields = compute_fields(geometry, positions, Representation::kHLT);
    key.pose.rotation = Eigen::AngleAxisd(0.2 * k, Vec3(0, 1, 0)).toRotationMatrix();
    key.pose.translation = Vec3(k, 0.1234567 * k, -k);
    for (const Vec2& w : geometry.grid().nodes) key.hole_level.push_back(std::min((w - Vec2(0.3, 0)).norm() - 0.1 * k, kHoleLevelBand));
    key.texture = Image(texture, texture, 3);
    for (int y = 0; y < texture; ++y) {
      for (int x = 0; x < texture; ++x) {
        uint8_t* p = key.texture.at(x, y);
        p[0] = static_cast<uint8_t>(8 * x + 20 * k);
        p[1] = static_cast<uint8_t>(8 * y);
        p[2] = 128;
      }
    }
    s.keyframes.push_back(std::move(key));
  }
  return s;
}

inline SequenceFileMetadata small_metadata() {
  SequenceFileMetadata m;
  m.settings = R"({"keyframes":"10%"})";
  m.landmark_names = {"nose_tip", "rim_top"};
  m.texture_quality = 101;  // lossless: the round trip compares exactly
  return m;
}

// Lossy AVIF textures at quality 80, one AV1 image sequence per group of two keyframes (TGOP,
// format 2.1), with predicted_metadata's steps.
inline SequenceFileMetadata grouped_texture_metadata();

// The same with steps of the caller's choosing: every array on its own step, a group of keyframes
// every second one.
inline SequenceFileMetadata predicted_metadata() {
  SequenceFileMetadata m = small_metadata();
  m.field_coding.steps.assign(kKeyframeArrayCount, 1e-4);
  m.field_coding.steps[kScalarArrayCount] = 1e-3;
  m.field_coding.intra_period = 2;
  set_default_pose_steps(m.field_coding, "mm");
  return m;
}

inline SequenceFileMetadata grouped_texture_metadata() {
  SequenceFileMetadata m = predicted_metadata();
  m.texture_codec = TextureCodec::kAvif;
  m.texture_coding = TextureCoding::kSequence;
  m.texture_quality = 80;
  return m;
}

// An index payload (spec/container.md §6) with pose component `component`'s change at keyframe `k`
// (from keyframe k - 1's, or from 0) moved by `change`, written as the varint it then is (one
// longer than 6 bytes if it must).
inline std::vector<uint8_t> with_pose_change(const std::vector<uint8_t>& index, size_t component, size_t k, int64_t change) {
  format::ByteReader r(index, "index");
  format::ByteWriter w;
  const uint32_t count = r.read<uint32_t>("count");
  w.write(count);
  for (uint32_t i = 0; i < count; ++i) w.write(r.read<double>("t"));
  for (size_t c = 0; c < 6; ++c) {
    for (uint32_t i = 0; i < count; ++i) {
      uint64_t zigzag = 0;
      int shift = 0;
      uint8_t byte = 0;
      do {
        byte = r.read<uint8_t>("pose");
        zigzag |= static_cast<uint64_t>(byte & 0x7F) << shift;
        shift += 7;
      } while ((byte & 0x80) != 0);
      int64_t value = (zigzag & 1) != 0 ? -static_cast<int64_t>(zigzag >> 1) - 1 : static_cast<int64_t>(zigzag >> 1);
      if (c == component && i == k) value += change;
      zigzag = value >= 0 ? static_cast<uint64_t>(value) << 1 : (static_cast<uint64_t>(-(value + 1)) << 1) | 1;
      while (zigzag >= 0x80) {
        w.write(static_cast<uint8_t>(zigzag | 0x80));
        zigzag >>= 7;
      }
      w.write(static_cast<uint8_t>(zigzag));
    }
  }
  w.bytes(r.bytes(r.remaining(), "offsets"));
  return w.take();
}

// Rebuilds a file chunk by chunk, letting `edit(type, payload)` change a payload (decompressed) or
// a chunk's type (an `edit` taking `std::string&`), and keeps the index's offsets right: each offset that named a chunk names it where it
// now starts (chunks before it may have grown), the index itself included (compressed, its size moves with its numbers). Times and other
// index fields are taken from the index as `edit` left it.
template <typename Edit>
// `compress`: chunk types stored compressed (where zstd makes them smaller) even if they were not.
// `alter_header`: changes the header's chunk as it will be written (its flags, sizes, stored bytes);
// `alter_each` every other chunk's (not the index's, which is made again with the offsets).
std::vector<uint8_t> rebuild(const std::vector<uint8_t>& bytes, Edit&& edit, bool extra_unknown = false, bool extra_critical = false,
                             const std::vector<std::string>& compress = {},
                             const std::function<void(format::PreparedChunk&)>& alter_header = {},
                             const std::function<void(format::PreparedChunk&)>& alter_each = {}) {
  const format::ContainerReader reader(bytes, "in");
  std::vector<format::PreparedChunk> chunks;
  size_t groups = 0;          // KGOP chunks
  size_t texture_groups = 0;  // TGOP chunks (format 2.1: the index has one texture offset per group)
  bool textured = false;      // TEXR chunks (one texture offset per keyframe)
  std::vector<uint8_t> index_payload;
  for (const format::ChunkView& c : reader.chunks()) {
    std::vector<uint8_t> payload = reader.payload(c);
    std::string type = c.type;
    edit(type, payload);
    // The index's layout is the file's as written: by the chunks' types before the edit.
    groups += c.type == "KGOP" || c.type == "KGLV" ? 1 : 0;
    texture_groups += c.type == "TGOP" ? 1 : 0;
    textured = textured || c.type == "TEXR";
    if (c.type == "KIDX") index_payload = payload;
    const bool compressed = c.compressed() || std::find(compress.begin(), compress.end(), type) != compress.end();
    chunks.push_back(format::prepare_chunk(type, std::move(payload), c.critical(), compressed ? 19 : 0,
                                           c.against_dictionary() ? format::Dictionary::kHeader : format::Dictionary::kNone));
  }
  if (alter_each) {
    for (format::PreparedChunk& c : chunks) alter_each(c);
  }
  if (alter_header) alter_header(chunks[0]);
  std::vector<format::PreparedChunk> extra;
  if (extra_unknown) extra.push_back(format::prepare_chunk("ZZZ1", {1, 2, 3}, extra_critical));
  const std::vector<format::ChunkView>& old = reader.chunks();
  const format::ChunkView& old_index = old[1];
  const int64_t header_delta = static_cast<int64_t>(chunks[0].total_size()) - static_cast<int64_t>(old[0].total_size());
  const int64_t extra_delta = extra.empty() ? 0 : static_cast<int64_t>(extra[0].total_size());
  // The index with its offsets for an index of `size` bytes, at zstd `level` (0: stored).
  const auto index_chunk = [&](uint64_t size, int level) {
    // Where each chunk after the index starts now.
    std::vector<std::pair<uint64_t, uint64_t>> moved;
    uint64_t at = format::kPreambleBytes + chunks[0].total_size() + size + static_cast<uint64_t>(extra_delta);
    for (size_t i = 2; i < chunks.size(); ++i) {
      moved.emplace_back(old[i].offset, at);
      at += chunks[i].total_size();
    }
    const int64_t delta = header_delta + extra_delta + (static_cast<int64_t>(size) - static_cast<int64_t>(old_index.total_size()));
    format::ByteReader index(index_payload, "index");
    format::ByteWriter shifted;
    const auto shift = [&] {
      const uint64_t offset = index.read<uint64_t>("o");
      uint64_t now = offset == 0 ? 0 : static_cast<uint64_t>(static_cast<int64_t>(offset) + delta);
      for (const auto& [before, after] : moved) {
        if (before == offset) now = after;
      }
      shifted.write(now);
    };
    const uint32_t count = index.read<uint32_t>("count");
    shifted.write(count);
    // Times, the pose's six runs of varints (copied as they are), group offsets, texture offsets
    // (one per keyframe, or one per group with texture groups; spec/container.md §6).
    for (uint32_t k = 0; k < count; ++k) shifted.write(index.read<double>("t"));
    for (uint32_t v = 0; v < 6 * count; ++v) {
      uint8_t byte = 0;
      do {
        byte = index.read<uint8_t>("pose");
        shifted.write(byte);
      } while ((byte & 0x80) != 0);
    }
    for (size_t g = 0; g < groups; ++g) shift();
    for (uint32_t k = 0; textured && k < count; ++k) shift();
    for (size_t g = 0; g < texture_groups; ++g) shift();
    shifted.bytes(index.bytes(index.remaining(), "appended runs"));  // what a later minor version appends, or a crafted extra
    return format::prepare_chunk(chunks[1].type, shifted.take(), true, level);
  };
  // Compressed, its size moves with its numbers: laid out until it stays put, else stored (a size
  // the offsets do not change), as the writer does.
  uint64_t index_size = old_index.total_size();
  bool placed = false;
  for (int pass = 0; pass < 8 && !placed; ++pass) {
    chunks[1] = index_chunk(index_size, old_index.compressed() ? 19 : 0);
    placed = chunks[1].total_size() == index_size;
    index_size = chunks[1].total_size();
  }
  if (!placed) chunks[1] = index_chunk(index_chunk(index_size, 0).total_size(), 0);
  format::ContainerWriter writer;
  writer.add(chunks[0]);
  writer.add(chunks[1]);
  for (const auto& c : extra) writer.add(c);
  for (size_t i = 2; i < chunks.size(); ++i) writer.add(chunks[i]);
  return writer.finish();
}

// `bytes` with the payload of its chunk of type `type` (decompressed) edited by `change`: every
// other chunk as it was (rebuild).
inline std::vector<uint8_t> with_chunk_payload(const std::vector<uint8_t>& bytes, const std::string& type,
                                               const std::function<void(std::vector<uint8_t>&)>& change) {
  return rebuild(bytes, [&](const std::string& chunk, std::vector<uint8_t>& payload) {
    if (chunk == type) change(payload);
  });
}

// The payload (decompressed) of the first chunk of type `type` in `bytes`; none: empty.
inline std::vector<uint8_t> chunk_payload(const std::vector<uint8_t>& bytes, const std::string& type) {
  std::optional<std::vector<uint8_t>> found;
  rebuild(bytes, [&](const std::string& chunk, std::vector<uint8_t>& payload) {
    if (chunk == type && !found) found = payload;
  });
  return found.value_or(std::vector<uint8_t>{});
}

// The smallest memory budget (in 16 KiB steps) under which `bytes` opens on demand: the cache then
// keeps the fewest keyframes a frame needs (spec/container.md §10.1).
inline uint64_t smallest_budget(const std::vector<uint8_t>& bytes) {
  for (uint64_t budget = 16 << 10;; budget += 16 << 10) {
    try {
      DecoderLimits limits;
      limits.max_memory_bytes = budget;
      open_sequence_source(bytes, "smallest", limits);
      return budget;
    } catch (const Error& e) {
      if (e.code() != ErrorCode::kLimit) throw;
    }
  }
}

// The file with its header compressed without the header dictionary (spec/container.md §3.4), as a
// writer before 2.5 compressed it; every other byte as it is.
inline std::vector<uint8_t> with_plain_header(std::vector<uint8_t> bytes) {
  const std::vector<uint8_t> header = chunk_payload(bytes, "HEAD");
  return rebuild(bytes, [](const std::string&, std::vector<uint8_t>&) {}, false, false, {}, [&](format::PreparedChunk& c) {
    if ((c.flags & format::kChunkDictionary) != 0) c = format::prepare_chunk("HEAD", header, true, 19);
  });
}

// The file with its preamble's minor version set to `minor` (and the preamble's CRC made again):
// its groups of keyframes as they are, whatever that version allows in them. Below 2.5 its header is
// compressed without the dictionary, which a file of that version cannot use, so that what the file
// breaks is in its groups.
inline std::vector<uint8_t> restamped(std::vector<uint8_t> bytes, uint16_t minor) {
  if (minor < format::kDictionaryMinorVersion) bytes = with_plain_header(std::move(bytes));
  std::memcpy(bytes.data() + 10, &minor, sizeof minor);
  const uint32_t crc = format::crc32(std::span<const uint8_t>(bytes.data(), 12));
  std::memcpy(bytes.data() + 12, &crc, sizeof crc);
  return bytes;
}

// The file with its preamble's minor version set to `minor` (and the preamble's CRC made again).
// Below 2.6 its groups of keyframes are coded again without 2.6's levels predictor (KGLV chunks
// become KGOP), below 2.5 also without 2.5's linear predictor along a sequence (spec/container.md
// §7.2), the same codes, and below 2.5 its header without the header dictionary (§3.4), as a writer
// of that version would have written them; every other byte is left as it is.
inline std::vector<uint8_t> with_minor_version(std::vector<uint8_t> bytes, uint16_t minor) {
  if (minor < file_layout::kLevelsMinorVersion) {
    // The keyframes as the file holds them; its patches skipped (a chunk type no decoder knows, not
    // critical), as a test may have put an older version's PTCH coding in already.
    const std::vector<uint8_t> keyframes_only = rebuild(bytes, [](std::string& type, std::vector<uint8_t>&) {
      if (type == "PTCH") type = "ZPTC";
    });
    SequenceFileInfo info;
    const Sequence s = decode_sequence_file(keyframes_only, "older.fmv", &info);
    const FieldCoding& coding = info.metadata.field_coding;
    const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(s.grid_n);
    bytes = rebuild(bytes, [&](std::string& type, std::vector<uint8_t>& payload) {
      if (type != "KGOP" && type != "KGLV") return;
      format::ByteReader r(payload, type);
      const uint32_t first = r.read<uint32_t>("first");
      file_layout::KeyframeGroupWriter group(first, coding, *grid, minor);
      const size_t end = std::min(s.keyframes.size(), first + static_cast<size_t>(coding.intra_period));
      for (size_t k = first; k < end; ++k) group.add(s.keyframes[k]);
      payload = group.finish();
      type = std::string(group.chunk_type());
    });
  }
  return restamped(std::move(bytes), minor);
}

// A keyframe's residuals as a crafted group writes them: `codes`, under predictor 0, the integer
// codes of its arrays (or their change since the previous keyframe's, where it is coded from it);
// an edit may change any array's residuals and its predictor id in `ids`, and in a KGLV group
// (format 2.6) set `levels[a]` on an interior array of id 3: the levels decision, 1, follows the id
// and its residuals are in the levels predictor's coding order.
struct HandCodedKeyframe {
  size_t k = 0;
  bool from_previous = false;
  std::vector<uint8_t> ids;
  std::vector<std::vector<int64_t>> residuals;
  std::vector<uint8_t> levels = std::vector<uint8_t>(file_layout::kKeyframeArrays, 0);
};

// The file with its first group of keyframes (0 … the intra period − 1) written again by hand
// (spec/container.md §7): keyframe j > 0 coded from the previous one where `from_previous`, every
// array under predictor 0 with its codes (or their change) as residuals, then `edit` applied to each
// keyframe's before it is written. Reaches §7.2's checks with any predictor id and any residuals
// past every CRC; the file's bytes besides that group are as they were.
template <typename Edit>
// `decision_everywhere`: the levels decision after id 3 on every array, those where the format has none too (a hostile file).
std::vector<uint8_t> with_first_group_by_hand(const std::vector<uint8_t>& bytes, bool from_previous, Edit&& edit, bool levels_chunk = false,
                                              bool decision_everywhere = false) {
  SequenceFileInfo info;
  const Sequence s = decode_sequence_file(bytes, "crafted.fmv", &info);
  const FieldCoding& coding = info.metadata.field_coding;
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(s.grid_n);
  const auto codes_of = [&](const Keyframe& key) {
    const std::vector<std::vector<double>> arrays = file_layout::keyframe_arrays(key);
    std::vector<std::vector<int64_t>> codes(arrays.size());
    for (size_t a = 0; a < arrays.size(); ++a) {
      for (double v : arrays[a]) codes[a].push_back(std::llround(v / coding.steps[a]));
    }
    return codes;
  };
  return rebuild(bytes, [&](std::string& type, std::vector<uint8_t>& payload) {
    if (type != "KGOP" && type != "KGLV") return;
    format::ByteReader r(payload, type);
    if (r.read<uint32_t>("first") != 0) return;
    type = levels_chunk ? "KGLV" : "KGOP";
    format::RangedStreamWriter stream;
    file_layout::GroupModels models;
    const size_t count = std::min(s.keyframes.size(), static_cast<size_t>(coding.intra_period));
    for (size_t k = 0; k < count; ++k) {
      HandCodedKeyframe key{k, from_previous && k > 0, std::vector<uint8_t>(file_layout::kKeyframeArrays, 0), codes_of(s.keyframes[k])};
      if (key.from_previous) {
        const std::vector<std::vector<int64_t>> before = codes_of(s.keyframes[k - 1]);
        for (size_t a = 0; a < key.residuals.size(); ++a) {
          for (size_t i = 0; i < key.residuals[a].size(); ++i) key.residuals[a][i] -= before[a][i];
        }
      }
      edit(key);
      if (k > 0) stream.decision(models.reference, key.from_previous);
      for (size_t a = 0; a < file_layout::kKeyframeArrays; ++a) {
        if (key.residuals[a].empty()) continue;
        stream.decision(models.predictor[a][0], (key.ids[a] >> 1) != 0);
        stream.decision(models.predictor[a][1 + (key.ids[a] >> 1)], (key.ids[a] & 1) != 0);
        if (levels_chunk && key.ids[a] == 3 &&
            (decision_everywhere || file_layout::levels_allowed(file_layout::lattice_of(a, key.residuals[a].size(), *grid), *grid)))
          stream.decision(models.levels[a], key.levels[a] != 0);
      }
      std::vector<const format::LatticeNeighbours*> lattices = file_layout::lattices_of(file_layout::lengths_of(key.residuals), *grid);
      for (size_t a = 0; a < lattices.size(); ++a) {
        if (key.levels[a]) lattices[a] = &grid->interior_levels.context;
      }
      stream.residual_arrays(key.residuals, lattices, file_layout::kRangeModelSets, models.residuals);
    }
    format::ByteWriter w;
    w.write(uint32_t{0});
    w.bytes(stream.finish());
    payload = w.take();
  });
}

// An edit for with_first_group_by_hand with keyframe 1 from keyframe 0: array `a` (a sequence: the
// band or the rim) under linear (id 2, format 2.5), its codes zigzag between ±(2^30 − 1), the code
// bound, in keyframe 0 and the other way round in keyframe 1. The change d then alternates
// ±(2^31 − 2), its linear prediction reaches 3 (2^31 − 2) and the residuals 4 (2^31 − 2), near
// §7.3's 2^34: the widest arithmetic a valid file asks of §7.2. Returns the codes keyframe `key.k`
// must decode to.
inline std::vector<int32_t> linear_swing(HandCodedKeyframe& key, size_t a) {
  const auto zigzag = [&](int32_t sign) {
    std::vector<int32_t> codes(key.residuals[a].size());
    for (size_t i = 0; i < codes.size(); ++i) codes[i] = (i % 2 == 0 ? sign : -sign) * static_cast<int32_t>(file_layout::kMaxFieldCode - 1);
    return codes;
  };
  const std::vector<int32_t> first = zigzag(-1), codes = key.k == 0 ? first : zigzag(1);
  std::vector<int32_t> d = codes;
  if (key.from_previous) {
    for (size_t i = 0; i < d.size(); ++i) d[i] = codes[i] - first[i];
  }
  key.ids[a] = 2;
  key.residuals[a] = format::spatial_residuals(d, format::SpatialPredictor::kLinear, nullptr);
  return codes;
}

}  // namespace facemorph::crafted
