// Image encoding on the writer's side, without OpenCV: AVIF and WebP (how the container stores
// textures) and PNG (how decoded textures, previews and glTF clips are written). Debian's libavif,
// libwebp and libpng. A player links none of it: the decoders are codec/decoder/image/image_decode.hpp.
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/core/image/texture_codec.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

namespace facemorph {

// Lossy WebP at `quality` 0..100 (libwebp's scale), or lossless when `quality` is above 100.
// RGB or RGBA in; throws kInvalidArgument for an empty image or another channel count.
std::vector<uint8_t> encode_webp(const Image& image, int quality);
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
// encode_avif or encode_webp, as stored_texture_codec says.
std::vector<uint8_t> encode_texture(TextureCodec codec, const Image& image, int quality);
// One texture coded at several qualities (a quality search): encode_texture's bytes and
// avif_colour_round_trip's pixels, byte for byte, with the image converted to AVIF's YUV once
// rather than at every AVIF coding (the conversions were 1.3% of Medusa's encode, perf record).
// encode_texture and avif_colour_round_trip are a still's one coding.
// Keeps a reference to the image, which must outlive it; one thread's at a time.
class TextureStill {
 public:
  TextureStill(TextureCodec codec, const Image& image);
  ~TextureStill();
  TextureStill(const TextureStill&) = delete;
  TextureStill& operator=(const TextureStill&) = delete;
  std::vector<uint8_t> encode(int quality) const;  // encode_texture(codec, image, quality)
  Image colour_round_trip() const;                 // avif_colour_round_trip(image)

 private:
  struct Yuv;
  const Yuv& yuv() const;  // converted on first use
  TextureCodec codec_;
  const Image& image_;
  mutable std::unique_ptr<Yuv> yuv_;
};
// PNG, 8 bits per channel, RGB or RGBA (1-channel grey is written as grey).
std::vector<uint8_t> encode_png(const Image& image);
// Writes a PNG atomically (temporary name, then rename). Throws kIo naming the file.
void write_png(const std::filesystem::path& path, const Image& image);

}  // namespace facemorph
