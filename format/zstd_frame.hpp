// One zstd frame (RFC 8878) in and out: what every compressed payload of the container is. The
// callers name what a damaged frame was; this layer only says whether it is one.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace facemorph::format {

// `raw` as one frame at `level` (1..22) that announces its content size. kInvalidArgument if zstd fails.
std::vector<uint8_t> compress_frame(std::span<const uint8_t> raw, int level);

// The content size `frame` announces; nothing when it is not a frame or announces no size.
std::optional<uint64_t> announced_size(std::span<const uint8_t> frame);

// Decompresses `frame` into `out`, which must be what it announced; false when the frame is damaged
// or decompresses to another size.
bool decompress_frame(std::span<const uint8_t> frame, std::span<uint8_t> out);

}  // namespace facemorph::format
