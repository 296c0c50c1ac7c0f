// The keyframe index, KIDX (spec/container.md §6): every keyframe's time and pose, and where its
// chunks are. A player reads it with the header and can then place every keyframe in time and
// space, and fetch any keyframe's chunks, without decoding another (§10.1: opening costs what the
// index costs).
#include "codec/decoder/container/chunk_readers.hpp"

#include <cmath>

namespace facemorph::file_layout {

using format::ByteReader;

uint64_t max_index_bytes(const FileHeader& h) {
  const uint64_t count = h.keyframe_count, groups = h.group_count();
  const uint64_t textures = h.texture_groups() ? groups : h.has_texture() ? count : 0;
  return 4 + 8 * count + kPoseCodes * uint64_t{kMaxVarintBytes} * count + 8 * (groups + textures) + kMaxAppendedBytes;
}

std::vector<IndexEntry> read_index(std::span<const uint8_t> payload, const std::string& source, const FileHeader& h,
                                   uint16_t minor_version) {
  ByteReader r(payload, source + ": index");
  const uint32_t count = r.read<uint32_t>("the entry count");
  if (count != h.keyframe_count)
    corrupt(r.source(), std::to_string(count) + " entries for " + std::to_string(h.keyframe_count) + " keyframes");
  // The smallest index of `count` entries, before they are allocated: the times, a byte for each
  // pose number, the offsets.
  const size_t groups = h.group_count();
  // Texture offsets: one per keyframe (TEXR), or one per group (TGOP, format 2.1).
  const size_t textures = h.texture_groups() ? groups : h.has_texture() ? count : 0;
  r.require(size_t{8} * count + kPoseCodes * count + size_t{8} * (groups + textures), "the entries");
  std::vector<IndexEntry> entries(count);
  // Times: within ±1e9 s, increasing, and at least 1e-9 of their span apart, so that the spline's
  // ratios of intervals stay finite (0, 1e-200, 2e-200, 1 would not).
  for (IndexEntry& e : entries) {
    e.time = read_finite(r, "a keyframe time");
    if (std::abs(e.time) > kMaxTime) corrupt(r.source(), "a keyframe time beyond 1e9 s");
  }
  const double span = entries.back().time - entries.front().time;
  for (size_t k = 1; k < count; ++k) {
    if (!(entries[k].time - entries[k - 1].time >= kMinKeyframeGap * span && entries[k].time > entries[k - 1].time)) {
      corrupt(r.source(), "keyframe " + std::to_string(k) + "'s time is not at least 1e-9 of the keyframes' span after the previous one");
    }
  }
  // Poses: codes below 2⁴⁰, the rotation vector within 4 (log R has an angle of at most π), the
  // translation within the bound of every coordinate a file states.
  const FieldCoding& coding = h.metadata.field_coding;
  for (size_t i = 0; i < kPoseCodes; ++i) {
    int64_t code = 0;
    for (size_t k = 0; k < count; ++k) {
      code += read_varint(r, "a pose number");  // both below 2⁴²: no overflow
      if (code <= -kMaxPoseCode || code >= kMaxPoseCode) corrupt(r.source(), "keyframe " + std::to_string(k) + ": a pose code beyond 2^40");
      const double value = static_cast<double>(code) * (i < 3 ? coding.rotation_step : coding.translation_step);
      if (i < 3 && !(std::abs(value) <= kMaxRotationComponent))
        corrupt(r.source(), "keyframe " + std::to_string(k) + ": a rotation vector component beyond 4");
      if (i >= 3 && !(std::abs(value) <= kMaxCoordinate))
        corrupt(r.source(), "keyframe " + std::to_string(k) + ": a pose translation beyond 1e9");
      entries[k].pose[i] = code;
    }
  }
  r.require(size_t{8} * (groups + textures), "the chunk offsets");
  for (size_t g = 0; g < groups; ++g) {
    const uint64_t offset = r.read<uint64_t>("a group offset");
    for (size_t k = g * h.group_size(); k < std::min<size_t>(count, (g + 1) * h.group_size()); ++k) entries[k].group_offset = offset;
  }
  if (h.texture_groups()) {
    for (size_t g = 0; g < groups; ++g) {
      const uint64_t offset = r.read<uint64_t>("a texture group offset");
      for (size_t k = g * h.group_size(); k < std::min<size_t>(count, (g + 1) * h.group_size()); ++k) entries[k].texture_offset = offset;
    }
  } else if (h.has_texture()) {
    for (IndexEntry& e : entries) e.texture_offset = r.read<uint64_t>("a texture offset");
  }
  // Later minor versions append runs here; this reader skips them (a bounded number of bytes).
  check_appended_bytes(r.remaining(), minor_version, r.source());
  return entries;
}

}  // namespace facemorph::file_layout
