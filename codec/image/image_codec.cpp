#include "facemorph/image_codec.hpp"

#include "facemorph/error.hpp"
#include "format/file_io.hpp"

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

// The AV1 quantiser (0 finest .. 63 coarsest) of a quality 0..100.
int avif_quantizer(int quality) { return static_cast<int>(std::lround((100 - std::clamp(quality, 0, 100)) * 63 / 100.0)); }

}  // namespace

std::vector<uint8_t> encode_avif(const Image& image, int quality) {
  require_codable(image, false);
  if (avifCodecName(AVIF_CODEC_CHOICE_AOM, AVIF_CODEC_FLAG_CAN_ENCODE) == nullptr) {
    throw Error(ErrorCode::kUnsupported, "AVIF encoding needs libavif built with libaom");
  }
  std::unique_ptr<avifImage, AvifImageFree> yuv(avifImageCreate(static_cast<uint32_t>(image.width), static_cast<uint32_t>(image.height), 8, AVIF_PIXEL_FORMAT_YUV444));
  std::unique_ptr<avifEncoder, AvifEncoderFree> encoder(avifEncoderCreate());
  if (!yuv || !encoder) throw Error(ErrorCode::kInvalidArgument, "AVIF encoding: out of memory");
  // Full-range BT.601, the matrix WebP and JPEG use; every decoder converts back with the matrix the file signals.
  yuv->yuvRange = AVIF_RANGE_FULL;
  yuv->matrixCoefficients = AVIF_MATRIX_COEFFICIENTS_BT601;
  avifRGBImage rgb;
  avifRGBImageSetDefaults(&rgb, yuv.get());
  rgb.format = image.channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.ignoreAlpha = AVIF_TRUE;  // textures are opaque
  rgb.pixels = const_cast<uint8_t*>(image.pixels.data());  // read only: libavif's API is not const
  rgb.rowBytes = static_cast<uint32_t>(image.width * image.channels);
  avifResult result = avifImageRGBToYUV(yuv.get(), &rgb);
  if (result == AVIF_RESULT_OK) {
    const int quantizer = avif_quantizer(quality);
    encoder->minQuantizer = encoder->maxQuantizer = quantizer;
    encoder->speed = 6;       // avifenc's default, 0.06 s for a 448² texture
    encoder->maxThreads = 1;  // the same bytes on every run (with one libaom version)
    // libaom: it codes 4:4:4 (SVT-AV1 does not), and a fixed encoder keeps the bytes reproducible.
    encoder->codecChoice = AVIF_CODEC_CHOICE_AOM;
  }
  AvifBytes bytes;
  if (result == AVIF_RESULT_OK) result = avifEncoderWrite(encoder.get(), yuv.get(), &bytes.data);
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kInvalidArgument, "AVIF encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed: " + avifResultToString(result));
  }
  return std::vector<uint8_t>(bytes.data.data, bytes.data.data + bytes.data.size);
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
  Image image(static_cast<int>(decoded->width), static_cast<int>(decoded->height), channels);
  AvifRgb rgb;
  avifRGBImageSetDefaults(&rgb.rgb, decoded);
  rgb.rgb.format = channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.rgb.depth = 8;
  rgb.rgb.pixels = image.pixels.data();
  rgb.rgb.rowBytes = static_cast<uint32_t>(image.width * channels);
  result = avifImageYUVToRGB(decoded, &rgb.rgb);
  rgb.rgb.pixels = nullptr;  // ours, not libavif's to free
  if (channels == 4 && decoded->alphaPlane == nullptr) {
    for (size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;  // no alpha stored: opaque
  }
  if (result != AVIF_RESULT_OK) throw Error(ErrorCode::kCorrupt, source + ": the AVIF image cannot be converted to RGB (" + avifResultToString(result) + ")");
  return image;
}

const char* texture_codec_name(TextureCodec codec) { return codec == TextureCodec::kAvif ? "avif" : "webp"; }

TextureCodec parse_texture_codec(const std::string& name) {
  if (name == "avif") return TextureCodec::kAvif;
  if (name == "webp") return TextureCodec::kWebp;
  throw Error(ErrorCode::kInvalidArgument, "unknown texture codec '" + name + "' (avif or webp)");
}

TextureCodec stored_texture_codec(TextureCodec codec, int quality) { return quality > 100 ? TextureCodec::kWebp : codec; }

std::vector<uint8_t> encode_texture(TextureCodec codec, const Image& image, int quality) {
  return stored_texture_codec(codec, quality) == TextureCodec::kAvif ? encode_avif(image, quality) : encode_webp(image, quality);
}

Image decode_texture(TextureCodec codec, std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels) {
  return codec == TextureCodec::kAvif ? decode_avif(bytes, source, 3, max_pixels) : decode_webp(bytes, source, 3, max_pixels);
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

void write_png(const std::filesystem::path& path, const Image& image) { format::write_file_atomically(path, encode_png(image)); }

}  // namespace facemorph
