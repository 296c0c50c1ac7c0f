// What the readers and writers of a .fmv file's chunks share (spec/container.md, format 2.0): the
// chunk types, the bounds a file's numbers must keep, the header as read, the index entries and the
// grid facts the keyframe coding predicts along. The readers are the decoder's
// (codec/decoder/container/chunk_readers.hpp), the writers the writer's
// (codec/writer/container/chunk_writers.hpp).
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/image/texture_codec.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/level_predictor.hpp"
#include "format/spatial_predictor.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace facemorph::file_layout {

// KGLV (format 2.6): a group of keyframes as KGOP, whose lattice arrays may also have the levels
// predictor (spec/container.md §7.2); a chunk type of its own so that a 2.5 decoder refuses it by name.
inline constexpr std::string_view kHeaderChunk = "HEAD", kIndexChunk = "KIDX", kKeyframeGroupChunk = "KGOP", kLevelsGroupChunk = "KGLV",
                                  kTextureChunk = "TEXR", kTextureGroupChunk = "TGOP", kResidualChunk = "RSDW", kPatchChunk = "PTCH";

inline constexpr uint16_t kLevelsMinorVersion = 6;  // the first with KGLV

// The header's flags. kTextureGroups (format 2.1): the textures are one TGOP chunk per group of
// keyframes, not one TEXR per keyframe. kSharedTextures (format 2.2): one TEXR per keyframe, but
// keyframes that show the same texture name the same TEXR, stored once (never with groups).
inline constexpr uint8_t kHasTexture = 1, kHasHoles = 2, kTextureGroups = 4, kSharedTextures = 8;
inline constexpr uint32_t kMaxKeyframes = 1u << 20;
inline constexpr uint32_t kMaxIntraPeriod = 1u << 20;
inline constexpr uint32_t kMaxStringBytes = 1u << 20;
inline constexpr uint32_t kMaxLandmarks = 1u << 16;
// Every string of the header together (units, encoder, settings, landmark names; §5): each within
// kMaxStringBytes, all within this, so that 65536 names of 1 MiB cannot ask for 64 GiB.
inline constexpr uint64_t kMaxHeaderStringBytes = uint64_t{4} << 20;
// What a later minor version may append to the header or the index (§12.1) and this decoder skips:
// bounded, so that a chunk cannot make a reader decompress bytes it then ignores.
inline constexpr uint64_t kMaxAppendedBytes = uint64_t{64} << 10;
inline constexpr int kMaxTextureSize = 16384;
inline constexpr size_t kKeyframeArrays = kKeyframeArrayCount;  // the fields' arrays, then the hole level
inline constexpr int64_t kMaxFieldCode = int64_t{1} << 30;      // |code| bound: differences of codes fit 32 bits
inline constexpr double kMaxRotationComponent = 4;              // > π: a rotation vector log R is within it
inline constexpr int64_t kMaxPoseCode = int64_t{1} << 40;       // pose codes: changes fit 42 bits
// Ranges a file may state (spec/container.md §5, §6): within them every product the decoder forms
// (a pose applied to a point, a spline's powers of time ratios) is a finite double.
inline constexpr double kMaxCoordinate = 1e9;  // |pose centre|, |translation| in the file's units (1000 km in mm)
inline constexpr double kMaxTime = 1e9;        // |a time|, seconds (31 years)
inline constexpr double kMinFrameRate = 1e-6, kMaxFrameRate = 1e6;
inline constexpr double kMinKeyframeGap = 1e-9;
// |a hole level| (§7.1, array 13): a distance on the unit disk, which the encoder caps at
// kHoleLevelBand outside the holes; 8 disk diameters leave room and keep every blend of them finite.
inline constexpr double kMaxHoleLevel = 16;  // keyframe times at least this fraction of their span apart

// A signed integer as a zigzag LEB128 varint (v >= 0 -> 2v, v < 0 -> -2v - 1; 7 bits a byte, low
// first, the high bit on all but the last): the index's pose changes (§6) and the residual frames
// (§7.4). At most kMaxVarintBytes bytes, so |value| < 2^41; a longer one is corrupt.
inline constexpr int kMaxVarintBytes = 6;
void write_varint(format::ByteWriter& w, int64_t value);
int64_t read_varint(format::ByteReader& r, const char* what);

[[noreturn]] inline void corrupt(const std::string& where, const std::string& what) {
  throw Error(ErrorCode::kCorrupt, where + ": " + what);
}
[[noreturn]] inline void over_limit(const std::string& where, const std::string& what) {
  throw Error(ErrorCode::kLimit, where + ": " + what);
}

// A float64 the file states, which must be finite.
double read_finite(format::ByteReader& r, const char* what);

// The numbers the file uses for enumerations (§5, §8) stand in each enumeration's one table, beside
// its names: kRepresentations, kSplineKinds, kTextureCodecs (code_of, enum_of: enum_names.hpp).

// The format's number for a TGOP's AVIF image sequence, after its first keyframe (§8.1); a TEXR
// still's codec numbers are kTextureCodecs'.
inline constexpr uint32_t kTextureAvifSequence = 3;
inline constexpr size_t kTextureGroupPreambleBytes = 8;

// ---- The header (HEAD, header_chunk.cpp) ----

struct FileHeader {
  DecoderLimits limits;  // the caller's: what the file may make the decoder allocate
  Sequence shape;        // every field but the keyframes
  uint32_t keyframe_count = 0;
  uint32_t grid_rule = 0;
  uint64_t grid_hash = 0;
  uint8_t flags = 0;
  uint32_t texture_size = 0;
  std::vector<int32_t> fixed_nodes;
  SequenceFileMetadata metadata;  // with the field coding
  bool has_texture() const { return (flags & kHasTexture) != 0; }
  bool has_holes() const { return (flags & kHasHoles) != 0; }
  bool texture_groups() const { return (flags & kTextureGroups) != 0; }
  bool shared_textures() const { return (flags & kSharedTextures) != 0; }
  // One KGOP chunk per intra period.
  size_t group_size() const { return static_cast<size_t>(metadata.field_coding.intra_period); }
  size_t group_count() const { return (keyframe_count + group_size() - 1) / group_size(); }
};

// What each array of a keyframe must hold (§7.1), from the header alone.
std::vector<size_t> expected_lengths(int grid_n, Representation representation, size_t fixed, bool with_holes);
std::vector<size_t> expected_lengths(const FileHeader& h);

// What an AV1 decoder holds while it decodes a group's texture sequence of M x M frames (§10.1):
// up to 8 reference frames and the frame it decodes, each 8-bit YUV 4:4:4 (3 M² bytes).
inline uint64_t texture_sequence_decoder_bytes(uint64_t texture_size) { return 9 * 3 * texture_size * texture_size; }

// How many keyframes the caller holds at once for a keyframe count and spline: for the memory
// estimate checked from the header (§10.1).
using KeyframesHeld = std::function<uint64_t(uint32_t keyframes, SplineKind spline)>;

// How a file's textures are laid out: one TEXR per keyframe (stills), TEXR chunks that keyframes
// share (flag bit 3, format 2.2), or one TGOP per group (flag bit 2, format 2.1).
enum class TextureLayout { kStills, kSharedStills, kGroups };

// ---- The pose as the file stores it: integer multiples of the header's pose steps ----

inline constexpr size_t kPoseCodes = 6;  // the rotation vector log R, then the translation
using PoseCodes = std::array<int64_t, kPoseCodes>;
// Throws kInvalidArgument for a pose beyond 2⁴⁰ steps or a rotation step that rounds it beyond 4.
PoseCodes pose_codes(const RigidPose& pose, const FieldCoding& coding);
RigidPose pose_of(const PoseCodes& codes, const FieldCoding& coding);

// ---- The index (KIDX, index_chunk.cpp) ----

struct IndexEntry {
  double time = 0;
  PoseCodes pose{};
  uint64_t group_offset = 0;  // the KGOP chunk of the keyframe's group
  uint64_t texture_offset =
      0;  // its TEXR chunk (shared with other keyframes where flag bit 3 is set), or its group's TGOP chunk; 0 without textures
};

// ---- Residual frames (RSDW, residual_chunk.cpp; format 2.3) ----

// Times are whole 64ths of a frame period from the capture's first frame; below 2^52 a double holds
// every such count exactly.
inline constexpr int64_t kMaxTimeCode = int64_t{1} << 52;

// The largest correction code for step 2^-e: kMaxResidualDelta / 2^-e.
inline int64_t max_code(int e) { return static_cast<int64_t>(std::ldexp(kMaxResidualDelta, e)); }

// The most residual frames a file may state: more than any capture has frames between keyframes
// (a day at 120 fps), so that their count bounds what reading them allocates.
inline constexpr uint32_t kMaxResiduals = 1u << 24;
// Corrections are multiples of 2^-e, e <= this.
inline constexpr int kMaxResidualStepExponent = 30;
// What the budget charges for one residual frame (§10.1): a fixed 64 bytes on every platform, so
// that a file is accepted or refused alike everywhere. It is what one holds on a 64-bit platform
// (its time, the vector and up to 4 corrections); in WebAssembly (32-bit) it holds 56.
inline constexpr uint64_t kResidualMemoryBytes = 64;
static_assert(sizeof(ResidualFrame) + 4 * sizeof(double) <= kResidualMemoryBytes, "the charge is below what a residual frame holds");

// ---- Frame patches (PTCH, patch_chunk.cpp; format 2.4) ----

// The most patches a file may state (kMaxResiduals' reason), and what the budget charges for one
// before its nodes, and for each node (its index and displacement) (§10.1): fixed, 64 and 28 bytes
// on every platform, so that a file is accepted or refused alike everywhere. They are what a patch
// and a node hold on a 64-bit platform; in WebAssembly (32-bit) a patch holds 40 bytes.
inline constexpr uint32_t kMaxPatches = 1u << 24;
inline constexpr uint64_t kPatchMemoryBytes = 64;
inline constexpr uint64_t kPatchNodeMemoryBytes = 28;
static_assert(sizeof(FramePatch) <= kPatchMemoryBytes, "the charge is below what a patch holds");
static_assert(sizeof(int32_t) + sizeof(Vec3) <= kPatchNodeMemoryBytes, "the charge is below what a patch's node holds");
// Displacements are whole multiples of 2^e, e within these (2^-60 of a metre is far below any
// capture's precision, 2^30 far above any face); codes within 2^40, the varint's bound (§6).
inline constexpr int kMinPatchStepExponent = -60, kMaxPatchStepExponent = 30;
inline constexpr double kMaxPatchCode = 1099511627776.0;  // 2^40
// From format 2.5 the chunk is one range-coded stream (§7.5.1), whose codes stay within the
// residual coder's 2^34. Each patch codes at least 9 decisions, each at least 0.0124 bits (the
// models' bounds, §7.3), so a stream of S bytes holds at most 72 S patches.
inline constexpr uint16_t kRangedPatchMinorVersion = 5;
inline constexpr double kMaxRangedPatchCode = 17179869184.0;  // 2^34
inline constexpr uint64_t kMaxRangedPatchesPerByte = 72;

// ---- G's lattice, along which the keyframe coding predicts (grid_facts.cpp) ----

// What the container needs of G for N: its hash, and the lattice neighbours its predicted arrays
// use (interior nodes row by row; the hole level's rim nodes follow, each after the one before it).
struct GridFacts {
  int n = 0;
  uint64_t hash = 0;
  format::LatticeNeighbours interior, all_nodes;
  format::LevelOrder interior_levels;  // the levels predictor's order of the interior nodes (format 2.6)
};
// Built once per N; one N kept (a player opens files of one grid, an encoder writes one), so memory
// never grows with the grids a process has seen. The caller holds what it uses.
std::shared_ptr<const GridFacts> grid_facts(int n);

// ---- A group of keyframes (KGOP, keyframe_group_chunk.cpp) ----

// A keyframe's arrays in the file's order (§7.1): scalar_arrays(fields), then the hole level.
std::vector<std::vector<double>> keyframe_arrays(const Keyframe& key);
void assign_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, Representation representation, int grid_n,
                            std::vector<int32_t> fixed_nodes);
// A value as an integer multiple of `step`; kInvalidArgument beyond 2³⁰ steps.
int32_t field_code(double value, double step);
// kInvalidArgument unless the coding has kKeyframeArrays finite positive steps, an intra period in
// [1, 2²⁰] and finite positive pose steps.
void check_field_coding(const FieldCoding& coding);

}  // namespace facemorph::file_layout
