// The header chunk, HEAD (spec/container.md §5): the grid, representation, spline, times, units,
// metadata and the keyframe coding's steps. Read first, and checked against the caller's limits
// before anything the file describes is allocated (§10.2 steps 2-4).
#include "codec/decoder/container/chunk_readers.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "format/container.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace facemorph::file_layout {

namespace {

using format::ByteReader;

// A string of at most 1 MiB; `total` counts the header's strings, which together take at most
// kMaxHeaderStringBytes (checked before the string is copied).
std::string read_string(ByteReader& r, const char* what, uint64_t& total) {
  const uint32_t size = r.read<uint32_t>(what);
  if (size > kMaxStringBytes) corrupt(r.source(), std::string(what) + " announces " + std::to_string(size) + " bytes (at most 1 MiB)");
  total += size;
  if (total > kMaxHeaderStringBytes) {
    corrupt(r.source(), std::string(what) + " brings the header's strings to " + std::to_string(total) + " bytes (at most 4 MiB together)");
  }
  const auto bytes = r.bytes(size, what);
  return {bytes.begin(), bytes.end()};
}

// "12.5 MiB" (or "16.0 KiB") for messages.
std::string mebibytes(uint64_t bytes) {
  char text[32];
  if (bytes < (1 << 20)) {
    std::snprintf(text, sizeof text, "%.1f KiB", static_cast<double>(bytes) / (1 << 10));
  } else {
    std::snprintf(text, sizeof text, "%.1f MiB", static_cast<double>(bytes) / (1 << 20));
  }
  return text;
}

}  // namespace

uint64_t max_header_bytes(int max_grid_n) {
  // grid size, rule, hash, representation, spline, flags, reserved, keyframe count, fps, times, pose
  // centre, texture size, rim count, fixed count, landmark count, intra period, steps, pose steps.
  constexpr uint64_t kFixedFields = 4 + 4 + 8 + 4 + 4 + 3 * 8 + 3 * 8 + 4 + 4 + 4 + 4 + 4 + 8 * kKeyframeArrays + 2 * 8;
  const uint64_t strings = 4 * (3 + uint64_t{kMaxLandmarks}) + kMaxHeaderStringBytes;  // their lengths and bytes
  const auto interior = static_cast<uint64_t>(disk_grid_shape(std::clamp(max_grid_n, kMinGridSize, kMaxGridSize)).interior_count);
  return kFixedFields + 4 * interior + strings + kMaxAppendedBytes;
}

void check_appended_bytes(size_t remaining, uint16_t minor_version, const std::string& where) {
  if (remaining == 0) return;
  if (minor_version <= format::kMinorVersion) {
    corrupt(where, std::to_string(remaining) + " bytes after its last field, which format 2." + std::to_string(minor_version) +
                       " does not define");
  }
  if (remaining > kMaxAppendedBytes) {
    corrupt(where, std::to_string(remaining) + " bytes after the fields this decoder knows; a later minor version appends at most 64 KiB");
  }
}

FileHeader read_header(std::span<const uint8_t> payload, const std::string& source, const DecoderLimits& limits,
                       const KeyframesHeld& keyframes_held, uint16_t minor_version) {
  ByteReader r(payload, source + ": header");
  FileHeader h;
  h.limits = limits;
  const uint32_t n = r.read<uint32_t>("the grid size");
  if (n < static_cast<uint32_t>(kMinGridSize) || n > static_cast<uint32_t>(kMaxGridSize)) {
    corrupt(r.source(),
            "grid size " + std::to_string(n) + " outside [" + std::to_string(kMinGridSize) + ", " + std::to_string(kMaxGridSize) + "]");
  }
  if (n > static_cast<uint32_t>(limits.max_grid_n)) {
    over_limit(r.source(),
               "grid size " + std::to_string(n) + " over the limit of " + std::to_string(limits.max_grid_n) + " (max_grid_n, --max-grid)");
  }
  h.shape.grid_n = static_cast<int>(n);
  h.grid_rule = r.read<uint32_t>("the grid rule");
  h.grid_hash = r.read<uint64_t>("the grid hash");
  h.shape.representation = enum_of(kRepresentations, r.read<uint8_t>("the representation"), source + ": representation");
  h.shape.spline = enum_of(kSplineKinds, r.read<uint8_t>("the spline"), source + ": spline kind");
  h.flags = r.read<uint8_t>("the flags");
  if ((h.flags & ~(kHasTexture | kHasHoles | kTextureGroups | kSharedTextures)) != 0) corrupt(r.source(), "reserved flags are set");
  if (h.texture_groups() && !h.has_texture()) corrupt(r.source(), "the texture groups flag (bit 2) without the textures flag (bit 0)");
  if (h.shared_textures() && !h.has_texture()) corrupt(r.source(), "the shared textures flag (bit 3) without the textures flag (bit 0)");
  if (h.shared_textures() && h.texture_groups())
    corrupt(r.source(), "both the texture groups flag (bit 2) and the shared textures flag (bit 3)");
  r.skip(1, "a reserved byte");
  h.keyframe_count = r.read<uint32_t>("the keyframe count");
  if (h.keyframe_count == 0 || h.keyframe_count > kMaxKeyframes) corrupt(r.source(), "keyframe count " + std::to_string(h.keyframe_count));
  if (h.keyframe_count > limits.max_keyframes) {
    over_limit(r.source(), std::to_string(h.keyframe_count) + " keyframes, over the limit of " + std::to_string(limits.max_keyframes) +
                               " (max_keyframes)");
  }
  h.shape.fps = read_finite(r, "the frame rate");
  h.shape.first_time = read_finite(r, "the first time");
  h.shape.last_time = read_finite(r, "the last time");
  if (h.shape.fps <= 0 || h.shape.last_time < h.shape.first_time) corrupt(r.source(), "impossible frame rate or time range");
  if (h.shape.fps < kMinFrameRate || h.shape.fps > kMaxFrameRate || std::abs(h.shape.first_time) > kMaxTime ||
      std::abs(h.shape.last_time) > kMaxTime) {
    corrupt(r.source(), "a frame rate outside [1e-6, 1e6] or a time beyond 1e9 s");
  }
  for (int k = 0; k < 3; ++k) {
    h.shape.pose_centre[k] = read_finite(r, "the pose centre");
    if (std::abs(h.shape.pose_centre[k]) > kMaxCoordinate) corrupt(r.source(), "a pose centre coordinate beyond 1e9");
  }
  h.texture_size = r.read<uint32_t>("the texture size");
  if (h.has_texture() != (h.texture_size > 0) || h.texture_size > static_cast<uint32_t>(kMaxTextureSize)) {
    corrupt(r.source(), "texture size " + std::to_string(h.texture_size) + " does not match the texture flag or exceeds 16384");
  }
  if (h.texture_size > static_cast<uint32_t>(limits.max_texture_size)) {
    over_limit(r.source(), "texture size " + std::to_string(h.texture_size) + " over the limit of " +
                               std::to_string(limits.max_texture_size) + " (max_texture_size)");
  }
  const uint32_t rim_count = r.read<uint32_t>("the rim node count");
  const DiskGridShape shape = disk_grid_shape(h.shape.grid_n);
  if (rim_count != static_cast<uint32_t>(shape.rim_count)) {
    corrupt(r.source(),
            std::to_string(rim_count) + " rim nodes; G at N = " + std::to_string(n) + " has " + std::to_string(shape.rim_count));
  }
  const uint32_t fixed = r.read<uint32_t>("the fixed node count");
  if (fixed > static_cast<uint32_t>(shape.interior_count)) corrupt(r.source(), "more fixed nodes than interior nodes");
  r.require(size_t{4} * fixed, "the fixed nodes");
  h.fixed_nodes.resize(fixed);
  uint64_t node = 0;
  for (uint32_t i = 0; i < fixed; ++i) {
    const uint32_t step = r.read<uint32_t>("a fixed node");
    // Strictly increasing: every difference after the first is positive (a zero would repeat a node).
    if (i > 0 && step == 0) corrupt(r.source(), "the fixed nodes are not strictly increasing");
    node += step;
    if (node >= static_cast<uint64_t>(shape.interior_count)) corrupt(r.source(), "a fixed node beyond G's interior nodes");
    h.fixed_nodes[i] = static_cast<int32_t>(node);
  }
  // What decoding this file holds, from these numbers alone, before any keyframe is read.
  uint64_t values = 0;
  for (size_t length : expected_lengths(h)) values += length;
  const uint64_t held = keyframes_held(h.keyframe_count, h.shape.spline);
  // With texture groups, the AV1 decoder's frames too (§10.1: 8 references and the frame it decodes).
  const uint64_t sequence_decoder = h.texture_groups() ? texture_sequence_decoder_bytes(h.texture_size) : 0;
  const uint64_t memory = estimated_memory_bytes(static_cast<int>(n), held, static_cast<int>(h.texture_size), values) +
                          index_memory_bytes(h.keyframe_count) + sequence_decoder;
  if (memory > limits.max_memory_bytes) {
    over_limit(r.source(), std::to_string(held) + " keyframes held at once on G at N = " + std::to_string(n) + " with " +
                               std::to_string(h.texture_size) + "² textures need about " + mebibytes(memory) +
                               ", over the memory limit of " + mebibytes(limits.max_memory_bytes) + " (max_memory_bytes, --max-memory)");
  }
  uint64_t string_bytes = 0;
  h.shape.units = read_string(r, "the units", string_bytes);
  if (h.shape.units != "m" && h.shape.units != "cm" && h.shape.units != "mm")
    corrupt(r.source(), "units '" + h.shape.units + "' (m, cm or mm)");
  h.metadata.encoder = read_string(r, "the encoder", string_bytes);
  h.metadata.settings = read_string(r, "the settings", string_bytes);
  const uint32_t landmarks = r.read<uint32_t>("the landmark count");
  if (landmarks > kMaxLandmarks) corrupt(r.source(), std::to_string(landmarks) + " landmark names");
  r.require(size_t{4} * landmarks, "the landmark names");  // each one's length, before the list is allocated
  h.metadata.landmark_names.reserve(landmarks);
  for (uint32_t i = 0; i < landmarks; ++i) h.metadata.landmark_names.push_back(read_string(r, "a landmark name", string_bytes));
  FieldCoding& c = h.metadata.field_coding;
  const uint32_t period = r.read<uint32_t>("the intra period");
  if (period == 0 || period > kMaxIntraPeriod) corrupt(r.source(), "intra period " + std::to_string(period));
  c.intra_period = static_cast<int>(period);
  c.steps.resize(kKeyframeArrays);
  for (double& step : c.steps) {
    step = read_finite(r, "a field step");
    if (!(step > 0)) corrupt(r.source(), "a field step that is not positive");
  }
  c.rotation_step = read_finite(r, "the rotation step");
  c.translation_step = read_finite(r, "the translation step");
  if (!(c.rotation_step > 0) || !(c.translation_step > 0)) corrupt(r.source(), "a pose step that is not positive");
  // Later minor versions append fields here; this reader skips them (a bounded number of bytes).
  check_appended_bytes(r.remaining(), minor_version, r.source());
  // The hash from the table where N has one (no G built for a header that is refused), else from
  // G built within the caller's limit.
  const uint64_t known = known_disk_grid_hash(h.shape.grid_n);
  if (h.grid_rule != static_cast<uint32_t>(kDiskGridRule) || h.grid_hash != (known != 0 ? known : grid_facts(h.shape.grid_n)->hash)) {
    throw Error(ErrorCode::kUnsupported, source + ": the file's grid (rule " + std::to_string(h.grid_rule) + ", N = " + std::to_string(n) +
                                             ") is not the grid this decoder builds (rule " + std::to_string(kDiskGridRule) +
                                             "): it would decode differently");
  }
  return h;
}

}  // namespace facemorph::file_layout
