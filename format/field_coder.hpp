// The provisional coding of a keyframe's 16-bit fields (spec/method.md §5.3), until the container
// fixes one: every array's codes in order, each as the difference from the previous code (mod
// 2^16; the grid is row-major, so neighbours are near), split into a plane of high bytes and one of
// low bytes, the planes concatenated (all high bytes, then all low) and compressed with zstd. The
// same for every representation, so sizes compare representations, not coders.
#pragma once

#include "format/quantize.hpp"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

// The codes of `arrays` coded as above; zstd at `level` (1..22).
std::vector<uint8_t> encode_code_planes(std::span<const Quantized16> arrays, int level = 19);

// The inverse: `lengths[k]` codes for array k. Throws kCorrupt naming `source` when the bytes do not
// decompress to exactly the announced number of codes.
std::vector<std::vector<uint16_t>> decode_code_planes(std::span<const uint8_t> bytes, std::span<const size_t> lengths,
                                                      const std::string& source);

}  // namespace facemorph::format
