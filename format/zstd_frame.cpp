#include "format/zstd_frame.hpp"

#include "facemorph/error.hpp"

#include <string>
#include <zstd.h>

namespace facemorph::format {

std::vector<uint8_t> compress_frame(std::span<const uint8_t> raw, int level) {
  std::vector<uint8_t> out(ZSTD_compressBound(raw.size()));
  const size_t size = ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), level);
  if (ZSTD_isError(size)) throw Error(ErrorCode::kInvalidArgument, std::string("zstd: ") + ZSTD_getErrorName(size));
  out.resize(size);
  return out;
}

std::optional<uint64_t> announced_size(std::span<const uint8_t> frame) {
  const unsigned long long size = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN) return std::nullopt;
  return size;
}

bool decompress_frame(std::span<const uint8_t> frame, std::span<uint8_t> out) {
  const size_t size = ZSTD_decompress(out.data(), out.size(), frame.data(), frame.size());
  return !ZSTD_isError(size) && size == out.size();
}

}  // namespace facemorph::format
