// The texture codecs' names (spec/container.md §8) and the codec a quality is stored in.
#include "codec/core/image/texture_codec.hpp"

#include "format/error.hpp"

namespace facemorph {

const char* texture_codec_name(TextureCodec codec) { return name_of(kTextureCodecs, codec); }

TextureCodec parse_texture_codec(const std::string& name) { return parse_name(kTextureCodecs, name, "texture codec"); }

TextureCodec stored_texture_codec(TextureCodec codec, int quality) { return quality > 100 ? TextureCodec::kWebp : codec; }

}  // namespace facemorph
