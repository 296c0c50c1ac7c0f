// A Sequence as a .fmv file (spec/container.md): the header, the keyframe index, the fields, pose
// and holes of every keyframe (one chunk per group of keyframes), one texture chunk per keyframe. What fmenc writes, fmdec and
// players read, fminfo describes.
#pragma once

#include "codec/decoder/image/image_codec.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/container/decoder_limits.hpp"
#include "codec/core/sequence/sequence.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// The arrays a keyframe stores, in the file's order: scalar_arrays(fields), then the hole level.
inline constexpr size_t kKeyframeArrayCount = kScalarArrayCount + 1;

// How a file codes its keyframes (spec/container.md §5, §6, §7; format 2.0 has one coding).
struct FieldCoding {
  // One step per keyframe array (kKeyframeArrayCount; any positive value for an array the
  // representation leaves empty): each value is stored as the nearest integer multiple of its step,
  // predicted from the previous keyframe and from its neighbours on G, the residuals range-coded.
  // The encoder chooses the steps from the error they cause in the decoded surface
  // (field_precision.hpp). Empty: the writer takes a 65535th of each array's range over the
  // keyframes (16-bit fixed point's precision) and leaves the sequence given unrounded.
  std::vector<double> steps;
  // Every intra_period-th keyframe (0, P, 2P, ...) starts a group coded without the keyframes
  // before it, so decoding any keyframe needs at most P - 1 others. 1: every keyframe on its own.
  int intra_period = 8;
  // The pose in the index: the rotation vector log R in multiples of rotation_step radians, the
  // translation in multiples of translation_step (the capture's units). Both 0: the writer sets
  // set_default_pose_steps's for the sequence's units.
  double rotation_step = 0, translation_step = 0;
  // Whether keyframe `keyframe` starts a group (it is a multiple of P).
  bool intra(size_t keyframe) const { return keyframe % static_cast<size_t>(intra_period) == 0; }
  bool predicted() const { return !steps.empty(); }
};

// The pose steps as facemorph's encoder sets them: 10⁻⁵ rad and 10 µm in `units`
// (m, cm or mm), 1.5 µm at the far side of a face for the rotation. Thirty times below the
// smallest geometry error the encoder aims at (0.1% of a ~30 cm diagonal), and 2-3 bytes a
// component in the index where a float32 takes 4 (spec/container.md §6). kInvalidArgument for other units.
void set_default_pose_steps(FieldCoding& coding, const std::string& units);

// How a file stores lossy AVIF keyframe textures (spec/container.md §8, §8.1). kSequence (format
// 2.1, the writer's default): one AV1 image sequence per group of keyframes (a TGOP chunk), each
// texture predicted from the group's earlier ones, 1.8-5x fewer bytes than stills at equal PSNR.
// kStills: one AVIF still per keyframe (TEXR), as format 2.0. WebP and lossless textures are
// always stills.
enum class TextureCoding { kSequence, kStills };
const char* texture_coding_name(TextureCoding coding);        // "sequence", "stills"
TextureCoding parse_texture_coding(const std::string& name);  // throws kInvalidArgument

// What a file says about itself besides the sequence.
struct SequenceFileMetadata {
  std::string encoder;                      // e.g. "facemorph 0.2.0"; the writer fills it when empty
  std::string settings;                     // the encoder's settings (JSON text)
  std::vector<std::string> landmark_names;  // of the capture, for players that show them
  TextureCodec texture_codec = TextureCodec::kAvif;  // the reader reports keyframe 0's
  int texture_quality = 90;                 // the codec's quality 0..100 (above 100: lossless WebP)
  std::vector<int> keyframe_texture_qualities;  // one per keyframe, in place of texture_quality (the encoder's choice)
  TextureCoding texture_coding = TextureCoding::kSequence;  // lossy AVIF textures only; the reader reports the file's
  FieldCoding field_coding;                 // the writer's; the reader reports the file's
  // The writer's texture layout from these settings alone, not from the bytes each takes: texture
  // groups wherever they apply (lossy AVIF, kSequence), else stills, shared where keyframes show the
  // same pixels. The segments of one encode lay theirs out alike, so that they join (file_join.hpp).
  bool texture_layout_from_settings = false;
};

struct SequenceFileInfo {
  uint16_t major_version = 0, minor_version = 0;
  uint64_t file_bytes = 0;
  uint64_t grid_hash = 0;
  int grid_rule = 0;
  int texture_size = 0;
  SequenceFileMetadata metadata;
  struct ChunkTotal {
    std::string type;
    int count = 0;
    uint64_t stored_bytes = 0;  // as in the file, chunk headers and checksums included
    uint64_t raw_bytes = 0;     // payloads after decompression
  };
  std::vector<ChunkTotal> chunks;  // per type, in order of first appearance
  struct KeyframeBytes {
    // Chunk sizes in the file. A group of keyframes shares a chunk: each gets the bytes its part of
    // the stream took (the first also the chunk's framing); 0 until the fields are decoded
    // (inspect_sequence_file, decode_sequence_file). A group's texture sequence (TGOP) is divided
    // by its frames' AV1 samples, the first keyframe taking the chunk's framing and the AVIF
    // container's own bytes too (a sample that only shows a hidden frame coded in an earlier one,
    // libaom's alternate reference, is a few bytes).
    uint64_t fields = 0, texture = 0;
  };
  std::vector<KeyframeBytes> keyframes;
  // The chunks that hold the keyframes' fields, in order: a group of `count` keyframes from
  // `first` (an intra period), its bytes as stored (framing and checksum included). Known from the
  // index alone, where a keyframe's own share of its group is known only by decoding.
  struct FieldGroup {
    size_t first = 0, count = 0;
    uint64_t bytes = 0;
  };
  std::vector<FieldGroup> field_groups;
  // Textures stored: the keyframe count, or fewer where keyframes share one (format 2.2, whose
  // shared texture's bytes are its first keyframe's); 0 without textures.
  size_t distinct_textures = 0;
  size_t residual_frames = 0;  // format 2.3's RSDW (spec/container.md §7.4); 0 without
};

// The keyframe's fields and hole level rounded to the multiples of `coding`'s steps, and its pose
// to multiples of the pose steps: exactly what a file with that coding stores, so an encoder that
// keeps these values decodes from memory what a player decodes from the file. Throws
// kInvalidArgument for steps that are not kKeyframeArrayCount finite positive numbers, pose steps
// that are not finite and positive, or a value more than 2³⁰ steps from 0.
void round_to_field_steps(Keyframe& key, const FieldCoding& coding);

// The file's bytes (format 2.1; a file without texture groups is what 2.0 wrote). Fields are coded with metadata.field_coding's steps (or, where it
// has none, a 65535th of each array's range; spec/method.md §5.3), textures encoded in metadata.texture_codec at metadata.texture_quality (or each
// at its keyframe_texture_qualities entry; above 100: lossless WebP). Throws kInvalidArgument for a sequence validate_sequence rejects,
// a coding round_to_field_steps does, or per-keyframe qualities that are not one per keyframe in 0..101.
std::vector<uint8_t> encode_sequence_file(const Sequence& sequence, const SequenceFileMetadata& metadata);
// The same from a source's keyframes, read one at a time (a group's in order; each texture a few
// times: checked, hashed, coded, and compared with those of the same hash), so that the writer
// holds the chunks it has made, not the sequence: an encoder's
// keyframes may stay in its temporary file until written. Each keyframe is checked as
// validate_sequence checks it (kInvalidArgument naming it), and must carry the outline's time.
std::vector<uint8_t> encode_sequence_file(const KeyframeSource& source, const SequenceFileMetadata& metadata);
// The size of the file encode_sequence_file would make, from its chunks' sizes: no chunk is kept,
// so memory holds one keyframe and one chunk whatever the sequence's length.
uint64_t sequence_file_size(const KeyframeSource& source, const SequenceFileMetadata& metadata);

// Reads a file's bytes. Everything is checked before use (checksums, sizes against the header,
// the grid's rule and hash against the one this decoder builds, every keyframe's fields by
// validate_fields, the sequence by validate_sequence). Throws kTruncated, kCorrupt or kUnsupported
// naming `source` and the chunk, kLimit where the file needs more than `limits` allow (checked from
// the sizes it states, before they are allocated; spec/container.md §10).
Sequence decode_sequence_file(std::span<const uint8_t> bytes, const std::string& source, SequenceFileInfo* info = nullptr,
                              const DecoderLimits& limits = kDefaultDecoderLimits);

// Opens a file for decoding on demand (spec/container.md §10.1): the header and index are read and
// checked (times, poses, every entry at a chunk of its kind); a keyframe's fields and texture are
// decoded, and their chunks' checksums verified, when first asked for, and kept only while the
// cache has room. A keyframe whose chunk is at fault fails when asked for (kCorrupt naming the
// chunk), and at once every later time. Opening costs what the header and index cost, whatever
// the file's length (inspect_sequence_file checks every keyframe). What the source holds is bounded by limits.max_memory_bytes whatever the
// file's length: the index, a cache of keyframes, and (with a decoder on it) the keyframe surfaces
// its surfaces_kept() allows. Throws as decode_sequence_file; kLimit where the budget does not hold
// the keyframes one frame of the spline blends. A file is mapped (format::MappedFile), not read;
// bytes are copied (they count against the budget) and may be freed at once. `info`: the file's
// description, as decode_sequence_file gives it.
std::shared_ptr<const KeyframeSource> open_sequence_source(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits,
                                                           SequenceFileInfo* info = nullptr);
std::shared_ptr<const KeyframeSource> open_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                           const DecoderLimits& limits = kDefaultDecoderLimits, SequenceFileInfo* info = nullptr);
// The same over bytes the caller keeps, not copied (fm_file_open_memory_borrowed): they must outlive
// the source and every decoder on it. Only the header's and index's chunks and every chunk's 24-byte
// header and 4-byte checksum are read here; a keyframe's chunks when a frame first needs them (and
// their checksums verified then), so a player streaming the file fills those bytes in later,
// before the first decode that needs them (spec/web.md).
std::shared_ptr<const KeyframeSource> open_borrowed_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                                    const DecoderLimits& limits = kDefaultDecoderLimits);

// Checks a whole file as a player would find it, keyframe by keyframe: every keyframe's fields and
// texture decoded once and dropped, every checksum verified, within `limits` (one keyframe held at
// a time). Returns the file's description with every keyframe's bytes (fminfo). Throws as
// decode_sequence_file.
SequenceFileInfo inspect_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits);
// Describes a file from what opening it reads (header and index, checked as §10.2 steps 1-5) and
// verifies every chunk's checksum; decodes no keyframe. Each keyframe's fields bytes are 0 (a
// group's are in field_groups); a texture group's are divided among its frames. Its cost is
// reading the file's bytes once (a few ms a MB), where inspect_sequence_file's is decoding them
// (about 0.4 s a MB at N = 257): what `fminfo` does, `fminfo --verify` the other. Throws as
// open_sequence_source, and kCorrupt naming the first chunk whose checksum does not match.
SequenceFileInfo describe_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits);

// The same through files: the write is atomic (a temporary name, then a rename), so a failed write
// leaves any previous file untouched. The file is streamed: the chunks wait in a temporary file
// (TMPDIR) until the index is laid out, and only then is the destination's temporary name opened,
// so memory holds one keyframe and one chunk, not the file. Errors name `path` (kIo for a full
// disk or a missing TMPDIR).
void write_sequence_file(const std::filesystem::path& path, const Sequence& sequence, const SequenceFileMetadata& metadata);
void write_sequence_file(const std::filesystem::path& path, const KeyframeSource& source, const SequenceFileMetadata& metadata);
Sequence read_sequence_file(const std::filesystem::path& path, SequenceFileInfo* info = nullptr, const DecoderLimits& limits = kDefaultDecoderLimits);

}  // namespace facemorph
