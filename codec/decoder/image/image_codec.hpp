// Image coding on the decoder's side, without OpenCV: AVIF and WebP (how the container stores
// textures) and PNG (how decoded textures and previews are written). Debian's libavif, libwebp and
// libpng: C, and ported to WebAssembly, where the decoder is headed (spec/method.md §6).
#pragma once

#include "codec/core/image/image.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// Lossy WebP at `quality` 0..100 (libwebp's scale), or lossless when `quality` is above 100.
// RGB or RGBA in; throws kInvalidArgument for an empty image or another channel count.
std::vector<uint8_t> encode_webp(const Image& image, int quality);
// Decodes WebP bytes to RGB (`channels` 3) or RGBA (4). Throws kCorrupt naming `source` when the
// bytes are not a WebP image, kInvalidArgument when its size exceeds `max_pixels`.
Image decode_webp(std::span<const uint8_t> bytes, const std::string& source, int channels = 3,
                  int64_t max_pixels = int64_t{1} << 26);

// AVIF (AV1 intra, 8-bit 4:4:4, full-range BT.601) at `quality` 0..100 (100 the finest AV1
// quantiser, 0, at which libaom codes the YUV losslessly; the RGB still loses the conversion's
// rounding, as avif_colour_round_trip shows). At the low qualities keyframe textures take it codes a face in about 30%
// fewer bytes than WebP at the same PSNR (spec/method.md §7.12). Deterministic: one thread.
// RGB or RGBA in (alpha dropped); throws kInvalidArgument for an empty image or another channel count.
std::vector<uint8_t> encode_avif(const Image& image, int quality);
// The AV1 quantiser (0 finest .. 63 coarsest) encode_avif and encode_avif_sequence code a quality
// 0..100 at: round((100 − quality) · 63 / 100). Qualities of one quantiser give the same bytes.
int avif_quantizer(int quality);
// The image converted as encode_avif converts it (8-bit YUV 4:4:4, full-range BT.601) and back to
// RGB as the decoder does: what AVIF at quality 100 decodes to, pixel for pixel, without coding it
// (the error floor of every AVIF quality; texture_quality_for's, 4x faster than the lossless encode).
Image avif_colour_round_trip(const Image& image);
// Decodes AVIF bytes to RGB (`channels` 3) or RGBA (4, opaque). Throws kCorrupt naming `source` when
// the bytes are not an AVIF image or its data is damaged, kInvalidArgument when its size exceeds
// `max_pixels`.
Image decode_avif(std::span<const uint8_t> bytes, const std::string& source, int channels = 3,
                  int64_t max_pixels = int64_t{1} << 26);

// An AV1 image sequence in AVIF (a group's keyframe textures, spec/container.md §8.1): the frames in
// order, frame 0 intra and every later one predicted from those before it; 8-bit 4:4:4, full-range
// BT.601, libaom at speed 6 on one thread, as encode_avif (deterministic). `quality` 0..100 as
// encode_avif's, for the whole sequence: libavif 0.11 applies a changed quantiser to every frame
// still in libaom's look-ahead, so a per-frame quantiser would not be what the frames get. Throws
// kInvalidArgument for no frames, frames of different sizes, or an image encode_avif refuses.
std::vector<uint8_t> encode_avif_sequence(std::span<const Image* const> frames, int quality);
// The same, a frame at a time (the container writer's: a group's textures are read one by one, so
// that they need not all be in memory; libaom keeps its own look-ahead of frames).
class AvifSequenceWriter {
 public:
  explicit AvifSequenceWriter(int quality);
  ~AvifSequenceWriter();
  AvifSequenceWriter(const AvifSequenceWriter&) = delete;
  AvifSequenceWriter& operator=(const AvifSequenceWriter&) = delete;
  void add(const Image& frame);
  // The sequence's bytes; the writer takes no frame after.
  std::vector<uint8_t> finish();

 private:
  struct State;
  std::unique_ptr<State> state_;
};
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

// The lossy codecs a keyframe texture may be stored in (spec/container.md §8).
enum class TextureCodec { kAvif, kWebp };
const char* texture_codec_name(TextureCodec codec);          // "avif", "webp"
TextureCodec parse_texture_codec(const std::string& name);   // throws kInvalidArgument
// The codec a texture asked for in `codec` at `quality` is stored in: a quality above 100 is
// lossless WebP whatever the codec (AVIF's lossless mode needs an identity matrix, and lossless
// WebP is what facemorph has always written).
TextureCodec stored_texture_codec(TextureCodec codec, int quality);
// encode_avif or encode_webp, as stored_texture_codec says.
std::vector<uint8_t> encode_texture(TextureCodec codec, const Image& image, int quality);
// decode_avif or decode_webp, to RGB, with their errors.
Image decode_texture(TextureCodec codec, std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels = int64_t{1} << 26);

// PNG, 8 bits per channel, RGB or RGBA (1-channel grey is written as grey).
std::vector<uint8_t> encode_png(const Image& image);
// Decodes PNG bytes to 8-bit RGB or RGBA (grey and palettes expanded, 16 bits reduced). Throws
// kCorrupt naming `source` for anything that is not a complete PNG image.
Image decode_png(std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels = int64_t{1} << 26);
// Writes a PNG atomically (temporary name, then rename). Throws kIo naming the file.
void write_png(const std::filesystem::path& path, const Image& image);

}  // namespace facemorph
