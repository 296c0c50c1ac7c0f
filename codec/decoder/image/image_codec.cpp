#include "codec/decoder/image/image_codec.hpp"

#include "format/error.hpp"

#include <avif/avif.h>
#include <png.h>
#include <webp/decode.h>
#include <webp/encode.h>

#include <algorithm>
#include <cmath>
#include <csetjmp>
#include <cstring>
#include <memory>

namespace facemorph {

namespace {

void require_codable(const Image& image, bool grey_allowed) {
  const bool channels_ok = image.channels == 3 || image.channels == 4 || (grey_allowed && image.channels == 1);
  if (image.empty() || !channels_ok || image.pixels.size() != static_cast<size_t>(image.width) * image.height * image.channels) {
    throw Error(ErrorCode::kInvalidArgument, "cannot encode an image of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels and " + std::to_string(image.channels) + " channels");
  }
}

}  // namespace

std::vector<uint8_t> encode_webp(const Image& image, int quality) {
  require_codable(image, false);
  WebPConfig config;
  WebPPicture picture;
  if (!WebPConfigInit(&config) || !WebPPictureInit(&picture)) throw Error(ErrorCode::kUnsupported, "libwebp version mismatch");
  config.lossless = quality > 100;
  config.quality = config.lossless ? 100.0f : static_cast<float>(quality < 0 ? 0 : quality);
  config.exact = 1;  // keep colours under transparent pixels: a lossless image comes back bit-exact
  picture.use_argb = config.lossless;
  picture.width = image.width;
  picture.height = image.height;
  const int stride = image.width * image.channels;
  const int imported = image.channels == 3 ? WebPPictureImportRGB(&picture, image.pixels.data(), stride)
                                           : WebPPictureImportRGBA(&picture, image.pixels.data(), stride);
  WebPMemoryWriter writer;
  WebPMemoryWriterInit(&writer);
  picture.writer = WebPMemoryWrite;
  picture.custom_ptr = &writer;
  const bool ok = imported && WebPEncode(&config, &picture);
  const int error = picture.error_code;
  WebPPictureFree(&picture);
  std::vector<uint8_t> bytes(writer.mem, writer.mem + writer.size);
  WebPMemoryWriterClear(&writer);
  if (!ok) {
    throw Error(ErrorCode::kInvalidArgument, "WebP encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed (libwebp error " + std::to_string(error) + "; at most 16383 per side)");
  }
  return bytes;
}

Image decode_webp(std::span<const uint8_t> bytes, const std::string& source, int channels, int64_t max_pixels) {
  if (channels != 3 && channels != 4) throw Error(ErrorCode::kInvalidArgument, "decode_webp: channels must be 3 or 4");
  int width = 0, height = 0;
  if (!WebPGetInfo(bytes.data(), bytes.size(), &width, &height)) throw Error(ErrorCode::kCorrupt, source + ": not a WebP image");
  if (static_cast<int64_t>(width) * height > max_pixels) {
    throw Error(ErrorCode::kInvalidArgument, source + ": WebP image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is too large");
  }
  Image image(width, height, channels);
  const int stride = width * channels;
  const uint8_t* ok = channels == 3 ? WebPDecodeRGBInto(bytes.data(), bytes.size(), image.pixels.data(), image.pixels.size(), stride)
                                    : WebPDecodeRGBAInto(bytes.data(), bytes.size(), image.pixels.data(), image.pixels.size(), stride);
  if (ok == nullptr) throw Error(ErrorCode::kCorrupt, source + ": the WebP image data is damaged");
  return image;
}

namespace {

// libavif's objects, freed on every path.
struct AvifImageFree {
  void operator()(avifImage* image) const { avifImageDestroy(image); }
};
struct AvifEncoderFree {
  void operator()(avifEncoder* encoder) const { avifEncoderDestroy(encoder); }
};
struct AvifDecoderFree {
  void operator()(avifDecoder* decoder) const { avifDecoderDestroy(decoder); }
};
struct AvifBytes {
  avifRWData data = AVIF_DATA_EMPTY;
  ~AvifBytes() { avifRWDataFree(&data); }
};
struct AvifRgb {
  avifRGBImage rgb;
  AvifRgb() { std::memset(&rgb, 0, sizeof rgb); }
  ~AvifRgb() { avifRGBImageFreePixels(&rgb); }
};

// An image as 8-bit YUV 4:4:4, full-range BT.601 (the matrix WebP and JPEG use; every decoder
// converts back with the matrix the file signals): what the stills and the sequences code.
std::unique_ptr<avifImage, AvifImageFree> yuv_of(const Image& image) {
  require_codable(image, false);
  std::unique_ptr<avifImage, AvifImageFree> yuv(avifImageCreate(static_cast<uint32_t>(image.width), static_cast<uint32_t>(image.height), 8, AVIF_PIXEL_FORMAT_YUV444));
  if (!yuv) throw Error(ErrorCode::kInvalidArgument, "AVIF encoding: out of memory");
  yuv->yuvRange = AVIF_RANGE_FULL;
  yuv->matrixCoefficients = AVIF_MATRIX_COEFFICIENTS_BT601;
  avifRGBImage rgb;
  avifRGBImageSetDefaults(&rgb, yuv.get());
  rgb.format = image.channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.ignoreAlpha = AVIF_TRUE;  // textures are opaque
  rgb.pixels = const_cast<uint8_t*>(image.pixels.data());  // read only: libavif's API is not const
  rgb.rowBytes = static_cast<uint32_t>(image.width * image.channels);
  const avifResult result = avifImageRGBToYUV(yuv.get(), &rgb);
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kInvalidArgument, "AVIF encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed: " + avifResultToString(result));
  }
  return yuv;
}

// The encoder the stills and the sequences share, at the AV1 quantiser of `quality`.
std::unique_ptr<avifEncoder, AvifEncoderFree> avif_encoder(int quality) {
  if (avifCodecName(AVIF_CODEC_CHOICE_AOM, AVIF_CODEC_FLAG_CAN_ENCODE) == nullptr) {
    throw Error(ErrorCode::kUnsupported, "AVIF encoding needs libavif built with libaom");
  }
  std::unique_ptr<avifEncoder, AvifEncoderFree> encoder(avifEncoderCreate());
  if (!encoder) throw Error(ErrorCode::kInvalidArgument, "AVIF encoding: out of memory");
  encoder->minQuantizer = encoder->maxQuantizer = avif_quantizer(quality);
  encoder->speed = 6;       // avifenc's default, 0.06 s for a 448² texture
  encoder->maxThreads = 1;  // the same bytes on every run (with one libaom version)
  // libaom: it codes 4:4:4 (SVT-AV1 does not), and a fixed encoder keeps the bytes reproducible.
  encoder->codecChoice = AVIF_CODEC_CHOICE_AOM;
  return encoder;
}

// An 8-bit decoded frame as RGB (`channels` 3) or opaque RGBA (4).
Image rgb_of(const avifImage* decoded, int channels, const std::string& source) {
  Image image(static_cast<int>(decoded->width), static_cast<int>(decoded->height), channels);
  AvifRgb rgb;
  avifRGBImageSetDefaults(&rgb.rgb, decoded);
  rgb.rgb.format = channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.rgb.depth = 8;
  rgb.rgb.pixels = image.pixels.data();
  rgb.rgb.rowBytes = static_cast<uint32_t>(image.width * channels);
  const avifResult result = avifImageYUVToRGB(decoded, &rgb.rgb);
  rgb.rgb.pixels = nullptr;  // ours, not libavif's to free
  if (channels == 4 && decoded->alphaPlane == nullptr) {
    for (size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;  // no alpha stored: opaque
  }
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": the AVIF image cannot be converted to RGB (" + avifResultToString(result) + ")");
  return image;
}

}  // namespace

std::vector<uint8_t> encode_avif(const Image& image, int quality) {
  const auto yuv = yuv_of(image);
  const auto encoder = avif_encoder(quality);
  AvifBytes bytes;
  const avifResult result = avifEncoderWrite(encoder.get(), yuv.get(), &bytes.data);
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kInvalidArgument, "AVIF encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed: " + avifResultToString(result));
  }
  return std::vector<uint8_t>(bytes.data.data, bytes.data.data + bytes.data.size);
}

namespace {

// libavif stamps an image sequence's movie, track and media headers (mvhd, tkhd, mdhd) with the
// wall-clock time of the encode: set to 0 ("unknown" in ISO BMFF), so the same frames give the same
// bytes (spec/container.md §11). Walks the boxes of `bytes` (the encoder's own output) within
// [begin, end), descending into moov, trak and mdia.
void clear_creation_times(std::vector<uint8_t>& bytes, size_t begin, size_t end) {
  const auto u32 = [&](size_t at) { return (uint32_t{bytes[at]} << 24) | (uint32_t{bytes[at + 1]} << 16) | (uint32_t{bytes[at + 2]} << 8) | bytes[at + 3]; };
  size_t at = begin;
  while (at + 8 <= end) {
    uint64_t size = u32(at);
    size_t header = 8;
    if (size == 1 && at + 16 <= end) {
      size = (uint64_t{u32(at + 8)} << 32) | u32(at + 12);
      header = 16;
    } else if (size == 0) {
      size = end - at;
    }
    if (size < header || size > end - at) return;  // not a box we wrote: leave the rest alone
    const std::string type(bytes.begin() + static_cast<ptrdiff_t>(at + 4), bytes.begin() + static_cast<ptrdiff_t>(at + 8));
    const size_t body = at + header, box_end = at + static_cast<size_t>(size);
    if (type == "moov" || type == "trak" || type == "mdia") clear_creation_times(bytes, body, box_end);
    if ((type == "mvhd" || type == "tkhd" || type == "mdhd") && body + 4 <= box_end) {
      const size_t times = bytes[body] == 1 ? 16 : 8;  // version 1: two u64, else two u32
      if (body + 4 + times <= box_end) std::fill(bytes.begin() + static_cast<ptrdiff_t>(body + 4), bytes.begin() + static_cast<ptrdiff_t>(body + 4 + times), 0);
    }
    at = box_end;
  }
}

}  // namespace

struct AvifSequenceWriter::State {
  std::unique_ptr<avifEncoder, AvifEncoderFree> encoder;
  int width = 0, height = 0;
  bool finished = false;
};

AvifSequenceWriter::AvifSequenceWriter(int quality) : state_(std::make_unique<State>()) {
  state_->encoder = avif_encoder(quality);
  state_->encoder->timescale = 30;        // informative: a frame a tick (the file's times are the container's)
  state_->encoder->keyframeInterval = 0;  // frame 0 intra, every later one predicted from those before it
}

AvifSequenceWriter::~AvifSequenceWriter() = default;

void AvifSequenceWriter::add(const Image& frame) {
  State& s = *state_;
  if (s.finished) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence given a frame after it was finished");
  if (s.width == 0) {
    s.width = frame.width;
    s.height = frame.height;
  } else if (frame.width != s.width || frame.height != s.height) {
    throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of frames of different sizes");
  }
  const auto yuv = yuv_of(frame);
  const avifResult result = avifEncoderAddImage(s.encoder.get(), yuv.get(), 1, AVIF_ADD_IMAGE_FLAG_NONE);
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kInvalidArgument, std::string("AVIF sequence encoding failed: ") + avifResultToString(result));
}

std::vector<uint8_t> AvifSequenceWriter::finish() {
  State& s = *state_;
  if (s.width == 0) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of no frames");
  if (s.finished) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence finished twice");
  s.finished = true;
  AvifBytes bytes;
  const avifResult result = avifEncoderFinish(s.encoder.get(), &bytes.data);
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kInvalidArgument, std::string("AVIF sequence encoding failed: ") + avifResultToString(result));
  std::vector<uint8_t> out(bytes.data.data, bytes.data.data + bytes.data.size);
  clear_creation_times(out, 0, out.size());
  return out;
}

std::vector<uint8_t> encode_avif_sequence(std::span<const Image* const> frames, int quality) {
  if (frames.empty()) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of no frames");
  AvifSequenceWriter writer(quality);
  for (const Image* frame : frames) writer.add(*frame);
  return writer.finish();
}

Image avif_colour_round_trip(const Image& image) { return rgb_of(yuv_of(image).get(), 3, "avif_colour_round_trip"); }

namespace {

// A decoder on an AVIF image sequence of exactly `frames` 8-bit images of size × size, parsed and
// checked from the container alone (no pixel decoded yet); kCorrupt naming `source` otherwise.
std::unique_ptr<avifDecoder, AvifDecoderFree> parsed_sequence(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size) {
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
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": not an AVIF image sequence (" + avifResultToString(result) + ")");
  if (decoder->imageCount != static_cast<int>(frames) || decoder->image->width != size || decoder->image->height != size || decoder->image->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": an AVIF sequence of " + std::to_string(decoder->imageCount) + " images of " + std::to_string(decoder->image->width) +
                                         " x " + std::to_string(decoder->image->height) + " at " + std::to_string(decoder->image->depth) + " bits, not " +
                                         std::to_string(frames) + " of " + std::to_string(size) + " x " + std::to_string(size) + " at 8");
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
  if (j >= s.frames) throw Error(ErrorCode::kInvalidArgument, s.source + ": frame " + std::to_string(j) + " of a sequence of " + std::to_string(s.frames));
  const avifResult result = avifDecoderNextImage(s.decoder.get());
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kCorrupt, s.source + ": frame " + std::to_string(j) + " of the AVIF sequence is damaged (" + avifResultToString(result) + ")");
  }
  const avifImage* decoded = s.decoder->image;
  if (decoded->width != s.size || decoded->height != s.size || decoded->depth != 8) {
    throw Error(ErrorCode::kCorrupt, s.source + ": frame " + std::to_string(j) + " of the AVIF sequence is " + std::to_string(decoded->width) + " x " +
                                         std::to_string(decoded->height) + ", not " + std::to_string(s.size) + " x " + std::to_string(s.size));
  }
  ++s.next;
  return convert ? rgb_of(decoded, 3, s.source) : Image();
}

void decode_avif_sequence(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size, uint32_t last,
                          const std::function<bool(uint32_t)>& wanted, const std::function<void(uint32_t, Image&&)>& take) {
  if (last >= frames) throw Error(ErrorCode::kInvalidArgument, source + ": frame " + std::to_string(last) + " of a sequence of " + std::to_string(frames));
  AvifSequenceReader reader(bytes, source, frames, size);
  for (uint32_t j = 0; j <= last; ++j) {
    const bool convert = wanted(j);
    Image image = reader.read(convert);
    if (convert) take(j, std::move(image));
  }
}

std::vector<uint64_t> avif_sequence_sample_bytes(std::span<const uint8_t> bytes, const std::string& source, uint32_t frames, uint32_t size) {
  const auto decoder = parsed_sequence(bytes, source, frames, size);
  // The extent frame j needs runs from the sync sample (frame 0) to j's sample: j's own bytes are
  // how far it reaches past frame j - 1's.
  std::vector<uint64_t> sizes(frames);
  uint64_t previous_end = 0;
  for (uint32_t j = 0; j < frames; ++j) {
    avifExtent extent{};
    const avifResult result = avifDecoderNthImageMaxExtent(decoder.get(), j, &extent);
    if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": frame " + std::to_string(j) + " of the AVIF sequence: " + avifResultToString(result));
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
    throw Error(ErrorCode::kInvalidArgument, source + ": AVIF image of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is too large");
  }
  // One 8-bit still image (spec/container.md §8): a sequence or a deeper image is not a texture.
  if (decoder->imageCount != 1 || decoder->image->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": an AVIF of " + std::to_string(decoder->imageCount) + " images at " + std::to_string(decoder->image->depth) +
                                         " bits, not one 8-bit still image");
  }
  // The AV1 frame may claim another size than the container's header; the AV1 decoder refuses a
  // frame larger than the header's, so a hostile file cannot make it allocate more.
  decoder->imageSizeLimit = std::max<uint32_t>(width * height, 1);
  result = avifDecoderNextImage(decoder.get());
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": the AVIF image data is damaged (" + avifResultToString(result) + ")");
  const avifImage* decoded = decoder->image;
  if (decoded->width != width || decoded->height != height || decoded->depth != 8) {
    throw Error(ErrorCode::kCorrupt, source + ": the AVIF frame is " + std::to_string(decoded->width) + " x " + std::to_string(decoded->height) +
                                         ", its header says " + std::to_string(width) + " x " + std::to_string(height));
  }
  return rgb_of(decoded, channels, source);
}

std::vector<uint8_t> encode_png(const Image& image) {
  require_codable(image, true);
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = image.channels == 4 ? PNG_FORMAT_RGBA : image.channels == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
  png_alloc_size_t size = 0;
  const int stride = image.width * image.channels;
  if (!png_image_write_to_memory(&png, nullptr, &size, 0, image.pixels.data(), stride, nullptr)) {
    throw Error(ErrorCode::kInvalidArgument, std::string("PNG encoding failed: ") + png.message);
  }
  std::vector<uint8_t> bytes(size);
  if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, image.pixels.data(), stride, nullptr)) {
    throw Error(ErrorCode::kInvalidArgument, std::string("PNG encoding failed: ") + png.message);
  }
  bytes.resize(size);
  return bytes;
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
    throw Error(ErrorCode::kInvalidArgument, source + ": PNG image of " + std::to_string(png.width) + " x " + std::to_string(png.height) + " pixels is too large");
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
