// The image decoders of a build without libavif, libwebp and libpng (FACEMORPH_IMAGE_CODECS=OFF): the
// WebAssembly decoder, whose textures the browser decodes itself (createImageBitmap, ImageDecoder),
// so that the module carries no AV1 decoder twice. Every codec call is kUnsupported, naming why; a
// player of this build asks for no texture buffer and blends the keyframes' images itself with the
// weights fm_decoder_get_texture_weights gives (spec/web.md).
#include "codec/decoder/image/image_decode.hpp"

#include "format/error.hpp"

namespace facemorph {

namespace {

[[noreturn]] void no_codec(const char* what, const std::string& source = "") {
  throw Error(ErrorCode::kUnsupported,
              (source.empty() ? std::string() : source + ": ") + what +
                  ": this decoder was built without image codecs (FACEMORPH_IMAGE_CODECS=OFF); its player decodes the textures");
}

}  // namespace

Image decode_webp(std::span<const uint8_t>, const std::string& source, int, int64_t) { no_codec("WebP decoding", source); }
Image decode_avif(std::span<const uint8_t>, const std::string& source, int, int64_t) { no_codec("AVIF decoding", source); }
struct AvifSequenceReader::State {};
AvifSequenceReader::AvifSequenceReader(std::span<const uint8_t>, std::string source, uint32_t, uint32_t) {
  no_codec("AVIF sequence decoding", source);
}
AvifSequenceReader::~AvifSequenceReader() = default;
uint32_t AvifSequenceReader::next() const { return 0; }
Image AvifSequenceReader::read(bool) { no_codec("AVIF sequence decoding"); }
void decode_avif_sequence(std::span<const uint8_t>, const std::string& source, uint32_t, uint32_t, uint32_t,
                          const std::function<bool(uint32_t)>&, const std::function<void(uint32_t, Image&&)>&) {
  no_codec("AVIF sequence decoding", source);
}
std::vector<uint64_t> avif_sequence_sample_bytes(std::span<const uint8_t>, const std::string& source, uint32_t, uint32_t) {
  no_codec("AVIF sequence parsing", source);
}
Image decode_png(std::span<const uint8_t>, const std::string& source, int64_t) { no_codec("PNG decoding", source); }
Image decode_texture(TextureCodec codec, std::span<const uint8_t>, const std::string& source, int64_t) {
  no_codec(codec == TextureCodec::kAvif ? "AVIF decoding" : "WebP decoding", source);
}

}  // namespace facemorph
