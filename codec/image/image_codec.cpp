#include "facemorph/image_codec.hpp"

#include "facemorph/error.hpp"
#include "format/file_io.hpp"

#include <png.h>
#include <webp/decode.h>
#include <webp/encode.h>

#include <csetjmp>
#include <cstring>

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
