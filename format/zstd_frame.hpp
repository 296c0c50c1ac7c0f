// One zstd frame (RFC 8878) in and out: what every compressed payload of the container is. The
// callers name what a damaged frame was; this layer only says whether it is one.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace facemorph::format {

// `raw` as one frame at `level` (1..22) that announces its content size. kInvalidArgument if zstd fails.
// With a `prefix` (a raw-content dictionary: zstd's ZSTD_CCtx_refPrefix), the frame may copy from it,
// decompresses only with the same prefix, and carries zstd's content checksum (XXH64).
std::vector<uint8_t> compress_frame(std::span<const uint8_t> raw, int level, std::span<const uint8_t> prefix = {});

// The content size `frame` announces; nothing when it is not a frame or announces no size.
std::optional<uint64_t> announced_size(std::span<const uint8_t> frame);

// Whether `frame` is a zstd frame whose header says it carries the content checksum.
bool has_content_checksum(std::span<const uint8_t> frame);

// Decompresses `frame` into `out`, which must be what it announced; false when the frame is damaged
// or decompresses to another size.
bool decompress_frame(std::span<const uint8_t> frame, std::span<uint8_t> out);

// Decompresses `frame`, which must announce `size` bytes and decompress to exactly that, into a
// vector that grows with what the frame actually produces (never allocated from the announcement
// alone: a frame that claims 1 GiB and is damaged after a few bytes costs a few bytes). Nothing
// when the frame is damaged or its output differs from `size`. `prefix`: the raw-content
// dictionary the frame was compressed against (compress_frame), if any.
std::optional<std::vector<uint8_t>> decompress_frame_growing(std::span<const uint8_t> frame, uint64_t size,
                                                             std::span<const uint8_t> prefix = {});

// zstd's largest expansion: a 4-byte RLE block gives at most 128 KiB (RFC 8878 §3.1.1.2), so a
// frame of S bytes decompresses to less than 32768 S + 128 KiB. An announcement beyond that is a lie.
inline constexpr uint64_t kMaxZstdExpansion = 32768;
inline bool possible_content_size(uint64_t frame_bytes, uint64_t size) {
  return size <= kMaxZstdExpansion * frame_bytes + (uint64_t{128} << 10);
}

}  // namespace facemorph::format
