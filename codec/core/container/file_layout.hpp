// What the readers and writers of a .fmv file's chunks share (spec/container.md, format 2.0): the
// chunk types, the bounds a file's numbers must keep, the header as read, the index entries and the
// grid facts the keyframe coding predicts along. Internal to the decoder library: each chunk's
// reader and writer is a file of its own (header_chunk, index_chunk, keyframe_group_chunk,
// texture_chunk); sequence_file.cpp puts them together.
#pragma once

#include "format/error.hpp"
#include "codec/decoder/image/image_codec.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/container/decoder_limits.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/container.hpp"
#include "format/spatial_predictor.hpp"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace facemorph::file_layout {

inline constexpr std::string_view kHeaderChunk = "HEAD", kIndexChunk = "KIDX", kKeyframeGroupChunk = "KGOP", kTextureChunk = "TEXR",
                                  kTextureGroupChunk = "TGOP", kResidualChunk = "RSDW";

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
inline constexpr int64_t kMaxFieldCode = int64_t{1} << 30;       // |code| bound: differences of codes fit 32 bits
inline constexpr double kMaxRotationComponent = 4;               // > π: a rotation vector log R is within it
inline constexpr int64_t kMaxPoseCode = int64_t{1} << 40;        // pose codes: changes fit 42 bits
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

[[noreturn]] inline void corrupt(const std::string& where, const std::string& what) { throw Error(ErrorCode::kCorrupt, where + ": " + what); }
[[noreturn]] inline void over_limit(const std::string& where, const std::string& what) { throw Error(ErrorCode::kLimit, where + ": " + what); }

// A float64 the file states, which must be finite.
double read_finite(format::ByteReader& r, const char* what);

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
// The header of a file of the outline's keyframes, all sharing the fixed-frame nodes `fixed`.
std::vector<uint8_t> write_header(const SequenceOutline& s, const std::vector<int32_t>& fixed, const SequenceFileMetadata& metadata, TextureLayout textures);
// Reads and checks a header. `minor_version`: the file's; one this decoder knows (kMinorVersion or
// older) defines every byte of its header, and a byte past its last field is corrupt; a later one
// may append up to kMaxAppendedBytes, which are skipped.
FileHeader read_header(std::span<const uint8_t> payload, const std::string& source, const DecoderLimits& limits, const KeyframesHeld& keyframes_held,
                       uint16_t minor_version);
// The most bytes a header chunk may decompress to (§5, §10.2): its fixed fields, the fixed nodes of
// the largest G that `max_grid_n` allows, the strings within kMaxHeaderStringBytes and the appended
// fields of a later minor version. Checked against the chunk's stated size before it is decompressed.
uint64_t max_header_bytes(int max_grid_n);
// The same for the index of the header's keyframes (§6): times, the pose varints at their longest,
// the offsets, and what a later minor version may append.
uint64_t max_index_bytes(const FileHeader& h);
// A payload that held `remaining` bytes after the fields of its version: corrupt in a file of a
// minor version this decoder knows, skipped up to kMaxAppendedBytes in a later one.
void check_appended_bytes(size_t remaining, uint16_t minor_version, const std::string& where);

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
  uint64_t group_offset = 0;    // the KGOP chunk of the keyframe's group
  uint64_t texture_offset = 0;  // its TEXR chunk (shared with other keyframes where flag bit 3 is set), or its group's TGOP chunk; 0 without textures
};

std::vector<uint8_t> write_index(const std::vector<IndexEntry>& entries, const FileHeader& h);
// Checks the times (bounds, separation) and pose codes (bounds) as it reads; the offsets are the
// caller's to check against the chunks.
std::vector<IndexEntry> read_index(std::span<const uint8_t> payload, const std::string& source, const FileHeader& h, uint16_t minor_version);

// ---- Residual frames (RSDW, residual_chunk.cpp; format 2.3) ----

// The most residual frames a file may state: more than any capture has frames between keyframes
// (a day at 120 fps), so that their count bounds what reading them allocates.
inline constexpr uint32_t kMaxResiduals = 1u << 24;
// Corrections are multiples of 2^-e, e <= this.
inline constexpr int kMaxResidualStepExponent = 30;
// What one residual frame holds in memory (its time, the vector and up to 4 corrections): the
// budget's count of them (§10.1).
inline constexpr uint64_t kResidualMemoryBytes = sizeof(ResidualFrame) + 4 * sizeof(double);
// The payload of the outline's residual frames (not empty): times on the file's lattice
// (residual_time), corrections multiples of a power of two 2^-e (e <= kMaxResidualStepExponent)
// summing to 0 exactly; kInvalidArgument otherwise.
std::vector<uint8_t> write_residuals(const SequenceOutline& outline);
// Reads and checks a payload against the header (first time, fps) and the keyframes' times: every
// check of §7.4, kCorrupt naming the residual; kLimit where their memory passes `max_memory_bytes`.
std::vector<ResidualFrame> read_residuals(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                          const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version);

// ---- Where the chunks after the index go (index_layout.cpp) ----

// A chunk after the index, in file order: its size in the file (header, payload and checksum), and
// the keyframes whose index entries name it, as their group's KGOP or as their texture (a TEXR or
// their group's TGOP).
struct PlacedChunk {
  uint64_t size = 0;
  std::vector<uint32_t> group_of, texture_of;
};
struct IndexLayout {
  format::PreparedChunk index;    // the KIDX chunk, its entries' offsets set
  std::vector<uint64_t> offsets;  // each placed chunk's
  uint64_t end = 0;               // where the end chunk goes
};
// The index of `entries` (their times and poses as given) over `chunks` placed in order after the
// preamble, a header chunk of `header_size` bytes and the index itself. The index's size depends
// on the offsets it holds (it is compressed), so it is laid out again until its size stays put,
// and stored uncompressed (a size the offsets do not change) in the unlikely case it keeps
// changing. kInvalidArgument where a keyframe is named by no group or, in a file with textures, by
// no texture chunk.
IndexLayout lay_out_index(uint64_t header_size, std::vector<IndexEntry>& entries, const FileHeader& h, const std::vector<PlacedChunk>& chunks);

// ---- G's lattice, along which the keyframe coding predicts (grid_facts.cpp) ----

// What the container needs of G for N: its hash, and the lattice neighbours its predicted arrays
// use (interior nodes row by row; the hole level's rim nodes follow, each after the one before it).
struct GridFacts {
  int n = 0;
  uint64_t hash = 0;
  format::LatticeNeighbours interior, all_nodes;
};
// Built once per N; one N kept (a player opens files of one grid, an encoder writes one), so memory
// never grows with the grids a process has seen. The caller holds what it uses.
std::shared_ptr<const GridFacts> grid_facts(int n);

// ---- A group of keyframes (KGOP, keyframe_group_chunk.cpp) ----

// A keyframe's arrays in the file's order (§7.1): scalar_arrays(fields), then the hole level.
std::vector<std::vector<double>> keyframe_arrays(const Keyframe& key);
void assign_keyframe_arrays(Keyframe& key, std::vector<std::vector<double>> arrays, Representation representation, int grid_n, std::vector<int32_t> fixed_nodes);
// A value as an integer multiple of `step`; kInvalidArgument beyond 2³⁰ steps.
int32_t field_code(double value, double step);
// kInvalidArgument unless the coding has kKeyframeArrays finite positive steps, an intra period in
// [1, 2²⁰] and finite positive pose steps.
void check_field_coding(const FieldCoding& coding);

// A group's payload from its keyframes first, first + 1, … given in order (their fields and hole
// levels only: times and poses are the index's), one at a time: what is kept between them is the
// previous keyframe's codes and the range coder's state. `coding` and `grid` outlive the writer;
// every keyframe's arrays have one set of lengths (the caller checks).
class KeyframeGroupWriter {
 public:
  KeyframeGroupWriter(size_t first, const FieldCoding& coding, const GridFacts& grid);
  ~KeyframeGroupWriter();
  KeyframeGroupWriter(const KeyframeGroupWriter&) = delete;
  KeyframeGroupWriter& operator=(const KeyframeGroupWriter&) = delete;
  void add(const Keyframe& key);
  std::vector<uint8_t> finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};
// Reads the fields of a group of `count` keyframes from keyframe `first` on, one keyframe at a
// time, in order, so that a caller may stop between two (a decode call's work limit, §10.3) and go
// on later with the same reader: it holds the payload, the stream's place and models, and the last
// keyframe's codes. `h` must outlive it.
class KeyframeGroupReader {
 public:
  KeyframeGroupReader(std::vector<uint8_t> payload, std::string where, const FileHeader& h, uint32_t first, uint32_t count);
  ~KeyframeGroupReader();
  KeyframeGroupReader(const KeyframeGroupReader&) = delete;
  KeyframeGroupReader& operator=(const KeyframeGroupReader&) = delete;
  // The keyframe of the group read() decodes next (count: none left).
  uint32_t next() const;
  // Decodes keyframe first + next(), charging `work` (null: unbounded) its values first, so that a
  // stop leaves the reader where it was. The key holds the fields and hole level: its fields pass
  // validate_fields and its hole levels are finite and within kMaxHoleLevel (corrupt, naming the
  // keyframe and the node). `end`: where its part of the stream ended from the payload's start.
  Keyframe read(WorkMeter* work, uint64_t& end);
  // After the group's last keyframe: kCorrupt unless the stream ends exactly there.
  void expect_end() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// ---- A texture (TEXR, texture_chunk.cpp) ----

std::vector<uint8_t> write_texture(const Image& texture, uint32_t number, TextureCodec codec, int quality);
// The image codec a TEXR payload names, from its first 8 bytes (kUnsupported for an unknown one).
TextureCodec texture_codec_of(std::span<const uint8_t> payload, const std::string& where, uint32_t number);
Image read_texture(std::span<const uint8_t> payload, const std::string& where, uint32_t number, uint32_t size);

// ---- A group's textures as one AV1 image sequence (TGOP, texture_group_chunk.cpp; format 2.1) ----

// Whether a file with textures (or not: `has_texture`) written with `metadata` stores them in TGOP
// chunks: textures, the sequence coding, AVIF, and every keyframe's quality lossy (≤ 100).
bool uses_texture_groups(bool has_texture, const SequenceFileMetadata& metadata);
// The payload of a group of keyframes' textures from keyframe `first` on, at `quality` (the finest
// of their qualities): the images given in order, one at a time.
class TextureGroupWriter {
 public:
  TextureGroupWriter(size_t first, int quality);
  void add(const Image& texture) { sequence_.add(texture); }
  std::vector<uint8_t> finish();

 private:
  size_t first_;
  AvifSequenceWriter sequence_;
};
// Reads the textures of the group of `count` keyframes starting at `first` one frame at a time, in
// order (KeyframeGroupReader's counterpart: it holds the payload and the AV1 decoder's state), after
// checking the chunk's first keyframe, codec and its image sequence's count and size against the
// container's (corrupt, naming `where`, before any pixel).
class TextureGroupReader {
 public:
  TextureGroupReader(std::vector<uint8_t> payload, const std::string& where, uint32_t first, uint32_t count, uint32_t size);
  // The frame of the group read() decodes next (count: none left).
  uint32_t next() const { return sequence_->next(); }
  // Decodes frame next(): its RGB image where `convert`, else an empty one (every frame is decoded,
  // as later ones are predicted from it).
  Image read(bool convert) { return sequence_->read(convert); }

 private:
  std::vector<uint8_t> payload_;  // the sequence reads it where it lies
  std::unique_ptr<AvifSequenceReader> sequence_;
};
// The bytes of each of the group's keyframes' AV1 samples, in order (fminfo). Throws as TextureGroupReader.
std::vector<uint64_t> texture_group_sample_bytes(std::span<const uint8_t> payload, const std::string& where, uint32_t first, uint32_t count, uint32_t size);

}  // namespace facemorph::file_layout
