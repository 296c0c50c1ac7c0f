// What a .fmv file says about itself besides the sequence (spec/container.md §5): how it codes its
// keyframes, its textures' codec and coding, the encoder's settings; and the description a reader
// gives of a file. Shared by the reader (codec/decoder/container/sequence_file.hpp) and the writer
// (codec/writer/container/sequence_file_writer.hpp).
#pragma once

#include "codec/core/image/texture_codec.hpp"
#include "codec/core/sequence/sequence.hpp"

#include <cstdint>
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
  std::string encoder;                                      // e.g. "facemorph 0.2.0"; the writer fills it when empty
  std::string settings;                                     // the encoder's settings (JSON text)
  std::vector<std::string> landmark_names;                  // of the capture, for players that show them
  TextureCodec texture_codec = TextureCodec::kAvif;         // the reader reports keyframe 0's
  int texture_quality = 90;                                 // the codec's quality 0..100 (above 100: lossless WebP)
  std::vector<int> keyframe_texture_qualities;              // one per keyframe, in place of texture_quality (the encoder's choice)
  TextureCoding texture_coding = TextureCoding::kSequence;  // lossy AVIF textures only; the reader reports the file's
  FieldCoding field_coding;                                 // the writer's; the reader reports the file's
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
    int against_dictionary = 0;  // of `count`, compressed against the header dictionary (format 2.5)
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
  size_t frame_patches = 0;    // format 2.4's PTCH (spec/container.md §7.5); 0 without
  size_t patch_nodes = 0;      // their moving lattice nodes, all patches together
};

// The keyframe's fields and hole level rounded to the multiples of `coding`'s steps, and its pose
// to multiples of the pose steps: exactly what a file with that coding stores, so an encoder that
// keeps these values decodes from memory what a player decodes from the file. Throws
// kInvalidArgument for steps that are not kKeyframeArrayCount finite positive numbers, pose steps
// that are not finite and positive, or a value more than 2³⁰ steps from 0.
void round_to_field_steps(Keyframe& key, const FieldCoding& coding);

}  // namespace facemorph
