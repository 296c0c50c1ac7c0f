// A Sequence written as a .fmv file (spec/container.md): what fmenc writes, and what a player never
// links. The reader is codec/decoder/container/sequence_file.hpp.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "codec/writer/container/texture_group_cache.hpp"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace facemorph {

// The file's bytes (format 2.1; a file without texture groups is what 2.0 wrote). Fields are coded with metadata.field_coding's steps (or,
// where it has none, a 65535th of each array's range; spec/method.md §5.3), textures encoded in metadata.texture_codec at
// metadata.texture_quality (or each at its keyframe_texture_qualities entry; above 100: lossless WebP). Throws kInvalidArgument for a
// sequence validate_sequence rejects, a coding round_to_field_steps does, or per-keyframe qualities that are not one per keyframe in
// 0..101.
std::vector<uint8_t> encode_sequence_file(const Sequence& sequence, const SequenceFileMetadata& metadata);
// The same from a source's keyframes, read one at a time (a group's in order; each texture a few
// times: checked, hashed, coded, and compared with those of the same hash), so that the writer
// holds the chunks it has made, not the sequence: an encoder's
// keyframes may stay in its temporary file until written. Each keyframe is checked as
// validate_sequence checks it (kInvalidArgument naming it), and must carry the outline's time.
std::vector<uint8_t> encode_sequence_file(const KeyframeSource& source, const SequenceFileMetadata& metadata);
// The size of the file encode_sequence_file would make, from its chunks' sizes: no chunk is kept,
// so memory holds one keyframe and one chunk whatever the sequence's length. `coded`: the texture
// groups' payloads are taken from it where it holds them, and kept in it where coded here, for the
// write that follows (write_sequence_file's `coded`): the same bytes, coded once. The cache holds
// every group's payload (the AV1 bytes, kilobytes a group) for as long as its owner keeps it.
uint64_t sequence_file_size(const KeyframeSource& source, const SequenceFileMetadata& metadata, TextureGroupCache* coded = nullptr);

// The same through files: the write is atomic (a temporary name, then a rename), so a failed write
// leaves any previous file untouched. The file is streamed: the chunks wait in a temporary file
// (TMPDIR) until the index is laid out, and only then is the destination's temporary name opened,
// so memory holds one keyframe and one chunk, not the file (and with `coded`, the payloads it
// holds and keeps, as sequence_file_size's). Errors name `path` (kIo for a full disk or a missing
// TMPDIR).
void write_sequence_file(const std::filesystem::path& path, const Sequence& sequence, const SequenceFileMetadata& metadata);
void write_sequence_file(const std::filesystem::path& path, const KeyframeSource& source, const SequenceFileMetadata& metadata,
                         TextureGroupCache* coded = nullptr);

}  // namespace facemorph
