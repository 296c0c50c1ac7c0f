// A Sequence as a .fmv file (spec/container.md): the header, the keyframe index, the fields, pose
// and holes of every keyframe (one chunk per group of keyframes), one texture chunk per keyframe. What fmenc writes, fmdec and
// players read, fminfo describes.
#pragma once

#include "facemorph/image_codec.hpp"
#include "facemorph/keyframe_source.hpp"
#include "facemorph/limits.hpp"
#include "facemorph/sequence.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// The arrays a keyframe stores, in the file's order: scalar_arrays(fields), then the hole level.
inline constexpr size_t kKeyframeArrayCount = kScalarArrayCount + 1;

// How a file codes its keyframes' fields (spec/container.md §7).
struct FieldCoding {
  // Empty: every array in 16-bit fixed point over its own range, as code planes (format 1.0's KEYF).
  // Otherwise one step per keyframe array (kKeyframeArrayCount; any positive value for an array the
  // representation leaves empty): each value is stored as the nearest integer multiple of its step,
  // predicted from the previous keyframe and from its neighbours on G (KEYP, format 1.1 on). The
  // encoder chooses the steps from the error they cause in the decoded surface (field_precision.hpp).
  std::vector<double> steps;
  // Every intra_period-th keyframe (0, P, 2P, ...) is coded without the previous one, so decoding
  // any keyframe needs at most P - 1 others. 1: every keyframe on its own.
  int intra_period = 8;
  // Whether keyframe `keyframe` must be coded without the previous one (it is a multiple of P).
  bool intra(size_t keyframe) const { return keyframe % static_cast<size_t>(intra_period) == 0; }
  // How predicted keyframes are stored (spec/container.md §7.3-7.5):
  //   kRangeCoded: format 1.5's field coding 4, the default. Every intra period's keyframes in one
  //     chunk and one range-coded stream: references and predictors as modelled decisions, the pose
  //     as integer multiples of pose_steps coded as its change from the previous keyframe, the
  //     residuals under adaptive context models carried through the group.
  //   kRangeCodedV14: 1.4's field coding 3, which facemorph 0.6 decoders read: a chunk per
  //     keyframe, models carried from the previous keyframe, the pose as float32.
  //   kRangeCodedV13: 1.3's field coding 2, which facemorph 0.5 decoders read: models fresh in every
  //     keyframe, the pose as float64 matrix and translation.
  //   kZstdVarints: 1.1's field coding 1, which 0.3 and 0.4 decoders read.
  enum class Residuals { kRangeCoded, kRangeCodedV14, kRangeCodedV13, kZstdVarints };
  Residuals residuals = Residuals::kRangeCoded;
  // Field coding 4's pose quantisation: the rotation vector log R in multiples of rotation_step
  // radians, the translation in multiples of translation_step (the capture's units). Both must be
  // set (set_default_pose_steps) where residuals is kRangeCoded; other codings ignore them.
  double rotation_step = 0, translation_step = 0;
  bool predicted() const { return !steps.empty(); }
};

// Field coding 4's pose steps as facemorph's encoder sets them: 10⁻⁵ rad and 10 µm in `units`
// (m, cm or mm), 1.5 µm at the far side of a face for the rotation. Thirty times below the
// smallest geometry error the encoder aims at (0.1% of a ~30 cm diagonal), and 2-3 bytes a
// component where a float32 takes 4 (spec/container.md §7.5). kInvalidArgument for other units.
void set_default_pose_steps(FieldCoding& coding, const std::string& units);

// What a file says about itself besides the sequence.
struct SequenceFileMetadata {
  std::string encoder;                      // e.g. "facemorph 0.2.0"; the writer fills it when empty
  std::string settings;                     // the encoder's settings (JSON text)
  std::vector<std::string> landmark_names;  // of the capture, for players that show them
  TextureCodec texture_codec = TextureCodec::kAvif;  // the reader reports keyframe 0's
  int texture_quality = 90;                 // the codec's quality 0..100 (above 100: lossless WebP)
  std::vector<int> keyframe_texture_qualities;  // one per keyframe, in place of texture_quality (the encoder's choice)
  FieldCoding field_coding;                 // the writer's; the reader reports the file's
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
    // Chunk sizes in the file. Field coding 4 shares a chunk among a group of keyframes: each gets
    // the bytes its part of the stream took (the first also the chunk's framing).
    uint64_t fields = 0, texture = 0;
  };
  std::vector<KeyframeBytes> keyframes;
};

// The keyframe's fields and hole level rounded to the multiples of `coding`'s steps, and its pose as
// the coding stores it (float32 in kRangeCodedV14, multiples of the pose steps in kRangeCoded): exactly what a file with that coding stores,
// so an encoder that keeps these values decodes from memory what a player decodes from the file. Throws kInvalidArgument for steps that are not kKeyframeArrayCount
// finite positive numbers, or a value more than 2³⁰ steps from 0.
void round_to_field_steps(Keyframe& key, const FieldCoding& coding);

// The file's bytes. Fields are coded as metadata.field_coding says (16-bit code planes when it has
// no steps; spec/method.md §5.3), textures encoded in metadata.texture_codec at metadata.texture_quality (or each
// at its keyframe_texture_qualities entry; above 100: lossless WebP). Throws kInvalidArgument for a sequence validate_sequence rejects,
// a coding round_to_field_steps does, or per-keyframe qualities that are not one per keyframe in 0..101.
std::vector<uint8_t> encode_sequence_file(const Sequence& sequence, const SequenceFileMetadata& metadata);

// Reads a file's bytes. Everything is checked before use (checksums, sizes against the header,
// the grid's rule and hash against the one this decoder builds, every keyframe's fields by
// validate_fields, the sequence by validate_sequence). Throws kTruncated, kCorrupt or kUnsupported
// naming `source` and the chunk, kLimit where the file needs more than `limits` allow (checked from
// the sizes it states, before they are allocated; spec/container.md §10).
Sequence decode_sequence_file(std::span<const uint8_t> bytes, const std::string& source, SequenceFileInfo* info = nullptr,
                              const DecoderLimits& limits = kDefaultDecoderLimits);

// Opens a file for decoding on demand (spec/container.md §10.1): the header and index are read, every
// keyframe's fields decoded once in order (their poses are in the fields' streams) and checked, each
// kept only while the cache has room, and every chunk's checksum verified; textures are decoded when
// first asked for. What the source holds then is bounded by limits.max_memory_bytes whatever the
// file's length: the index, a cache of keyframes, and (with a decoder on it) the keyframe surfaces
// its surfaces_kept() allows. Throws as decode_sequence_file; kLimit where the budget does not hold
// the keyframes one frame of the spline blends. A file is mapped (format::MappedFile), not read;
// bytes are copied (they count against the budget) and may be freed at once. `info`: the file's
// description, as decode_sequence_file gives it.
std::shared_ptr<const KeyframeSource> open_sequence_source(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits,
                                                           SequenceFileInfo* info = nullptr);
std::shared_ptr<const KeyframeSource> open_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                           const DecoderLimits& limits = kDefaultDecoderLimits, SequenceFileInfo* info = nullptr);

// The same through files: the write is atomic (a temporary name, then a rename), so a failed write
// leaves any previous file untouched.
void write_sequence_file(const std::filesystem::path& path, const Sequence& sequence, const SequenceFileMetadata& metadata);
Sequence read_sequence_file(const std::filesystem::path& path, SequenceFileInfo* info = nullptr, const DecoderLimits& limits = kDefaultDecoderLimits);

}  // namespace facemorph
