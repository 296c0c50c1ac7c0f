#include "codec/decoder/image/image_decode.hpp"

#include "codec/core/image/avif_image.hpp"
#include "format/error.hpp"

#include <avif/avif.h>
#include <png.h>
#include <webp/decode.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstring>
#include <memory>

namespace facemorph {

Image decode_webp(std::span<const uint8_t> bytes, const std::string& source, int channels, int64_t max_pixels) {
  if (channels != 3 && channels != 4) throw Error(ErrorCode::kInvalidArgument, "decode_webp: channels must be 3 or 4");
  int width = 0, height = 0;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &width, &height)) throw Error(ErrorCode::kCorrupt, source + ": not a WebP image");
  if (static_cast<int64_t>(width) * height > max_pixels) {
    throw Error(ErrorCode::kInvalidArgument,
                source + ": WebP image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is too large");
  }
  Image image(width, height, channels);
  const int stride = width * channels;
  const uint8_t* ok = channels == 3 ? WebPDecodeRGBInto(bytes.data(), bytes.size(), image.pixels.data(), image.pixels.size(), stride)
                                    : WebPDecodeRGBAInto(bytes.data(), bytes.size(), image.pixels.data(), image.pixels.size(), stride);
  if (ok == nullptr) throw Error(ErrorCode::kCorrupt, source + ": the WebP image data is damaged");
  return image;
}

namespace {

// A decoder on an AVIF image sequence of exactly `frames` 8-bit images of size × size, parsed and
// checked from the container alone (no pixel decoded yet); kCorrupt naming `source` otherwise.
std::unique_ptr<avifDecoder, AvifDecoderFree> parsed_sequence(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames,
                                                              uint32_t size) {
  std::unique_ptr<avifDecoder, AvifDecoderFree> decoder(avifDecoderCreate());
  if (!decoder) throw Error(ErrorCode::kInvalidArgument, source + ": AVIF decoding: out of memory");
  decoder->maxThreads = 1;
  decoder->ignoreExif = decoder->ignoreXMP = AVIF_TRUE;
  // The container may claim no more than the file's own counts and size: refused while parsing.
  decoder->imageCountLimit = std::max<uint32_t>(frames, 1);
  decoder->imageDimensionLimit = std::max<uint32_t>(size, 1);
  decoder->imageSizeLimit = std::max<uint32_t>(size * size, 1);
  // The sequence's track where the file has one; a one-frame sequence is a still image (libavif
  // writes one image so), and a still where several frames belong is refused by its count below.
  avifResult result = avifDecoderSetIOMemory(decoder.get(), bytes.data(), bytes.size());
  if (result == AVIF_RESULT_OK) result = avifDecoderParse(decoder.get());
  if (result != AVIF_RESULT_OK)
    throw Error(ErrorCode::kCorrupt, source + ": not an AVIF image sequence (" + avifResultToString(result) + ")");
  if (decoder->imageCount != static_cast<int>(frames) || decoder->image->width != size || decoder->image->height != size ||
      decoder->image->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": an AVIF sequence of " + std::to_string(decoder->imageCount) + " images of " +
                                         std::to_string(decoder->image->width) + " x " + std::to_string(decoder->image->height) + " at " +
                                         std::to_string(decoder->image->depth) + " bits, not " + std::to_string(frames) + " of " +
                                         std::to_string(size) + " x " + std::to_string(size) + " at 8");
  }
  return decoder;
}

}  // namespace

struct AvifSequenceReader::State {
  std::string source;
  uint32_t frames = 0, size = 0, next = 0;
  std::unique_ptr<avifDecoder, AvifDecoderFree> decoder;
};

AvifSequenceReader::AvifSequenceReader(std::span<const uint8_t> bytes, std::string source, uint32_t frames, uint32_t size)
    : state_(std::make_unique<State>()) {
  state_->decoder = parsed_sequence(bytes, source, frames, size);
  state_->source = std::move(source);
  state_->frames = frames;
  state_->size = size;
}

AvifSequenceReader::~AvifSequenceReader() = default;

uint32_t AvifSequenceReader::next() const { return state_->next; }

Image AvifSequenceReader::read(bool convert) {
  State& s = *state_;
  const uint32_t j = s.next;
  if (j >= s.frames)
    throw Error(ErrorCode::kInvalidArgument, s.source + ": frame " + std::to_string(j) + " of a sequence of " + std::to_string(s.frames));
  const avifResult result = avifDecoderNextImage(s.decoder.get());
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kCorrupt,
                s.source + ": frame " + std::to_string(j) + " of the AVIF sequence is damaged (" + avifResultToString(result) + ")");
  }
  const avifImage* decoded = s.decoder->image;
  if (decoded->width != s.size || decoded->height != s.size || decoded->depth != 8) {
    throw Error(ErrorCode::kCorrupt, s.source + ": frame " + std::to_string(j) + " of the AVIF sequence is " +
                                         std::to_string(decoded->width) + " x " + std::to_string(decoded->height) + ", not " +
                                         std::to_string(s.size) + " x " + std::to_string(s.size));
  }
  ++s.next;
  return convert ? rgb_of(decoded, 3, s.source) : Image();
}

void decode_avif_sequence(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size, uint32_t last,
                          const std::function<bool(uint32_t)>& wanted, const std::function<void(uint32_t, Image&&)>& take) {
  if (last >= frames)
    throw Error(ErrorCode::kInvalidArgument, source + ": frame " + std::to_string(last) + " of a sequence of " + std::to_string(frames));
  AvifSequenceReader reader(bytes, source, frames, size);
  for (uint32_t j = 0; j <= last; ++j) {
    const bool convert = wanted(j);
    Image image = reader.read(convert);
    if (convert) take(j, std::move(image));
  }
}

std::vector<uint64_t> avif_sequence_sample_bytes(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames,
                                                 uint32_t size) {
  const auto decoder = parsed_sequence(bytes, source, frames, size);
  // The extent frame j needs runs from the sync sample (frame 0) to j's sample: j's own bytes are
  // how far it reaches past frame j - 1's.
  std::vector<uint64_t> sizes(frames);
  uint64_t previous_end = 0;
  for (uint32_t j = 0; j < frames; ++j) {
    avifExtent extent{};
    const avifResult result = avifDecoderNthImageMaxExtent(decoder.get(), j, &extent);
    if (result != AVIF_RESULT_OK)
      throw Error(ErrorCode::kCorrupt, source + ": frame " + std::to_string(j) + " of the AVIF sequence: " + avifResultToString(result));
    const uint64_t end = extent.offset + extent.size;
    sizes[j] = j == 0 ? extent.size : (end > previous_end ? end - previous_end : 0);
    previous_end = std::max(previous_end, end);
  }
  return sizes;
}

Image decode_avif(std::span<const uint8_t> bytes, const std::string& source, int channels, int64_t max_pixels) {
  if (channels != 3 && channels != 4) throw Error(ErrorCode::kInvalidArgument, "decode_avif: channels must be 3 or 4");
  std::unique_ptr<avifDecoder, AvifDecoderFree> decoder(avifDecoderCreate());
  if (!decoder) throw Error(ErrorCode::kInvalidArgument, source + ": AVIF decoding: out of memory");
  decoder->maxThreads = 1;
  decoder->ignoreExif = decoder->ignoreXMP = AVIF_TRUE;
  avifResult result = avifDecoderSetIOMemory(decoder.get(), bytes.data(), bytes.size());
  if (result == AVIF_RESULT_OK) result = avifDecoderParse(decoder.get());
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": not an AVIF image (" + avifResultToString(result) + ")");
  const uint32_t width = decoder->image->width, height = decoder->image->height;
  if (static_cast<int64_t>(width) * height > max_pixels) {
    throw Error(ErrorCode::kInvalidArgument,
                source + ": AVIF image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is too large");
  }
  // One 8-bit still image (spec/container.md §8): a sequence or a deeper image is not a texture.
  if (decoder->imageCount != 1 || decoder->image->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": an AVIF of " + std::to_string(decoder->imageCount) + " images at " +
                                         std::to_string(decoder->image->depth) + " bits, not one 8-bit still image");
  }
  // The AV1 frame may claim another size than the container's header; the AV1 decoder refuses a
  // frame larger than the header's, so a hostile file cannot make it allocate more.
  decoder->imageSizeLimit = std::max<uint32_t>(width * height, 1);
  result = avifDecoderNextImage(decoder.get());
  if (result != AVIF_RESULT_OK)
    throw Error(ErrorCode::kCorrupt, source + ": the AVIF image data is damaged (" + avifResultToString(result) + ")");
  const avifImage* decoded = decoder->image;
  if (decoded->width != width || decoded->height != height || decoded->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": the AVIF frame is " + std::to_string(decoded->width) + " x " +
                                         std::to_string(decoded->height) + ", its header says " + std::to_string(width) + " x " +
                                         std::to_string(height));
  }
  return rgb_of(decoded, channels, source);
}

Image decode_texture(TextureCodec codec, std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels) {
  return codec == TextureCodec::kAvif ? decode_avif(bytes, source, 3, max_pixels) : decode_webp(bytes, source, 3, max_pixels);
}

Image decode_png(std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&png, bytes.data(), bytes.size())) {
    throw Error(ErrorCode::kCorrupt, source + ": not a PNG image (" + png.message + ")");
  }
  if (static_cast<int64_t>(png.width) * png.height > max_pixels) {
    png_image_free(&png);
    throw Error(ErrorCode::kInvalidArgument,
                source + ": PNG image of " + std::to_string(png.width) + " x " + std::to_string(png.height) + " pixels is too large");
  }
  const bool alpha = (png.format & PNG_FORMAT_FLAG_ALPHA) != 0;
  png.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
  Image image(static_cast<int>(png.width), static_cast<int>(png.height), alpha ? 4 : 3);
  if (!png_image_finish_read(&png, nullptr, image.pixels.data(), image.width * image.channels, nullptr)) {
    const std::string message = png.message;
    png_image_free(&png);
    throw Error(ErrorCode::kCorrupt, source + ": damaged PNG image (" + message + ")");
  }
  return image;
}

}  // namespace facemorph
