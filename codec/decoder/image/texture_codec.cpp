// What the image codecs share whichever codecs are built (image_codec.cpp with libavif, libwebp and
// libpng; image_codec_none.cpp without them, for the browser, which decodes the images itself):
// codec names, the choice of codec for a quality, and the dispatch to the codec's functions.
#include "codec/decoder/image/image_codec.hpp"

#include "format/error.hpp"
#include "format/file_io.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {

const char* texture_codec_name(TextureCodec codec) { return codec == TextureCodec::kAvif ? "avif" : "webp"; }

TextureCodec parse_texture_codec(const std::string& name) {
  if (name == "avif") return TextureCodec::kAvif;
  if (name == "webp") return TextureCodec::kWebp;
  throw Error(ErrorCode::kInvalidArgument, "unknown texture codec '" + name + "' (avif or webp)");
}

int avif_quantizer(int quality) { return static_cast<int>(std::lround((100 - std::clamp(quality, 0, 100)) * 63 / 100.0)); }

TextureCodec stored_texture_codec(TextureCodec codec, int quality) { return quality > 100 ? TextureCodec::kWebp : codec; }

std::vector<uint8_t> encode_texture(TextureCodec codec, const Image& image, int quality) {
  return stored_texture_codec(codec, quality) == TextureCodec::kAvif ? encode_avif(image, quality) : encode_webp(image, quality);
}

Image decode_texture(TextureCodec codec, std::span<const uint8_t> bytes, const std::string& source, int64_t max_pixels) {
  return codec == TextureCodec::kAvif ? decode_avif(bytes, source, 3, max_pixels) : decode_webp(bytes, source, 3, max_pixels);
}

void write_png(const std::filesystem::path& path, const Image& image) { format::write_file_atomically(path, encode_png(image)); }

uint64_t image_content_hash(const Image& image) {
  uint64_t hash = 1469598103934665603ull;
  const auto mix = [&hash](uint64_t byte) { hash = (hash ^ byte) * 1099511628211ull; };
  for (int v : {image.width, image.height, image.channels}) mix(static_cast<uint32_t>(v));
  for (uint8_t byte : image.pixels) mix(byte);
  return hash;
}

}  // namespace facemorph
