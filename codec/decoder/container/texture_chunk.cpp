// A keyframe's texture, TEXR (spec/container.md §8): an M × M image of the disk in one of the
// image codecs the format names.
#include "codec/decoder/container/chunk_readers.hpp"

#include "codec/decoder/image/image_decode.hpp"

namespace facemorph::file_layout {

TextureCodec texture_codec_of(std::span<const uint8_t> payload, const std::string& where, uint32_t number) {
  format::ByteReader r(payload, where);
  if (r.read<uint32_t>("the keyframe number") != number) corrupt(where, "holds another keyframe's texture than the index says");
  const uint32_t number_of_codec = r.read<uint32_t>("the image codec");
  const auto* codec = entry_of_code(kTextureCodecs, number_of_codec);
  if (codec == nullptr) {
    throw Error(ErrorCode::kUnsupported,
                where + ": image codec " + std::to_string(number_of_codec) + " (this decoder reads WebP, 1, and AVIF, 2)");
  }
  return codec->value;
}

Image read_texture(std::span<const uint8_t> payload, const std::string& where, uint32_t number, uint32_t size) {
  const TextureCodec codec = texture_codec_of(payload, where, number);
  constexpr size_t kPreambleBytes = 8;  // the number and the codec
  Image image;
  try {
    // At most the header's M² pixels, from the image's own header before its pixels are decoded.
    image = decode_texture(codec, payload.subspan(kPreambleBytes), where, int64_t{size} * size);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kInvalidArgument) throw;
    corrupt(where, std::string("an image larger than the header's texture size: ") + e.what());  // the file's fault, not the caller's
  }
  if (image.width != static_cast<int>(size) || image.height != static_cast<int>(size)) {
    corrupt(where,
            "a " + std::to_string(image.width) + "x" + std::to_string(image.height) + " texture, the header says " + std::to_string(size));
  }
  return image;
}

}  // namespace facemorph::file_layout
