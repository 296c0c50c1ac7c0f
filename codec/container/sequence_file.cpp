// The .fmv file of a Sequence: spec/container.md §4-7 in code. The outer layer (preamble, chunks,
// checksums, zstd) is format/container; this file gives the payloads their meaning and checks every
// value against the header before anything uses it.
#include "facemorph/sequence_file.hpp"

#include "codec/container/opened_file.hpp"

#include "facemorph/disk_grid.hpp"
#include "facemorph/error.hpp"
#include "facemorph/image_codec.hpp"
#include "facemorph/limits.hpp"
#include "facemorph/pose.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/container.hpp"
#include "format/field_coder.hpp"
#include "format/file_io.hpp"
#include "format/quantize.hpp"
#include "format/ranged_residuals.hpp"
#include "format/residual_coder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#ifndef FACEMORPH_VERSION
#define FACEMORPH_VERSION "unknown"
#endif

namespace facemorph {

namespace {

using format::ByteReader;
using format::ByteWriter;

constexpr std::string_view kHeader = "HEAD", kIndex = "KIDX", kKeyframe = "KEYF", kPredictedKeyframe = "KEYP", kKeyframeGroup = "KGOP",
                           kTexture = "TEXR";
constexpr uint8_t kCodePlanes = 0;  // the header's field coding without steps (spec/container.md §5)
constexpr uint8_t kIntra = 0, kFromPreviousKeyframe = 1;  // a KEYP chunk's reference
constexpr int64_t kMaxFieldCode = int64_t{1} << 30;       // |code| bound: differences of codes fit 32 bits
constexpr uint32_t kMaxIntraPeriod = 1u << 20;
constexpr uint32_t kTextureWebp = 1, kTextureAvif = 2;  // TEXR image codecs (spec/container.md §8)
constexpr uint8_t kHasTexture = 1, kHasHoles = 2;
constexpr uint32_t kMaxKeyframes = 1u << 20;
constexpr uint32_t kMaxStringBytes = 1u << 20;
constexpr uint32_t kMaxLandmarks = 1u << 16;
constexpr int kMaxTextureSize = 16384;
constexpr size_t kKeyframeArrays = kKeyframeArrayCount;  // the fields' arrays, then the hole level
constexpr double kMaxCompactTranslation = 1e30;            // float32 holds it (field coding 3's pose)
constexpr float kMaxRotationComponent = 4;                 // > π: field codings 3 and 4's rotation vector
constexpr int64_t kMaxPoseCode = int64_t{1} << 40;         // field coding 4's pose codes: changes fit 42 bits
// Ranges a file may state (spec/container.md §5, §6, §7): within them every product the decoder
// forms (a pose applied to a point, a spline's powers of time ratios) is a finite double.
constexpr double kMaxCoordinate = 1e9;        // |pose centre|, |translation| in the file's units (1000 km in mm)
constexpr double kMaxTime = 1e9;              // |a time|, seconds (31 years)
constexpr double kMinFrameRate = 1e-6, kMaxFrameRate = 1e6;
constexpr double kMinKeyframeGap = 1e-9;      // keyframe times at least this fraction of their span apart

// The numbers the file uses for enumerations (spec/container.md §5): fixed forever, independent of
// the order of the C++ enumerators.
constexpr std::pair<Representation, uint8_t> kRepresentationCodes[] = {
    {Representation::kHL, 0}, {Representation::kHLT, 1}, {Representation::kXYZ, 2}};
constexpr std::pair<SplineKind, uint8_t> kSplineCodes[] = {
    {SplineKind::kLocalCubic, 0}, {SplineKind::kCatmullRom, 1}, {SplineKind::kNotAKnot, 2}, {SplineKind::kLinear, 3}};
// The header's field codings with steps (KEYP chunks); 0 is kCodePlanes.
constexpr std::pair<FieldCoding::Residuals, uint8_t> kPredictedCodingCodes[] = {
    {FieldCoding::Residuals::kZstdVarints, 1}, {FieldCoding::Residuals::kRangeCodedV13, 2}, {FieldCoding::Residuals::kRangeCodedV14, 3},
    {FieldCoding::Residuals::kRangeCoded, 4}};

template <typename Enum, size_t N>
uint8_t code_of(const std::pair<Enum, uint8_t> (&table)[N], Enum value) {
  for (const auto& [e, c] : table) {
    if (e == value) return c;
  }
  throw Error(ErrorCode::kInvalidArgument, "no file code for an enumerator");
}

template <typename Enum, size_t N>
Enum enum_of(const std::pair<Enum, uint8_t> (&table)[N], uint8_t code, const std::string& what) {
  for (const auto& [e, c] : table) {
    if (c == code) return e;
  }
  throw Error(ErrorCode::kUnsupported, what + " " + std::to_string(code) + " is not one this decoder knows");
}

// What the container needs of G for N: its hash, and the lattice neighbours its predicted
// arrays use (interior nodes row by row; the hole level's rim nodes follow, each after the one
// before it). Built once per process and N: the grid is what costs.
struct GridFacts {
  int n = 0;
  uint64_t hash = 0;
  format::LatticeNeighbours interior, all_nodes;
};

// One N kept (a player opens files of one grid; an encoder writes one): memory never grows with the
// number of grids a process has seen. The caller holds what it uses, so a file opened on another
// thread with another N cannot free it under it.
std::shared_ptr<const GridFacts> grid_facts(int n) {
  static std::mutex mutex;
  static std::shared_ptr<const GridFacts> cached;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (cached && cached->n == n) return cached;
  }
  const DiskGrid grid = make_disk_grid(n);
  auto facts = std::make_shared<GridFacts>();
  facts->n = n;
  facts->hash = grid.hash;
  format::LatticeNeighbours& l = facts->all_nodes;
  for (int node = 0; node < grid.node_count(); ++node) {
    if (grid.is_rim(node)) {
      l.left.push_back(node - 1);
      l.up.push_back(-1);
      l.up_left.push_back(-1);
      continue;
    }
    const auto [i, j] = grid.cell[static_cast<size_t>(node)];
    l.left.push_back(grid.node(i - 1, j));
    l.up.push_back(grid.node(i, j - 1));
    l.up_left.push_back(grid.node(i - 1, j - 1));
  }
  const auto interior = static_cast<size_t>(grid.interior_count);
  facts->interior.left.assign(l.left.begin(), l.left.begin() + static_cast<ptrdiff_t>(interior));
  facts->interior.up.assign(l.up.begin(), l.up.begin() + static_cast<ptrdiff_t>(interior));
  facts->interior.up_left.assign(l.up_left.begin(), l.up_left.begin() + static_cast<ptrdiff_t>(interior));
  std::lock_guard<std::mutex> lock(mutex);
  cached = std::move(facts);
  return cached;
}

uint64_t grid_hash(int n) { return grid_facts(n)->hash; }

[[noreturn]] void corrupt(const std::string& where, const std::string& what) { throw Error(ErrorCode::kCorrupt, where + ": " + what); }

double read_finite(ByteReader& r, const char* what) {
  const double v = r.read<double>(what);
  if (!std::isfinite(v)) corrupt(r.source(), std::string(what) + " is not finite");
  return v;
}

std::string read_string(ByteReader& r, const char* what) {
  const uint32_t size = r.read<uint32_t>(what);
  if (size > kMaxStringBytes) corrupt(r.source(), std::string(what) + " announces " + std::to_string(size) + " bytes (at most 1 MiB)");
  const auto bytes = r.bytes(size, what);
  return {bytes.begin(), bytes.end()};
}

// What each array's length must be, from the header alone.
std::vector<size_t> expected_lengths(int grid_n, Representation representation, size_t fixed, bool with_holes) {
  const DiskGridShape shape = disk_grid_shape(grid_n);
  const auto interior = static_cast<size_t>(shape.interior_count);
  const auto rim = static_cast<size_t>(shape.rim_count);
  const bool fields = representation != Representation::kXYZ;
  const bool tangential = representation == Representation::kHLT;
  const size_t holes = with_holes ? interior + rim : 0;
  return {fields ? interior : 0, fields ? interior : 0, tangential ? interior : 0, tangential ? interior : 0,
          fixed, fixed, fixed,
          fields ? 0 : interior, fields ? 0 : interior, fields ? 0 : interior,
          rim, rim, rim, holes};
}

// ---- The header (HEAD) ----

struct Header {
  DecoderLimits limits;  // the caller's: what the file may make the decoder allocate
  Sequence shape;  // every field but the keyframes
  uint32_t keyframe_count = 0;
  uint32_t grid_rule = 0;
  uint64_t grid_hash = 0;
  uint8_t flags = 0;
  uint32_t texture_size = 0;
  uint32_t rim_count = 0;
  std::vector<int32_t> fixed_nodes;
  SequenceFileMetadata metadata;  // with the field coding
};

// What a KEYP chunk's layout depends on (spec/container.md §7.3).
bool range_coded(FieldCoding::Residuals coder) { return coder != FieldCoding::Residuals::kZstdVarints; }
// Field coding 3: the compact pose, the predictors packed, the models carried from the previous keyframe.
bool chained(FieldCoding::Residuals coder) { return coder == FieldCoding::Residuals::kRangeCodedV14; }
// Field coding 4: a chunk and one stream per group of keyframes (an intra period), the pose quantised.
bool grouped(FieldCoding::Residuals coder) { return coder == FieldCoding::Residuals::kRangeCoded; }

std::vector<uint8_t> write_header(const Sequence& s, const SequenceFileMetadata& metadata, const DiskGridShape& shape) {
  ByteWriter w;
  w.write(static_cast<uint32_t>(s.grid_n));
  w.write(static_cast<uint32_t>(kDiskGridRule));
  w.write(grid_hash(s.grid_n));
  w.write(code_of(kRepresentationCodes, s.representation));
  w.write(code_of(kSplineCodes, s.spline));
  w.write(static_cast<uint8_t>((s.has_texture() ? kHasTexture : 0) | (s.has_holes() ? kHasHoles : 0)));
  w.write(uint8_t{0});
  w.write(static_cast<uint32_t>(s.keyframes.size()));
  w.write(s.fps);
  w.write(s.first_time);
  w.write(s.last_time);
  for (int k = 0; k < 3; ++k) w.write(s.pose_centre[k]);
  w.write(static_cast<uint32_t>(s.has_texture() ? s.keyframes.front().texture.width : 0));
  w.write(static_cast<uint32_t>(shape.rim_count));
  const std::vector<int32_t>& fixed = s.keyframes.front().fields.fixed_nodes;
  w.write(static_cast<uint32_t>(fixed.size()));
  // As differences from the previous node (the first from 0): sorted nodes give small numbers,
  // which the header's zstd packs (Medusa-like noisy frames mark ~9% of the nodes).
  int32_t previous = 0;
  for (int32_t node : fixed) {
    w.write(static_cast<uint32_t>(node - previous));
    previous = node;
  }
  w.string(s.units);
  w.string(metadata.encoder.empty() ? std::string("facemorph ") + FACEMORPH_VERSION : metadata.encoder);
  w.string(metadata.settings);
  w.write(static_cast<uint32_t>(metadata.landmark_names.size()));
  for (const std::string& name : metadata.landmark_names) w.string(name);
  // Appended in 1.1: how the keyframes' fields are coded.
  const FieldCoding& coding = metadata.field_coding;
  w.write(coding.predicted() ? code_of(kPredictedCodingCodes, coding.residuals) : kCodePlanes);
  if (coding.predicted()) {
    w.write(static_cast<uint32_t>(coding.intra_period));
    for (double step : coding.steps) w.write(step);
    if (grouped(coding.residuals)) {
      w.write(coding.rotation_step);
      w.write(coding.translation_step);
    }
  }
  return w.take();
}

[[noreturn]] void over_limit(const std::string& where, const std::string& what) { throw Error(ErrorCode::kLimit, where + ": " + what); }

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

// `keyframes_held`: how many keyframes the caller holds at once for the given count and spline
// (every one to decode the file whole; the spline's window to decode on demand).
Header read_header(std::span<const uint8_t> payload, const std::string& source, uint16_t minor_version, const DecoderLimits& limits,
                   const OpenedFile::KeyframesHeld& keyframes_held) {
  ByteReader r(payload, source + ": header");
  Header h;
  h.limits = limits;
  const uint32_t n = r.read<uint32_t>("the grid size");
  if (n < static_cast<uint32_t>(kMinGridSize) || n > static_cast<uint32_t>(kMaxGridSize)) {
    corrupt(r.source(), "grid size " + std::to_string(n) + " outside [" + std::to_string(kMinGridSize) + ", " + std::to_string(kMaxGridSize) + "]");
  }
  if (n > static_cast<uint32_t>(limits.max_grid_n)) {
    over_limit(r.source(), "grid size " + std::to_string(n) + " over the limit of " + std::to_string(limits.max_grid_n) + " (max_grid_n, --max-grid)");
  }
  h.shape.grid_n = static_cast<int>(n);
  h.grid_rule = r.read<uint32_t>("the grid rule");
  h.grid_hash = r.read<uint64_t>("the grid hash");
  h.shape.representation = enum_of(kRepresentationCodes, r.read<uint8_t>("the representation"), source + ": representation");
  h.shape.spline = enum_of(kSplineCodes, r.read<uint8_t>("the spline"), source + ": spline kind");
  h.flags = r.read<uint8_t>("the flags");
  if ((h.flags & ~(kHasTexture | kHasHoles)) != 0) corrupt(r.source(), "reserved flags are set");
  r.skip(1, "a reserved byte");
  h.keyframe_count = r.read<uint32_t>("the keyframe count");
  if (h.keyframe_count == 0 || h.keyframe_count > kMaxKeyframes) corrupt(r.source(), "keyframe count " + std::to_string(h.keyframe_count));
  if (h.keyframe_count > limits.max_keyframes) {
    over_limit(r.source(), std::to_string(h.keyframe_count) + " keyframes, over the limit of " + std::to_string(limits.max_keyframes) + " (max_keyframes)");
  }
  h.shape.fps = read_finite(r, "the frame rate");
  h.shape.first_time = read_finite(r, "the first time");
  h.shape.last_time = read_finite(r, "the last time");
  if (h.shape.fps <= 0 || h.shape.last_time < h.shape.first_time) corrupt(r.source(), "impossible frame rate or time range");
  if (h.shape.fps < kMinFrameRate || h.shape.fps > kMaxFrameRate || std::abs(h.shape.first_time) > kMaxTime || std::abs(h.shape.last_time) > kMaxTime) {
    corrupt(r.source(), "a frame rate outside [1e-6, 1e6] or a time beyond 1e9 s");
  }
  for (int k = 0; k < 3; ++k) {
    h.shape.pose_centre[k] = read_finite(r, "the pose centre");
    if (std::abs(h.shape.pose_centre[k]) > kMaxCoordinate) corrupt(r.source(), "a pose centre coordinate beyond 1e9");
  }
  h.texture_size = r.read<uint32_t>("the texture size");
  if (((h.flags & kHasTexture) != 0) != (h.texture_size > 0) || h.texture_size > static_cast<uint32_t>(kMaxTextureSize)) {
    corrupt(r.source(), "texture size " + std::to_string(h.texture_size) + " does not match the texture flag or exceeds 16384");
  }
  if (h.texture_size > static_cast<uint32_t>(limits.max_texture_size)) {
    over_limit(r.source(), "texture size " + std::to_string(h.texture_size) + " over the limit of " + std::to_string(limits.max_texture_size) +
                               " (max_texture_size)");
  }
  h.rim_count = r.read<uint32_t>("the rim node count");
  const DiskGridShape shape = disk_grid_shape(h.shape.grid_n);
  if (h.rim_count != static_cast<uint32_t>(shape.rim_count)) {
    corrupt(r.source(), std::to_string(h.rim_count) + " rim nodes; G at N = " + std::to_string(n) + " has " + std::to_string(shape.rim_count));
  }
  const uint32_t fixed = r.read<uint32_t>("the fixed node count");
  if (fixed > static_cast<uint32_t>(shape.interior_count)) corrupt(r.source(), "more fixed nodes than interior nodes");
  r.require(size_t{4} * fixed, "the fixed nodes");
  h.fixed_nodes.resize(fixed);
  uint64_t node = 0;
  for (uint32_t i = 0; i < fixed; ++i) {
    node += r.read<uint32_t>("a fixed node");
    if (node >= static_cast<uint64_t>(shape.interior_count)) corrupt(r.source(), "a fixed node beyond G's interior nodes");
    h.fixed_nodes[i] = static_cast<int32_t>(node);
  }
  // What decoding this file holds, from these numbers alone, before any keyframe is read.
  uint64_t values = 0;
  for (size_t length : expected_lengths(h.shape.grid_n, h.shape.representation, h.fixed_nodes.size(), (h.flags & kHasHoles) != 0)) {
    values += length;
  }
  const uint64_t held = keyframes_held(h.keyframe_count, h.shape.spline);
  const uint64_t memory = estimated_memory_bytes(static_cast<int>(n), held, static_cast<int>(h.texture_size), values) + index_memory_bytes(h.keyframe_count);
  if (memory > limits.max_memory_bytes) {
    over_limit(r.source(), std::to_string(held) + " keyframes held at once on G at N = " + std::to_string(n) + " with " + std::to_string(h.texture_size) +
                               "² textures need about " + mebibytes(memory) + ", over the memory limit of " + mebibytes(limits.max_memory_bytes) +
                               " (max_memory_bytes, --max-memory)");
  }
  h.shape.units = read_string(r, "the units");
  if (h.shape.units != "m" && h.shape.units != "cm" && h.shape.units != "mm") corrupt(r.source(), "units '" + h.shape.units + "' (m, cm or mm)");
  h.metadata.encoder = read_string(r, "the encoder");
  h.metadata.settings = read_string(r, "the settings");
  const uint32_t landmarks = r.read<uint32_t>("the landmark count");
  if (landmarks > kMaxLandmarks) corrupt(r.source(), std::to_string(landmarks) + " landmark names");
  for (uint32_t i = 0; i < landmarks; ++i) h.metadata.landmark_names.push_back(read_string(r, "a landmark name"));
  // 1.1: the field coding (1.0 files have code planes); 1.3 adds range-coded residuals, 1.4 their
  // models carried along chains of predicted keyframes and compact poses.
  if (minor_version >= 1) {
    const uint8_t coding = r.read<uint8_t>("the field coding");
    if (coding != kCodePlanes) {
      FieldCoding& c = h.metadata.field_coding;
      c.residuals = enum_of(kPredictedCodingCodes, coding, source + ": field coding");
      const uint32_t period = r.read<uint32_t>("the intra period");
      if (period == 0 || period > kMaxIntraPeriod) corrupt(r.source(), "intra period " + std::to_string(period));
      c.intra_period = static_cast<int>(period);
      c.steps.resize(kKeyframeArrays);
      for (double& step : c.steps) {
        step = read_finite(r, "a field step");
        if (!(step > 0)) corrupt(r.source(), "a field step that is not positive");
      }
      if (grouped(c.residuals)) {
        c.rotation_step = read_finite(r, "the rotation step");
        c.translation_step = read_finite(r, "the translation step");
        if (!(c.rotation_step > 0) || !(c.translation_step > 0)) corrupt(r.source(), "a pose step that is not positive");
      }
    }
  }
  // Later minor versions append fields here; this reader ignores them.
  // The hash from the table where N has one (no G built for a header that is refused), else from
  // G built within the caller's limit.
  const uint64_t known = known_disk_grid_hash(h.shape.grid_n);
  if (h.grid_rule != static_cast<uint32_t>(kDiskGridRule) || h.grid_hash != (known != 0 ? known : grid_hash(h.shape.grid_n))) {
    throw Error(ErrorCode::kUnsupported, source + ": the file's grid (rule " + std::to_string(h.grid_rule) + ", N = " + std::to_string(n) +
                                             ") is not the grid this decoder builds (rule " + std::to_string(kDiskGridRule) + "): it would decode differently");
  }
  return h;
}

// ---- The index (KIDX) ----

struct IndexEntry {
  double time = 0;
  uint64_t keyframe_offset = 0, texture_offset = 0;
};

constexpr size_t kIndexEntryBytes = 24;

// Field codings 0-3: one record per keyframe. Field coding 4 (`group` = the intra period): every
// keyframe's time, then every group's chunk offset, then (with textures) every keyframe's texture
// chunk offset, each a run of like numbers that the chunk's zstd packs. An entry's keyframe offset
// is its group's chunk there.
std::vector<uint8_t> write_index(const std::vector<IndexEntry>& entries, size_t group, bool textured) {
  ByteWriter w;
  w.write(static_cast<uint32_t>(entries.size()));
  if (group == 0) {
    for (const IndexEntry& e : entries) {
      w.write(e.time);
      w.write(e.keyframe_offset);
      w.write(e.texture_offset);
    }
    return w.take();
  }
  for (const IndexEntry& e : entries) w.write(e.time);
  for (size_t k = 0; k < entries.size(); k += group) w.write(entries[k].keyframe_offset);
  if (textured) {
    for (const IndexEntry& e : entries) w.write(e.texture_offset);
  }
  return w.take();
}

std::vector<IndexEntry> read_index(std::span<const uint8_t> payload, const std::string& source, uint32_t keyframes, size_t group, bool textured) {
  ByteReader r(payload, source + ": index");
  const uint32_t count = r.read<uint32_t>("the entry count");
  if (count != keyframes) corrupt(r.source(), std::to_string(count) + " entries for " + std::to_string(keyframes) + " keyframes");
  if (group == 0) {
    r.require(size_t{count} * kIndexEntryBytes, "the entries");
    std::vector<IndexEntry> entries(count);
    for (IndexEntry& e : entries) {
      e.time = read_finite(r, "a keyframe time");
      e.keyframe_offset = r.read<uint64_t>("a keyframe offset");
      e.texture_offset = r.read<uint64_t>("a texture offset");
    }
    return entries;
  }
  const size_t groups = (count + group - 1) / group;
  r.require(size_t{8} * (count + groups + (textured ? count : 0)), "the entries");
  std::vector<IndexEntry> entries(count);
  for (IndexEntry& e : entries) e.time = read_finite(r, "a keyframe time");
  for (size_t g = 0; g < groups; ++g) {
    const uint64_t offset = r.read<uint64_t>("a group offset");
    for (size_t k = g * group; k < std::min<size_t>(count, (g + 1) * group); ++k) entries[k].keyframe_offset = offset;
  }
  if (textured) {
    for (IndexEntry& e : entries) e.texture_offset = r.read<uint64_t>("a texture offset");
  }
  return entries;
}

// ---- One keyframe (KEYF): time, pose, the quantised arrays ----

// Field coding 3's pose: the rotation vector log R and the translation, as float32. Half a float's
// step is 3e-8 of a value: a tenth of a micrometre on a head, and a 24-byte pose instead of 96.
std::array<float, 6> compact_pose(const RigidPose& pose) {
  const Vec3 rotation = rotation_log(pose.rotation);
  std::array<float, 6> stored{};
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(pose.translation[k]) < kMaxCompactTranslation)) {
      throw Error(ErrorCode::kInvalidArgument, "a pose translation of " + std::to_string(pose.translation[k]) + ", beyond what float32 stores");
    }
    stored[static_cast<size_t>(k)] = static_cast<float>(rotation[k]);
    stored[static_cast<size_t>(3 + k)] = static_cast<float>(pose.translation[k]);
  }
  return stored;
}

RigidPose pose_of(const std::array<float, 6>& stored) {
  RigidPose pose;
  pose.rotation = rotation_exp(Vec3(stored[0], stored[1], stored[2]));
  pose.translation = Vec3(stored[3], stored[4], stored[5]);
  return pose;
}

// What KEYF and KEYP share: the number, the time, the pose (float64 matrix and translation, or
// field coding 3's compact pose).
void write_keyframe_preamble(ByteWriter& w, const Keyframe& key, uint32_t number, bool compact = false) {
  w.write(number);
  w.write(key.time);
  if (compact) {
    for (float v : compact_pose(key.pose)) w.write(v);
    return;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) w.write(key.pose.rotation(i, j));
  }
  for (int k = 0; k < 3; ++k) w.write(key.pose.translation[k]);
}

// A decoded pose's translation within the bound every position a file states has (§7).
void check_translation(const RigidPose& pose, const std::string& where) {
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(pose.translation[k]) <= kMaxCoordinate)) corrupt(where, "a pose translation beyond 1e9");
  }
}

void read_keyframe_preamble(ByteReader& r, Keyframe& key, const std::string& where, uint32_t number, bool compact = false) {
  if (r.read<uint32_t>("the keyframe number") != number) corrupt(where, "holds another keyframe than the index says");
  key.time = read_finite(r, "the time");
  if (compact) {
    std::array<float, 6> stored{};
    for (float& v : stored) {
      v = r.read<float>("the pose");
      if (!std::isfinite(v)) corrupt(where, "the pose is not finite");
    }
    // log R has an angle of at most π: a larger component is no pose an encoder wrote.
    for (size_t k = 0; k < 3; ++k) {
      if (std::abs(stored[k]) > kMaxRotationComponent) corrupt(where, "a rotation vector component beyond 4");
    }
    key.pose = pose_of(stored);
    check_translation(key.pose, where);
    return;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) key.pose.rotation(i, j) = read_finite(r, "the rotation");
  }
  for (int k = 0; k < 3; ++k) key.pose.translation[k] = read_finite(r, "the translation");
  check_translation(key.pose, where);
}

std::vector<std::vector<double>> keyframe_arrays(const Keyframe& key) {
  std::vector<std::vector<double>> arrays = scalar_arrays(key.fields);
  arrays.push_back(key.hole_level);
  return arrays;
}

// The inverse of keyframe_arrays: the fields and hole level from the arrays in the file's order.
void assign_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, Representation representation, int grid_n,
                            std::vector<int32_t> fixed_nodes) {
  key.hole_level = std::move(arrays[kScalarArrayCount]);
  arrays.resize(kScalarArrayCount);
  key.fields = fields_from_scalar_arrays(representation, grid_n, std::move(fixed_nodes), arrays);
}

// The same for a decoded keyframe, checked as every decoded keyframe is.
void set_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, const Header& h, const std::string& where) {
  assign_keyframe_arrays(key, std::move(arrays), h.shape.representation, h.shape.grid_n, h.fixed_nodes);
  try {
    validate_fields(key.fields);
  } catch (const Error& e) {
    corrupt(where, e.what());
  }
}

std::vector<uint8_t> write_keyframe(const Keyframe& key, uint32_t number) {
  ByteWriter w;
  write_keyframe_preamble(w, key, number);
  const std::vector<std::vector<double>> arrays = keyframe_arrays(key);
  std::vector<format::Quantized16> quantized;
  w.write(static_cast<uint32_t>(arrays.size()));
  for (const std::vector<double>& values : arrays) {
    quantized.push_back(format::quantize16(values));
    w.write(static_cast<uint32_t>(values.size()));
    w.write(quantized.back().lo);
    w.write(quantized.back().hi);
  }
  const std::vector<uint8_t> coded = format::encode_code_planes(quantized);
  w.write(static_cast<uint32_t>(coded.size()));
  w.bytes(coded);
  return w.take();
}

std::vector<size_t> expected_lengths(const Header& h) {
  return expected_lengths(h.shape.grid_n, h.shape.representation, h.fixed_nodes.size(), (h.flags & kHasHoles) != 0);
}

Keyframe read_keyframe(std::span<const uint8_t> payload, const std::string& where, const Header& h, uint32_t number) {
  ByteReader r(payload, where);
  Keyframe key;
  read_keyframe_preamble(r, key, where, number);
  const uint32_t count = r.read<uint32_t>("the array count");
  if (count < kKeyframeArrays) corrupt(where, std::to_string(count) + " arrays, " + std::to_string(kKeyframeArrays) + " expected");
  if (count > 64) corrupt(where, std::to_string(count) + " arrays (at most 64)");
  const std::vector<size_t> expected = expected_lengths(h);
  // An appended array is at most I + B + B long (§7.1): the longest a later version may add.
  const DiskGridShape shape = disk_grid_shape(h.shape.grid_n);
  const auto longest_appended = static_cast<size_t>(shape.interior_count) + 2 * static_cast<size_t>(shape.rim_count);
  std::vector<format::Quantized16> ranges(count);
  std::vector<size_t> lengths(count);
  uint64_t total = 0;
  for (uint32_t a = 0; a < count; ++a) {
    lengths[a] = r.read<uint32_t>("an array length");
    ranges[a].lo = read_finite(r, "an array's range");
    ranges[a].hi = read_finite(r, "an array's range");
    if (a < kKeyframeArrays && lengths[a] != expected[a]) {
      corrupt(where, "array " + std::to_string(a) + " holds " + std::to_string(lengths[a]) + " values, " + std::to_string(expected[a]) + " expected");
    }
    if (a >= kKeyframeArrays && lengths[a] > longest_appended) corrupt(where, "an appended array is too long (at most I + B + B)");
    total += lengths[a];
    if (!(ranges[a].lo <= ranges[a].hi) || !std::isfinite(ranges[a].hi - ranges[a].lo)) corrupt(where, "array " + std::to_string(a) + " has an impossible range");
  }
  // Two bytes a code decompressed and two decoded, appended arrays included.
  if (4 * total > h.limits.max_memory_bytes) {
    over_limit(where, std::to_string(total) + " codes need " + std::to_string(4 * total) + " bytes, over the memory limit");
  }
  const uint32_t coded = r.read<uint32_t>("the coded size");
  const auto bytes = r.bytes(coded, "the coded arrays");
  std::vector<std::vector<uint16_t>> codes = format::decode_code_planes(bytes, lengths, where);
  std::vector<std::vector<double>> arrays(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    ranges[a].codes = std::move(codes[a]);
    arrays[a] = format::dequantize16(ranges[a]);
  }
  // Arrays past the ones this version knows were appended by a later minor version: ignored.
  set_keyframe_arrays(key, std::move(arrays), h, where);
  return key;
}

// ---- One predicted keyframe (KEYP): integer multiples of the header's steps, residuals coded ----

// Which arrays lie on G's lattice (spatial predictors 2 and 3 allowed): the per-node fields and
// positions on the interior nodes, the hole level on every node. The band vectors and the rim are
// sequences only.
const format::LatticeNeighbours* lattice_of(size_t array, size_t length, const GridFacts& grid) {
  const format::LatticeNeighbours* lattice = nullptr;
  if (array <= 3 || (array >= 7 && array <= 9)) lattice = &grid.interior;
  if (array == kScalarArrayCount) lattice = &grid.all_nodes;
  return lattice && lattice->size() == length ? lattice : nullptr;  // an empty array has none
}

// lattice_of for every array of a keyframe, given their lengths (the header's, or the arrays').
std::vector<const format::LatticeNeighbours*> lattices_of(const std::vector<size_t>& lengths, const GridFacts& grid) {
  std::vector<const format::LatticeNeighbours*> lattices;
  for (size_t a = 0; a < lengths.size(); ++a) lattices.push_back(lattice_of(a, lengths[a], grid));
  return lattices;
}

template <typename T>
std::vector<size_t> lengths_of(const std::vector<std::vector<T>>& arrays) {
  std::vector<size_t> lengths;
  for (const std::vector<T>& a : arrays) lengths.push_back(a.size());
  return lengths;
}

int32_t field_code(double value, double step) {
  const double code = std::nearbyint(value / step);
  if (!(std::abs(code) < static_cast<double>(kMaxFieldCode))) {
    throw Error(ErrorCode::kInvalidArgument, "a field value " + std::to_string(value) + " lies more than 2^30 steps of " + std::to_string(step) + " from 0");
  }
  return static_cast<int32_t>(code);
}

void check_steps(const FieldCoding& coding) {
  if (coding.steps.size() != kKeyframeArrays) throw Error(ErrorCode::kInvalidArgument, "field coding: one step per keyframe array needed");
  for (double step : coding.steps) {
    if (!(step > 0) || !std::isfinite(step)) throw Error(ErrorCode::kInvalidArgument, "field coding: a step that is not finite and positive");
  }
  if (coding.intra_period < 1 || static_cast<uint32_t>(coding.intra_period) > kMaxIntraPeriod) {
    throw Error(ErrorCode::kInvalidArgument, "field coding: intra period outside [1, 2^20]");
  }
  if (grouped(coding.residuals) && !(coding.rotation_step > 0 && coding.translation_step > 0 && std::isfinite(coding.rotation_step) &&
                                     std::isfinite(coding.translation_step))) {
    throw Error(ErrorCode::kInvalidArgument, "field coding 4: pose steps that are not finite and positive (set_default_pose_steps)");
  }
}

// Zigzag magnitudes' order-0 entropy in bits: how the coder chooses a predictor without running zstd.
double estimated_bits(const std::vector<int64_t>& residuals) {
  std::map<int64_t, size_t> counts;
  for (int64_t r : residuals) ++counts[r];
  double bits = 0;
  const auto n = static_cast<double>(residuals.size());
  for (const auto& [value, count] : counts) bits -= static_cast<double>(count) * std::log2(static_cast<double>(count) / n);
  return bits;
}

struct CodedArray {
  format::SpatialPredictor predictor = format::SpatialPredictor::kNone;
  std::vector<int64_t> residuals;
  double bits = 0;
};

// The models each array's residuals adapt under when range-coded (spec/container.md §7.4): its own,
// except that b continues a's and the second and third components of a vector field the first's.
constexpr std::array<uint8_t, kKeyframeArrays> kRangeModelSets = {0, 1, 2, 2, 4, 4, 4, 7, 7, 7, 10, 10, 10, 13};

CodedArray best_prediction(std::span<const int32_t> codes, const format::LatticeNeighbours* lattice, FieldCoding::Residuals coder) {
  CodedArray best;
  best.bits = std::numeric_limits<double>::infinity();
  for (uint8_t p = 0; p < format::kSpatialPredictorCount; ++p) {
    const auto predictor = static_cast<format::SpatialPredictor>(p);
    if (format::uses_lattice(predictor) && lattice == nullptr) continue;
    std::vector<int64_t> residuals = format::spatial_residuals(codes, predictor, lattice);
    const double bits = range_coded(coder) ? format::ranged_residual_bits(residuals, lattice) : estimated_bits(residuals);
    if (bits < best.bits) best = {predictor, std::move(residuals), bits};
  }
  return best;
}

// Field coding 3's predictors: 2 bits per array, array a's at bits 2a and 2a + 1.
constexpr int kPackedPredictorBits = 2;
static_assert(format::kSpatialPredictorCount <= (1 << kPackedPredictorBits) && kKeyframeArrays * kPackedPredictorBits <= 32);

// Array a's spatial predictor p as read, or kCorrupt where it is none this array can have.
format::SpatialPredictor checked_predictor(size_t a, uint8_t p, size_t length, const GridFacts& grid, const std::string& where) {
  const auto predictor = static_cast<format::SpatialPredictor>(p);
  if (p >= format::kSpatialPredictorCount || (format::uses_lattice(predictor) && lattice_of(a, length, grid) == nullptr)) {
    corrupt(where, "array " + std::to_string(a) + " has predictor " + std::to_string(p) + ", not one for that array");
  }
  return predictor;
}

// A decoded keyframe's arrays from its residuals: the spatial predictors undone, then the previous
// keyframe's `codes` added where the reference says so. `codes` holds this keyframe's on return.
std::vector<std::vector<double>> arrays_from_residuals(const std::vector<std::vector<int64_t>>& residuals, const std::vector<format::SpatialPredictor>& predictors,
                                                       uint8_t reference, std::vector<std::vector<int32_t>>& codes, const Header& h, const std::string& where) {
  const std::shared_ptr<const GridFacts> grid_held = grid_facts(h.shape.grid_n);
  const GridFacts& grid = *grid_held;
  const std::vector<double>& steps = h.metadata.field_coding.steps;
  std::vector<std::vector<double>> arrays(kKeyframeArrays);
  std::vector<std::vector<int32_t>> these(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    these[a] = format::codes_from_residuals(residuals[a], predictors[a], lattice_of(a, residuals[a].size(), grid), where);
    for (size_t i = 0; i < these[a].size(); ++i) {
      const int64_t code = reference == kFromPreviousKeyframe ? int64_t{these[a][i]} + codes[a][i] : int64_t{these[a][i]};
      if (code <= -kMaxFieldCode || code >= kMaxFieldCode) corrupt(where, "a field code beyond 2^30");
      these[a][i] = static_cast<int32_t>(code);
    }
    arrays[a].resize(these[a].size());
    for (size_t i = 0; i < these[a].size(); ++i) arrays[a][i] = steps[a] * these[a][i];
  }
  codes = std::move(these);
  return arrays;
}

// A keyframe's arrays as integer multiples of the coding's steps.
std::vector<std::vector<int32_t>> field_codes(const Keyframe& key, const FieldCoding& coding) {
  const std::vector<std::vector<double>> arrays = keyframe_arrays(key);
  std::vector<std::vector<int32_t>> codes(kKeyframeArrays);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    for (double v : arrays[a]) codes[a].push_back(field_code(v, coding.steps[a]));
  }
  return codes;
}

// How a keyframe's codes are predicted: from nothing or the previous keyframe's, and each array
// under its own spatial predictor, with the residuals that leaves.
struct Prediction {
  uint8_t reference = kIntra;
  std::vector<CodedArray> arrays;
};

// `codes`: this keyframe's integer codes, array by array; `previous`: the previous keyframe's, or
// null where this keyframe must be intra. Intra and predicted alike: each array's codes, or their
// change since the previous keyframe, under the spatial predictor that leaves the fewest bits. The
// reference that costs less wins.
Prediction choose_prediction(const std::vector<std::vector<int32_t>>& codes, const std::vector<std::vector<int32_t>>* previous, const GridFacts& grid,
                             FieldCoding::Residuals coder) {
  auto code_all = [&](bool from_previous) {
    std::vector<CodedArray> out;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      std::vector<int32_t> values = codes[a];
      if (from_previous) {
        for (size_t i = 0; i < values.size(); ++i) values[i] -= (*previous)[a][i];  // |codes| < 2^30: no overflow
      }
      out.push_back(best_prediction(values, lattice_of(a, values.size(), grid), coder));
    }
    return out;
  };
  auto total_bits = [](const std::vector<CodedArray>& arrays) {
    double bits = 0;
    for (const CodedArray& a : arrays) bits += a.bits;
    return bits;
  };
  Prediction chosen{kIntra, code_all(false)};
  if (previous) {
    std::vector<CodedArray> predicted = code_all(true);
    if (total_bits(predicted) < total_bits(chosen.arrays)) chosen = {kFromPreviousKeyframe, std::move(predicted)};
  }
  return chosen;
}

// One KEYP chunk's payload (field codings 1-3). `models`: field coding 3's range coder models as
// the previous keyframe's stream left them (empty before the first), and as this one's leaves them.
std::vector<uint8_t> write_predicted_keyframe(const Keyframe& key, uint32_t number, const std::vector<std::vector<int32_t>>& codes,
                                              const std::vector<std::vector<int32_t>>* previous, const GridFacts& grid, FieldCoding::Residuals coder,
                                              std::vector<format::ResidualModels>& models) {
  auto [reference, coded] = choose_prediction(codes, previous, grid, coder);
  ByteWriter w;
  write_keyframe_preamble(w, key, number, chained(coder));
  w.write(reference);
  // Field coding 1 repeats every array's length, which the header already fixes; 2 and 3 do not.
  if (!range_coded(coder)) w.write(static_cast<uint32_t>(kKeyframeArrays));
  std::vector<std::vector<int64_t>> residuals;
  uint32_t packed = 0;
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (!range_coded(coder)) w.write(static_cast<uint32_t>(codes[a].size()));
    if (chained(coder)) {
      packed |= static_cast<uint32_t>(coded[a].predictor) << (kPackedPredictorBits * a);
    } else {
      w.write(static_cast<uint8_t>(coded[a].predictor));
    }
    residuals.push_back(std::move(coded[a].residuals));
  }
  if (chained(coder)) w.write(packed);
  const std::vector<const format::LatticeNeighbours*> lattices = lattices_of(lengths_of(residuals), grid);
  // Field coding 3 continues the previous keyframe's models where this one is coded from it (a
  // player decodes that keyframe first anyway), and starts fresh where it is intra.
  if (reference == kIntra) models.clear();
  const std::vector<uint8_t> stream = !range_coded(coder) ? format::encode_residual_stream(residuals)
                                      : format::encode_ranged_residuals(residuals, lattices, kRangeModelSets, chained(coder) ? &models : nullptr);
  w.write(static_cast<uint32_t>(stream.size()));
  w.bytes(stream);
  return w.take();
}

// Reads keyframe `number`; `codes` and `models` hold the previous keyframe's codes and its stream's
// models (field coding 3) on entry (empty for the first) and this one's on return.
Keyframe read_predicted_keyframe(std::span<const uint8_t> payload, const std::string& where, const Header& h, uint32_t number,
                                 std::vector<std::vector<int32_t>>& codes, std::vector<format::ResidualModels>& models) {
  ByteReader r(payload, where);
  Keyframe key;
  const FieldCoding::Residuals coder = h.metadata.field_coding.residuals;
  read_keyframe_preamble(r, key, where, number, chained(coder));
  const uint8_t reference = r.read<uint8_t>("the reference");
  if (reference != kIntra && reference != kFromPreviousKeyframe) corrupt(where, "unknown reference " + std::to_string(reference));
  const FieldCoding& coding = h.metadata.field_coding;
  if (reference == kFromPreviousKeyframe && (coding.intra(number) || codes.empty())) {
    corrupt(where, "keyframe " + std::to_string(number) + " refers to the previous one, but the intra period is " + std::to_string(coding.intra_period));
  }
  if (!range_coded(coder)) {
    const uint32_t count = r.read<uint32_t>("the array count");
    if (count != kKeyframeArrays) corrupt(where, std::to_string(count) + " arrays, " + std::to_string(kKeyframeArrays) + " expected");
  }
  const std::vector<size_t> expected = expected_lengths(h);
  const std::shared_ptr<const GridFacts> grid_held = grid_facts(h.shape.grid_n);
  const GridFacts& grid = *grid_held;
  std::vector<format::SpatialPredictor> predictors(kKeyframeArrays);
  const uint32_t packed = chained(coder) ? r.read<uint32_t>("the predictors") : 0;
  if ((packed >> (kPackedPredictorBits * kKeyframeArrays)) != 0) corrupt(where, "unused predictor bits are set");
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    if (!range_coded(coder)) {
      const uint32_t length = r.read<uint32_t>("an array length");
      if (length != expected[a]) {
        corrupt(where, "array " + std::to_string(a) + " holds " + std::to_string(length) + " values, " + std::to_string(expected[a]) + " expected");
      }
    }
    constexpr uint32_t kPredictorMask = (1u << kPackedPredictorBits) - 1;
    const uint8_t p = chained(coder) ? static_cast<uint8_t>((packed >> (kPackedPredictorBits * a)) & kPredictorMask) : r.read<uint8_t>("a predictor");
    predictors[a] = checked_predictor(a, p, expected[a], grid, where);
  }
  const uint32_t coded = r.read<uint32_t>("the coded size");
  const auto stream = r.bytes(coded, "the coded residuals");
  const std::vector<const format::LatticeNeighbours*> lattices = lattices_of(expected, grid);
  if (reference == kIntra) models.clear();
  const std::vector<std::vector<int64_t>> residuals =
      !range_coded(coder) ? format::decode_residual_stream(stream, expected, where)
                          : format::decode_ranged_residuals(stream, expected, lattices, kRangeModelSets, where, chained(coder) ? &models : nullptr);
  // Bytes after the residuals were appended by a later minor version: ignored.
  set_keyframe_arrays(key, arrays_from_residuals(residuals, predictors, reference, codes, h, where), h, where);
  return key;
}

// ---- A group of keyframes (KGOP, field coding 4): an intra period in one range-coded stream ----

// The models a group's stream adapts, fresh at its start and carried through its keyframes.
struct GroupModels {
  format::BitModel reference;                                           // 1: from the previous keyframe
  std::array<std::array<format::BitModel, 3>, kKeyframeArrays> predictor;  // the high bit's, then the low bit's under each high bit
  std::array<format::NumberModels, 2> pose;                             // the rotation vector's components, the translation's
  std::vector<format::ResidualModels> residuals;
};

constexpr size_t kPoseCodes = 6;  // the rotation vector, then the translation
using PoseCodes = std::array<int64_t, kPoseCodes>;

size_t pose_model(size_t component) { return component < 3 ? 0 : 1; }

PoseCodes pose_codes(const RigidPose& pose, const FieldCoding& coding) {
  const Vec3 rotation = rotation_log(pose.rotation);
  PoseCodes codes{};
  for (int k = 0; k < 3; ++k) {
    const double r = std::nearbyint(rotation[k] / coding.rotation_step), t = std::nearbyint(pose.translation[k] / coding.translation_step);
    if (!(std::abs(r) < static_cast<double>(kMaxPoseCode)) || !(std::abs(t) < static_cast<double>(kMaxPoseCode))) {
      throw Error(ErrorCode::kInvalidArgument, "a pose more than 2^40 pose steps from the origin (translation " + std::to_string(pose.translation[k]) + ")");
    }
    if (std::abs(coding.rotation_step * r) > kMaxRotationComponent) {
      throw Error(ErrorCode::kInvalidArgument, "a rotation step of " + std::to_string(coding.rotation_step) + " rad rounds a rotation vector beyond 4");
    }
    codes[static_cast<size_t>(k)] = static_cast<int64_t>(r);
    codes[static_cast<size_t>(3 + k)] = static_cast<int64_t>(t);
  }
  return codes;
}

RigidPose pose_of(const PoseCodes& codes, const FieldCoding& coding) {
  RigidPose pose;
  const auto c = [&](size_t i) { return static_cast<double>(codes[i]); };
  pose.rotation = rotation_exp(Vec3(coding.rotation_step * c(0), coding.rotation_step * c(1), coding.rotation_step * c(2)));
  pose.translation = Vec3(coding.translation_step * c(3), coding.translation_step * c(4), coding.translation_step * c(5));
  return pose;
}

// Keyframes first .. first + count - 1 of `s`, as a KGOP payload (spec/container.md §7.5).
std::vector<uint8_t> write_keyframe_group(const Sequence& s, size_t first, size_t count, const FieldCoding& coding, const GridFacts& grid) {
  ByteWriter w;
  w.write(static_cast<uint32_t>(first));
  format::RangedStreamWriter stream;
  GroupModels models;
  std::vector<std::vector<int32_t>> previous;
  PoseCodes previous_pose{};
  std::vector<const format::LatticeNeighbours*> lattices;  // the same for every keyframe (validate_sequence)
  for (size_t j = 0; j < count; ++j) {
    const Keyframe& key = s.keyframes[first + j];
    std::vector<std::vector<int32_t>> codes = field_codes(key, coding);
    if (j == 0) lattices = lattices_of(lengths_of(codes), grid);
    Prediction prediction = choose_prediction(codes, j > 0 ? &previous : nullptr, grid, coding.residuals);
    if (j > 0) stream.decision(models.reference, prediction.reference == kFromPreviousKeyframe);
    std::vector<std::vector<int64_t>> residuals;
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      if (!codes[a].empty()) {
        const auto p = static_cast<unsigned>(prediction.arrays[a].predictor);
        stream.decision(models.predictor[a][0], (p >> 1) != 0);
        stream.decision(models.predictor[a][1 + (p >> 1)], (p & 1) != 0);
      }
      residuals.push_back(std::move(prediction.arrays[a].residuals));
    }
    const PoseCodes pose = pose_codes(key.pose, coding);
    for (size_t i = 0; i < kPoseCodes; ++i) stream.number(models.pose[pose_model(i)], pose[i] - previous_pose[i]);
    stream.residual_arrays(residuals, lattices, kRangeModelSets, models.residuals);
    previous = std::move(codes);
    previous_pose = pose;
  }
  w.bytes(stream.finish());
  return w.take();
}

// Reads the KGOP payload of keyframes first .. first + count - 1 (their times are the index's), the
// first `decoded` of them (the stream's end is checked when that is all), handing each to
// `take(j, key, end)` as it is decoded, with `end` where its part of the stream ended from the
// payload's start. One keyframe is held at a time: a group's count alone allocates nothing.
void read_keyframe_group(std::span<const uint8_t> payload, const std::string& where, const Header& h, uint32_t first, uint32_t count, uint32_t decoded,
                         const std::function<void(uint32_t, Keyframe&&, uint64_t)>& take) {
  ByteReader r(payload, where);
  if (r.read<uint32_t>("the first keyframe number") != first) corrupt(where, "holds another group of keyframes than the index says");
  const size_t stream_start = payload.size() - r.remaining();
  format::RangedStreamReader stream(r.bytes(r.remaining(), "the stream"), where);
  const FieldCoding& coding = h.metadata.field_coding;
  const std::vector<size_t> expected = expected_lengths(h);
  const std::shared_ptr<const GridFacts> grid_held = grid_facts(h.shape.grid_n);
  const GridFacts& grid = *grid_held;
  const std::vector<const format::LatticeNeighbours*> lattices = lattices_of(expected, grid);
  GroupModels models;
  std::vector<std::vector<int32_t>> codes;
  PoseCodes pose{};
  for (uint32_t j = 0; j < decoded; ++j) {
    const std::string keyframe_where = where + " (keyframe " + std::to_string(first + j) + ")";
    Keyframe key;
    const uint8_t reference = j > 0 && stream.decision(models.reference) ? kFromPreviousKeyframe : kIntra;
    std::vector<format::SpatialPredictor> predictors(kKeyframeArrays, format::SpatialPredictor::kNone);
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      if (expected[a] == 0) continue;
      const bool high = stream.decision(models.predictor[a][0]);
      const bool low = stream.decision(models.predictor[a][high ? 2 : 1]);
      predictors[a] = checked_predictor(a, static_cast<uint8_t>(2 * high + low), expected[a], grid, keyframe_where);
    }
    for (size_t i = 0; i < kPoseCodes; ++i) {
      pose[i] += stream.number(models.pose[pose_model(i)]);  // both below 2^42: no overflow
      if (pose[i] <= -kMaxPoseCode || pose[i] >= kMaxPoseCode) corrupt(keyframe_where, "a pose code beyond 2^40");
    }
    for (size_t k = 0; k < 3; ++k) {
      if (std::abs(coding.rotation_step * static_cast<double>(pose[k])) > kMaxRotationComponent) corrupt(keyframe_where, "a rotation vector component beyond 4");
    }
    key.pose = pose_of(pose, coding);
    check_translation(key.pose, keyframe_where);
    const std::vector<std::vector<int64_t>> residuals = stream.residual_arrays(expected, lattices, kRangeModelSets, models.residuals);
    set_keyframe_arrays(key, arrays_from_residuals(residuals, predictors, reference, codes, h, keyframe_where), h, keyframe_where);
    take(j, std::move(key), stream_start + stream.position());
  }
  if (decoded == count) stream.expect_end();
}

std::vector<uint8_t> write_texture(const Image& texture, uint32_t number, TextureCodec codec, int quality) {
  ByteWriter w;
  w.write(number);
  w.write(stored_texture_codec(codec, quality) == TextureCodec::kAvif ? kTextureAvif : kTextureWebp);
  w.bytes(encode_texture(codec, texture, quality));
  return w.take();
}

Image read_texture(std::span<const uint8_t> payload, const std::string& where, uint32_t number, uint32_t size, TextureCodec* codec_read) {
  ByteReader r(payload, where);
  if (r.read<uint32_t>("the keyframe number") != number) corrupt(where, "holds another keyframe's texture than the index says");
  const uint32_t number_of_codec = r.read<uint32_t>("the image codec");
  if (number_of_codec != kTextureWebp && number_of_codec != kTextureAvif) {
    throw Error(ErrorCode::kUnsupported, where + ": image codec " + std::to_string(number_of_codec) + " (this decoder reads WebP, 1, and AVIF, 2)");
  }
  const TextureCodec codec = number_of_codec == kTextureAvif ? TextureCodec::kAvif : TextureCodec::kWebp;
  if (codec_read) *codec_read = codec;
  Image image;
  try {
    // At most the header's M² pixels, from the image's own header before its pixels are decoded.
    image = decode_texture(codec, r.bytes(r.remaining(), "the image"), where, int64_t{size} * size);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kInvalidArgument) throw;
    corrupt(where, std::string("an image larger than the header's texture size: ") + e.what());  // the file's fault, not the caller's
  }
  if (image.width != static_cast<int>(size) || image.height != static_cast<int>(size)) {
    corrupt(where, "a " + std::to_string(image.width) + "x" + std::to_string(image.height) + " texture, the header says " + std::to_string(size));
  }
  return image;
}

}  // namespace

void round_to_field_steps(Keyframe& key, const FieldCoding& coding) {
  check_steps(coding);
  std::vector<std::vector<double>> arrays = keyframe_arrays(key);
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    for (double& v : arrays[a]) v = coding.steps[a] * field_code(v, coding.steps[a]);
  }
  assign_keyframe_arrays(key, std::move(arrays), key.fields.representation, key.fields.grid_n, key.fields.fixed_nodes);
  if (chained(coding.residuals)) key.pose = pose_of(compact_pose(key.pose));
  if (grouped(coding.residuals)) key.pose = pose_of(pose_codes(key.pose, coding), coding);
}

void set_default_pose_steps(FieldCoding& coding, const std::string& units) {
  constexpr double kRotationStep = 1e-5, kTranslationStepMetres = 1e-5;
  const double metres = units == "m" ? 1 : units == "cm" ? 1e-2 : units == "mm" ? 1e-3 : 0;
  if (metres == 0) throw Error(ErrorCode::kInvalidArgument, "units '" + units + "' (m, cm or mm)");
  coding.rotation_step = kRotationStep;
  coding.translation_step = kTranslationStepMetres / metres;
}

std::vector<uint8_t> encode_sequence_file(const Sequence& sequence, const SequenceFileMetadata& metadata) {
  validate_sequence(sequence);
  if (metadata.landmark_names.size() > kMaxLandmarks) throw Error(ErrorCode::kInvalidArgument, "too many landmark names");
  const FieldCoding& coding = metadata.field_coding;
  if (coding.predicted()) check_steps(coding);
  const std::vector<int>& qualities = metadata.keyframe_texture_qualities;
  if (!qualities.empty()) {
    if (qualities.size() != sequence.keyframes.size()) {
      throw Error(ErrorCode::kInvalidArgument, std::to_string(qualities.size()) + " texture qualities for " + std::to_string(sequence.keyframes.size()) + " keyframes");
    }
    for (int q : qualities) {
      if (q < 0 || q > 101) throw Error(ErrorCode::kInvalidArgument, "texture quality " + std::to_string(q) + " outside 0..101");
    }
  }
  const DiskGridShape shape = disk_grid_shape(sequence.grid_n);
  const format::PreparedChunk header = format::prepare_chunk(kHeader, write_header(sequence, metadata, shape), true, 19);
  // Every payload first, so the index can hold the offsets of the chunks after it. `fields[k]`:
  // keyframe k's fields chunk, or for field coding 4 its group's (empty but at a group's first).
  const size_t count = sequence.keyframes.size();
  const size_t group = coding.predicted() && grouped(coding.residuals) ? static_cast<size_t>(coding.intra_period) : 0;
  std::vector<format::PreparedChunk> fields(count), textures;
  std::vector<std::vector<int32_t>> previous_codes;
  std::vector<format::ResidualModels> models;  // field coding 3's, carried from keyframe to keyframe
  for (size_t k = 0; k < count; ++k) {
    const Keyframe& key = sequence.keyframes[k];
    if (group > 0) {
      if (k % group == 0) {
        fields[k] = format::prepare_chunk(kKeyframeGroup, write_keyframe_group(sequence, k, std::min(group, count - k), coding, *grid_facts(sequence.grid_n)), true);
      }
    } else if (coding.predicted()) {
      std::vector<std::vector<int32_t>> codes = field_codes(key, coding);
      const bool intra = coding.intra(k);
      fields[k] = format::prepare_chunk(
          kPredictedKeyframe, write_predicted_keyframe(key, static_cast<uint32_t>(k), codes, intra ? nullptr : &previous_codes, *grid_facts(sequence.grid_n),
                                                       coding.residuals, models),
          true);
      previous_codes = std::move(codes);
    } else {
      fields[k] = format::prepare_chunk(kKeyframe, write_keyframe(key, static_cast<uint32_t>(k)), true);
    }
    if (sequence.has_texture()) textures.push_back(format::prepare_chunk(kTexture, write_texture(key.texture, static_cast<uint32_t>(k), metadata.texture_codec, qualities.empty() ? metadata.texture_quality : qualities[k]), true));
  }
  // The chunks' offsets depend on the index's size, which (compressed, field coding 4) depends on
  // the offsets: the index is laid out again until its size stays put, and stored uncompressed (a
  // size the offsets do not change) in the unlikely case it keeps changing.
  std::vector<IndexEntry> entries(count);
  const auto lay_out = [&](uint64_t index_size) {
    uint64_t offset = format::kPreambleBytes + header.total_size() + index_size;
    for (size_t k = 0; k < count; ++k) {
      entries[k].time = sequence.keyframes[k].time;
      const bool starts_chunk = group == 0 || k % group == 0;
      entries[k].keyframe_offset = starts_chunk ? offset : entries[k - 1].keyframe_offset;
      if (starts_chunk) offset += fields[k].total_size();
      if (!textures.empty()) {
        entries[k].texture_offset = offset;
        offset += textures[k].total_size();
      }
    }
  };
  constexpr int kIndexLayouts = 8;
  format::PreparedChunk index;
  uint64_t index_size = 0;
  for (int layout = 0; layout <= kIndexLayouts; ++layout) {
    lay_out(index_size);
    const int level = group > 0 && layout < kIndexLayouts ? 19 : 0;
    index = format::prepare_chunk(kIndex, write_index(entries, group, sequence.has_texture()), true, level);
    if (index.total_size() == index_size) break;
    index_size = index.total_size();
    if (level == 0) {  // its size does not depend on the offsets: once more with them right
      lay_out(index_size);
      index = format::prepare_chunk(kIndex, write_index(entries, group, sequence.has_texture()), true, 0);
      break;
    }
  }
  format::ContainerWriter writer;
  writer.add(header);
  writer.add(index);
  for (size_t k = 0; k < count; ++k) {
    if (group == 0 || k % group == 0) {
      if (writer.add(fields[k]) != entries[k].keyframe_offset) throw Error(ErrorCode::kNumerical, "container index out of step");
    }
    if (!textures.empty() && writer.add(textures[k]) != entries[k].texture_offset) throw Error(ErrorCode::kNumerical, "container index out of step");
  }
  return writer.finish();
}

// ---- A file opened for reading (opened_file.hpp) ----

struct OpenedFile::State {
  // A file of K keyframes has 2 K + 2 chunks at most before its end chunk: the walk stops at twice
  // that for the largest K allowed (room for chunks a later minor version adds), so that its list
  // of chunks (about 80 bytes each) does not grow with a file padded with empty ones.
  State(std::span<const uint8_t> bytes, std::string source_name, const DecoderLimits& limits)
      : reader(bytes, source_name, 4 * uint64_t{limits.max_keyframes} + 64), source(std::move(source_name)), file_bytes(bytes.size()) {}
  format::ContainerReader reader;
  std::string source;
  uint64_t file_bytes = 0;
  DecoderLimits limits;
  std::optional<Header> header;
  size_t group = 0;  // field coding 4: the intra period, one KGOP chunk per group; else 0
  std::string_view keyframe_type;
  std::vector<IndexEntry> index;
};

OpenedFile::OpenedFile(std::span<const uint8_t> bytes, std::string source, const DecoderLimits& limits, const KeyframesHeld& keyframes_held) {
  check_decoder_limits(limits);
  state_ = std::make_unique<State>(bytes, std::move(source), limits);
  State& s = *state_;
  s.limits = limits;
  const format::ContainerReader& reader = s.reader;
  const std::vector<format::ChunkView>& chunks = reader.chunks();
  if (chunks.size() < 2 || chunks[0].type != kHeader || chunks[1].type != kIndex) {
    corrupt(s.source, "the file does not start with its header and index chunks");
  }
  for (const format::ChunkView& chunk : chunks) {
    const bool known = chunk.type == kHeader || chunk.type == kIndex || chunk.type == kKeyframe || chunk.type == kPredictedKeyframe ||
                       chunk.type == kKeyframeGroup || chunk.type == kTexture;
    if (!known && chunk.critical()) {
      throw Error(ErrorCode::kUnsupported, s.source + ": " + reader.describe(chunk) + " is critical and unknown to this decoder (a newer format?)");
    }
  }
  s.header = read_header(reader.payload(chunks[0], limits.max_memory_bytes), s.source, reader.minor_version(), limits, keyframes_held);
  const Header& header = *s.header;
  const FieldCoding& coding = header.metadata.field_coding;
  const bool predicted = coding.predicted();
  s.group = predicted && grouped(coding.residuals) ? static_cast<size_t>(coding.intra_period) : 0;
  s.keyframe_type = s.group > 0 ? kKeyframeGroup : predicted ? kPredictedKeyframe : kKeyframe;
  s.index = read_index(reader.payload(chunks[1], limits.max_memory_bytes), s.source, header.keyframe_count, s.group, (header.flags & kHasTexture) != 0);
  // Keyframe times: within ±1e9 s, increasing, and at least 1e-9 of their span apart, so that the
  // spline's ratios of intervals stay finite (0, 1e-200, 2e-200, 1 would not).
  const std::vector<IndexEntry>& index = s.index;
  const double span = index.back().time - index.front().time;
  for (size_t k = 0; k < index.size(); ++k) {
    if (std::abs(index[k].time) > kMaxTime) corrupt(s.source, "keyframe " + std::to_string(k) + "'s time is beyond 1e9 s");
    if (k > 0 && !(index[k].time - index[k - 1].time >= kMinKeyframeGap * span && index[k].time > index[k - 1].time)) {
      corrupt(s.source, "keyframe " + std::to_string(k) + "'s time is not at least 1e-9 of the keyframes' span after the previous one");
    }
  }
  // Every entry points at a chunk of its kind, before anything is decoded from it.
  for (size_t k = 0; k < index.size(); ++k) {
    const std::string name = "keyframe " + std::to_string(k);
    const format::ChunkView& chunk = reader.chunk_at(index[k].keyframe_offset, name + "'s index entry");
    if (chunk.type != s.keyframe_type) corrupt(s.source, name + "'s index entry points at a " + chunk.type + " chunk, not " + std::string(s.keyframe_type));
    if (header.flags & kHasTexture) {
      const format::ChunkView& texture = reader.chunk_at(index[k].texture_offset, name + "'s texture entry");
      if (texture.type != kTexture) corrupt(s.source, name + "'s texture entry points at a " + texture.type + " chunk");
    } else if (index[k].texture_offset != 0) {
      corrupt(s.source, name + " has a texture entry in a file without textures");
    }
  }
}

OpenedFile::~OpenedFile() = default;

const std::string& OpenedFile::source() const { return state_->source; }
const Sequence& OpenedFile::shape() const { return state_->header->shape; }
size_t OpenedFile::keyframe_count() const { return state_->index.size(); }
double OpenedFile::keyframe_time(size_t k) const { return state_->index.at(k).time; }
bool OpenedFile::has_texture() const { return (state_->header->flags & kHasTexture) != 0; }
bool OpenedFile::has_holes() const { return (state_->header->flags & kHasHoles) != 0; }
int OpenedFile::texture_size() const { return static_cast<int>(state_->header->texture_size); }

uint64_t OpenedFile::values_per_keyframe() const {
  uint64_t values = 0;
  for (size_t length : expected_lengths(*state_->header)) values += length;
  return values;
}

uint64_t OpenedFile::largest_payload() const {
  uint64_t largest = 0;
  for (const format::ChunkView& chunk : state_->reader.chunks()) {
    if (chunk.type == kKeyframe || chunk.type == kPredictedKeyframe || chunk.type == kKeyframeGroup || chunk.type == kTexture) {
      largest = std::max(largest, chunk.raw_size);
    }
  }
  return largest;
}

size_t OpenedFile::run_length() const {
  const FieldCoding& coding = state_->header->metadata.field_coding;
  return coding.predicted() ? static_cast<size_t>(coding.intra_period) : 1;
}

void OpenedFile::decode_run(size_t first, size_t last, const std::function<void(size_t, Keyframe&&, uint64_t)>& take) const {
  const State& s = *state_;
  const Header& header = *s.header;
  const format::ContainerReader& reader = s.reader;
  const uint64_t budget = s.limits.max_memory_bytes;
  if (first % run_length() != 0 || last < first || last >= s.index.size() || run_of(last) != run_of(first)) {
    throw Error(ErrorCode::kInternal, s.source + ": keyframes " + std::to_string(first) + ".." + std::to_string(last) + " are not one run's");
  }
  if (s.group > 0) {
    const format::ChunkView& chunk = reader.chunk_at(s.index[first].keyframe_offset, "keyframe " + std::to_string(first) + "'s index entry");
    // Stored as it is: its stream is the compression (and the bytes fminfo divides among keyframes).
    if (chunk.compressed()) corrupt(s.source, reader.describe(chunk) + " is compressed; a group's chunk never is");
    const auto count = static_cast<uint32_t>(std::min<size_t>(s.group, s.index.size() - first));
    uint64_t previous_end = 0;
    read_keyframe_group(reader.payload(chunk, budget), s.source + ": " + reader.describe(chunk), header, static_cast<uint32_t>(first), count,
                        static_cast<uint32_t>(last - first + 1), [&](uint32_t j, Keyframe&& key, uint64_t end) {
                          const size_t k = first + j;
                          key.time = s.index[k].time;  // field coding 4 stores it in the index only
                          // The chunk's framing counts with its first keyframe.
                          const uint64_t bytes = end - previous_end + (j == 0 ? chunk.total_size() - chunk.raw_size : 0);
                          previous_end = end;
                          take(k, std::move(key), bytes);
                        });
    return;
  }
  const bool predicted = header.metadata.field_coding.predicted();
  std::vector<std::vector<int32_t>> codes;     // the previous predicted keyframe's
  std::vector<format::ResidualModels> models;  // its range coder models (field coding 3)
  for (size_t k = first; k <= last; ++k) {
    const std::string name = "keyframe " + std::to_string(k);
    const format::ChunkView& chunk = reader.chunk_at(s.index[k].keyframe_offset, name + "'s index entry");
    const std::string where = s.source + ": " + reader.describe(chunk) + " (" + name + ")";
    const auto number = static_cast<uint32_t>(k);
    Keyframe key = predicted ? read_predicted_keyframe(reader.payload(chunk, budget), where, header, number, codes, models)
                             : read_keyframe(reader.payload(chunk, budget), where, header, number);
    if (key.time != s.index[k].time) corrupt(s.source, name + ": its time disagrees with the index");
    take(k, std::move(key), chunk.total_size());
  }
}

Image OpenedFile::decode_texture(size_t k, TextureCodec* codec) const {
  const State& s = *state_;
  const std::string name = "keyframe " + std::to_string(k);
  const format::ChunkView& texture = s.reader.chunk_at(s.index.at(k).texture_offset, name + "'s texture entry");
  return read_texture(s.reader.payload(texture, s.limits.max_memory_bytes), s.source + ": " + s.reader.describe(texture) + " (" + name + ")",
                      static_cast<uint32_t>(k), s.header->texture_size, codec);
}

void OpenedFile::verify_checksums() const { state_->reader.verify(); }

SequenceFileInfo OpenedFile::describe() const {
  const State& s = *state_;
  const Header& header = *s.header;
  SequenceFileInfo info;
  info.major_version = s.reader.major_version();
  info.minor_version = s.reader.minor_version();
  info.file_bytes = s.file_bytes;
  info.grid_hash = header.grid_hash;
  info.grid_rule = static_cast<int>(header.grid_rule);
  info.texture_size = static_cast<int>(header.texture_size);
  info.metadata = header.metadata;
  info.keyframes.resize(s.index.size());
  if (has_texture()) {
    for (size_t k = 0; k < s.index.size(); ++k) info.keyframes[k].texture = s.reader.chunk_at(s.index[k].texture_offset, "a texture entry").total_size();
  }
  for (const format::ChunkView& chunk : s.reader.chunks()) {
    auto it = std::find_if(info.chunks.begin(), info.chunks.end(), [&](const auto& t) { return t.type == chunk.type; });
    if (it == info.chunks.end()) it = info.chunks.insert(info.chunks.end(), {chunk.type, 0, 0, 0});
    ++it->count;
    it->stored_bytes += chunk.total_size();
    it->raw_bytes += chunk.raw_size;
  }
  return info;
}

Sequence decode_sequence_file(std::span<const uint8_t> bytes, const std::string& source, SequenceFileInfo* info, const DecoderLimits& limits) {
  check_decoder_limits(limits);
  if (bytes.size() > limits.max_memory_bytes) {
    throw Error(ErrorCode::kLimit, source + ": " + std::to_string(bytes.size()) + " bytes, over the memory limit of " + std::to_string(limits.max_memory_bytes));
  }
  // Decoded whole: every keyframe is held at once.
  const OpenedFile file(bytes, source, limits, [](uint32_t keyframes, SplineKind) { return uint64_t{keyframes}; });
  Sequence sequence = file.shape();
  std::vector<uint64_t> field_bytes(file.keyframe_count());
  const size_t run = file.run_length();
  for (size_t first = 0; first < file.keyframe_count(); first += run) {
    file.decode_run(first, std::min(first + run, file.keyframe_count()) - 1, [&](size_t k, Keyframe&& key, uint64_t bytes_taken) {
      sequence.keyframes.push_back(std::move(key));
      field_bytes[k] = bytes_taken;
    });
  }
  TextureCodec first_texture_codec = TextureCodec::kWebp;
  if (file.has_texture()) {
    for (size_t k = 0; k < file.keyframe_count(); ++k) sequence.keyframes[k].texture = file.decode_texture(k, k == 0 ? &first_texture_codec : nullptr);
  }
  try {
    validate_sequence(sequence);
  } catch (const Error& e) {
    corrupt(source, e.what());
  }
  if (info) {
    *info = file.describe();
    info->metadata.texture_codec = first_texture_codec;
    for (size_t k = 0; k < field_bytes.size(); ++k) info->keyframes[k].fields = field_bytes[k];
  }
  return sequence;
}

void write_sequence_file(const std::filesystem::path& path, const Sequence& sequence, const SequenceFileMetadata& metadata) {
  format::write_file_atomically(path, encode_sequence_file(sequence, metadata));
}

Sequence read_sequence_file(const std::filesystem::path& path, SequenceFileInfo* info, const DecoderLimits& limits) {
  // The file's size against the budget before its bytes are read.
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path, error);
  if (!error && size > limits.max_memory_bytes) {
    throw Error(ErrorCode::kLimit, path.string() + ": " + std::to_string(size) + " bytes, over the memory limit of " + std::to_string(limits.max_memory_bytes));
  }
  const std::vector<uint8_t> bytes = format::read_file(path);
  return decode_sequence_file(bytes, path.string(), info, limits);
}

}  // namespace facemorph
