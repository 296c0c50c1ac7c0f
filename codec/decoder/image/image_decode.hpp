// Image decoding on the decoder's side, without OpenCV: AVIF and WebP (how the container stores
// textures) and PNG (images the tools read). Debian's libavif, libwebp and libpng: C, and ported to
// WebAssembly, where the decoder is headed (spec/method.md §6). The encoders are the writer's
// (codec/writer/image/image_encode.hpp).
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/core/image/texture_codec.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// Decodes WebP bytes to RGB (`channels` 3) or RGBA (4). Throws kCorrupt naming `source` when the
// bytes are not a WebP image, kInvalidArgument when its size exceeds `max_pixels`.
Image decode_webp(std::span<const uint8_t> bytes, const std::string& source, int channels = 3, int64_t max_pixels = int64_t{1} << 26);

// Decodes AVIF bytes to RGB (`channels` 3) or RGBA (4, opaque). Throws kCorrupt naming `source` when
// the bytes are not an AVIF image or its data is damaged, kInvalidArgument when its size exceeds
// `max_pixels`.
Image decode_avif(std::span<const uint8_t> bytes, const std::string& source, int channels = 3, int64_t max_pixels = int64_t{1} << 26);

// Reads an AVIF image sequence that must hold exactly `frames` 8-bit images of size x size frame
// by frame, in order, so that a caller may stop between two frames and go on later with the same
// reader (a decode call's work limit). Checked from the container (its sample count and image size)
// when made, before any pixel is decoded (one frame: the still image libavif writes for a sequence
// of one). `bytes` must outlive the reader. Throws kCorrupt naming `source` for another count (a
// still where several frames belong), size or depth, or damaged data.
class AvifSequenceReader {
 public:
  AvifSequenceReader(std::span<const uint8_t> bytes, std::string source, uint32_t frames, uint32_t size);
  ~AvifSequenceReader();
  AvifSequenceReader(const AvifSequenceReader&) = delete;
  AvifSequenceReader& operator=(const AvifSequenceReader&) = delete;
  // The frame read() decodes next (frames: none left).
  uint32_t next() const;
  // Decodes frame next() (every frame is decoded: later ones are predicted from it); returns it in
  // RGB where `convert`, else an empty image. kInvalidArgument past the last frame.
  Image read(bool convert);

 private:
  struct State;
  std::unique_ptr<State> state_;
};
// Decodes frames 0 .. last of such a sequence (an AvifSequenceReader's frames): those for which
// wanted(j) are converted to RGB and handed to take(j, image). kInvalidArgument for last >= frames.
void decode_avif_sequence(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size, uint32_t last,
                          const std::function<bool(uint32_t)>& wanted, const std::function<void(uint32_t, Image&&)>& take);
// The bytes of each frame's AV1 sample in such a sequence (without the AVIF container's own), from
// its sample table; nothing decoded. Throws as decode_avif_sequence.
std::vector<uint64_t> avif_sequence_sample_bytes(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size);

// decode_avif or decode_webp, to RGB, with their errors.
Image decode_texture(TextureCodec codec, std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels = int64_t{1} << 26);

// Decodes PNG bytes to 8-bit RGB or RGBA (grey and palettes expanded, 16 bits reduced). Throws
// kCorrupt naming `source` for anything that is not a complete PNG image.
Image decode_png(std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels = int64_t{1} << 26);

}  // namespace facemorph
