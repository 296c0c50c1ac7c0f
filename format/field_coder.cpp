#include "format/field_coder.hpp"

#include "facemorph/error.hpp"

#include "format/zstd_frame.hpp"

namespace facemorph::format {

std::vector<uint8_t> encode_code_planes(std::span<const Quantized16> arrays, int level) {
  size_t total = 0;
  for (const Quantized16& q : arrays) total += q.codes.size();
  std::vector<uint8_t> planes(2 * total);
  size_t at = 0;
  for (const Quantized16& q : arrays) {
    uint16_t previous = 0;
    for (uint16_t code : q.codes) {
      const auto delta = static_cast<uint16_t>(code - previous);
      previous = code;
      planes[at] = static_cast<uint8_t>(delta >> 8);
      planes[total + at] = static_cast<uint8_t>(delta & 0xff);
      ++at;
    }
  }
  return compress_frame(planes, level);
}

std::vector<std::vector<uint16_t>> decode_code_planes(std::span<const uint8_t> bytes, std::span<const size_t> lengths, const std::string& source) {
  size_t total = 0;
  for (size_t n : lengths) {
    if (n > (size_t{1} << 30) || total > (size_t{1} << 30)) throw Error(ErrorCode::kCorrupt, source + ": field arrays too long");
    total += n;
  }
  // The decompressed size is announced by the frame; it must be exactly two bytes per code.
  const std::optional<uint64_t> announced = announced_size(bytes);
  if (!announced) throw Error(ErrorCode::kCorrupt, source + ": field payload is not a zstd frame");
  if (*announced != 2 * total) {
    throw Error(ErrorCode::kCorrupt, source + ": field payload holds " + std::to_string(*announced) + " bytes, " + std::to_string(2 * total) +
                                         " expected");
  }
  // Allocated as it decompresses: a frame that announces the right size but cannot back it (1.7 kB
  // announcing 1.28 GiB) fails after what it holds, not after zero-filling what it claims.
  const std::optional<std::vector<uint8_t>> decompressed = decompress_frame_growing(bytes, *announced);
  if (!decompressed) throw Error(ErrorCode::kCorrupt, source + ": damaged field payload");
  const std::vector<uint8_t>& planes = *decompressed;
  std::vector<std::vector<uint16_t>> out;
  size_t at = 0;
  for (size_t n : lengths) {
    std::vector<uint16_t> codes(n);
    uint16_t previous = 0;
    for (size_t i = 0; i < n; ++i, ++at) {
      previous = static_cast<uint16_t>(previous + ((planes[at] << 8) | planes[total + at]));
      codes[i] = previous;
    }
    out.push_back(std::move(codes));
  }
  return out;
}

}  // namespace facemorph::format
