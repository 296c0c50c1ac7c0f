// A .fmv file read (spec/container.md): the header, the keyframe index, the fields, pose and holes
// of every keyframe (one chunk per group of keyframes), the textures. What fmdec and players read,
// fminfo describes; fmenc writes it with codec/writer/container/sequence_file_writer.hpp.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/sequence/sequence.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

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
std::shared_ptr<const KeyframeSource> open_sequence_source(const std::filesystem::path& path,
                                                           const DecoderLimits& limits = kDefaultDecoderLimits,
                                                           SequenceFileInfo* info = nullptr);
std::shared_ptr<const KeyframeSource> open_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                           const DecoderLimits& limits = kDefaultDecoderLimits,
                                                           SequenceFileInfo* info = nullptr);
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
// The same, handing `opened` the file's description as describe_sequence_file gives it (checksums
// not yet verified) once it is open, then `each` every keyframe (its texture left empty) as it is
// decoded, in order: what a caller keeps of them is its own (fminfo --field-bytes keeps the one
// before, and codes it as the header's field coding says). One open serves both: opening a file of
// millions of frame patches is most of what reading it costs (spec/container.md §10.5).
SequenceFileInfo inspect_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits,
                                       const std::function<void(const SequenceFileInfo&)>& opened,
                                       const std::function<void(size_t, const Keyframe&)>& each);
// Describes a file from what opening it reads (header and index, checked as §10.2 steps 1-5) and
// verifies every chunk's checksum; decodes no keyframe. Each keyframe's fields bytes are 0 (a
// group's are in field_groups); a texture group's are divided among its frames. Its cost is
// reading the file's bytes once (a few ms a MB), where inspect_sequence_file's is decoding them
// (about 0.4 s a MB at N = 257): what `fminfo` does, `fminfo --verify` the other. Throws as
// open_sequence_source, and kCorrupt naming the first chunk whose checksum does not match.
SequenceFileInfo describe_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits);

Sequence read_sequence_file(const std::filesystem::path& path, SequenceFileInfo* info = nullptr,
                            const DecoderLimits& limits = kDefaultDecoderLimits);

}  // namespace facemorph
