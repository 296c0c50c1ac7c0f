#include "format/zstd_frame.hpp"

#include "format/error.hpp"

#include <zstd.h>
#include <algorithm>
#include <memory>
#include <new>
#include <string>

namespace facemorph::format {

std::vector<uint8_t> compress_frame(std::span<const uint8_t> raw, int level, std::span<const uint8_t> prefix) {
  std::vector<uint8_t> out(ZSTD_compressBound(raw.size()));
  size_t size = 0;
  if (prefix.empty()) {
    size = ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), level);
  } else {
    std::unique_ptr<ZSTD_CCtx, size_t (*)(ZSTD_CCtx*)> context(ZSTD_createCCtx(), ZSTD_freeCCtx);
    if (!context) throw std::bad_alloc();
    // ZSTD_compress2 states the content size in the frame header, as ZSTD_compress does; the
    // prefix (no dictionary ID in the frame) holds for this one frame only. The content checksum
    // tells a frame made against other bytes from one made against these: without it, such a frame
    // may decompress, to other bytes.
    size = ZSTD_CCtx_setParameter(context.get(), ZSTD_c_compressionLevel, level);
    if (!ZSTD_isError(size)) size = ZSTD_CCtx_setParameter(context.get(), ZSTD_c_checksumFlag, 1);
    if (!ZSTD_isError(size)) size = ZSTD_CCtx_refPrefix(context.get(), prefix.data(), prefix.size());
    if (!ZSTD_isError(size)) size = ZSTD_compress2(context.get(), out.data(), out.size(), raw.data(), raw.size());
  }
  if (ZSTD_isError(size)) throw Error(ErrorCode::kInvalidArgument, std::string("zstd: ") + ZSTD_getErrorName(size));
  out.resize(size);
  return out;
}

std::optional<uint64_t> announced_size(std::span<const uint8_t> frame) {
  const unsigned long long size = ZSTD_getFrameContentSize(frame.data(), frame.size());
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN) return std::nullopt;
  return size;
}

bool has_content_checksum(std::span<const uint8_t> frame) {
  // RFC 8878 §3.1.1: the magic number 0xFD2FB528, then the frame header descriptor, whose bit 2 is
  // the content checksum flag (read here, not by zstd's experimental ZSTD_getFrameHeader).
  constexpr uint8_t kMagic[4] = {0x28, 0xB5, 0x2F, 0xFD};
  return frame.size() > 4 && std::equal(kMagic, kMagic + 4, frame.begin()) && (frame[4] & 0x04) != 0;
}

bool decompress_frame(std::span<const uint8_t> frame, std::span<uint8_t> out) {
  const size_t size = ZSTD_decompress(out.data(), out.size(), frame.data(), frame.size());
  return !ZSTD_isError(size) && size == out.size();
}

std::optional<std::vector<uint8_t>> decompress_frame_growing(std::span<const uint8_t> frame, uint64_t size,
                                                             std::span<const uint8_t> prefix) {
  if (!possible_content_size(frame.size(), size)) return std::nullopt;
  std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> context(ZSTD_createDCtx(), ZSTD_freeDCtx);
  if (!context) throw std::bad_alloc();
  // The window a frame may ask for is bounded as its output is: no more than the announced size.
  ZSTD_DCtx_setParameter(context.get(), ZSTD_d_windowLogMax, 27);
  if (!prefix.empty() && ZSTD_isError(ZSTD_DCtx_refPrefix(context.get(), prefix.data(), prefix.size()))) return std::nullopt;
  constexpr uint64_t kFirstStep = uint64_t{1} << 20;  // then doubling: at most twice what arrived
  std::vector<uint8_t> out(static_cast<size_t>(std::min(size, kFirstStep)));
  ZSTD_inBuffer in{frame.data(), frame.size(), 0};
  size_t produced = 0;
  while (true) {
    ZSTD_outBuffer o{out.data(), out.size(), produced};
    const size_t status = ZSTD_decompressStream(context.get(), &o, &in);
    if (ZSTD_isError(status)) return std::nullopt;
    produced = o.pos;
    if (status == 0) break;  // the frame is complete
    if (produced == out.size()) {
      if (out.size() >= size) return std::nullopt;  // more than announced
      out.resize(static_cast<size_t>(std::min<uint64_t>(size, 2 * static_cast<uint64_t>(out.size()))));
    } else if (in.pos == in.size) {
      return std::nullopt;  // the frame ends before its end
    }
  }
  if (produced != size || in.pos != in.size) return std::nullopt;
  out.resize(produced);
  return out;
}

}  // namespace facemorph::format
