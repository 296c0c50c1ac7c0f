// The codecs a keyframe texture may be stored in, what the container records and the reader and
// writer agree on (spec/container.md §8): the encoding and decoding themselves are the writer's
// (codec/writer/image/image_encode.hpp) and the decoder's (codec/decoder/image/image_decode.hpp).
#pragma once

#include <string>

namespace facemorph {

// The lossy codecs a keyframe texture may be stored in (spec/container.md §8).
enum class TextureCodec { kAvif, kWebp };
const char* texture_codec_name(TextureCodec codec);         // "avif", "webp"
TextureCodec parse_texture_codec(const std::string& name);  // throws kInvalidArgument
// The codec a texture asked for in `codec` at `quality` is stored in: a quality above 100 is
// lossless WebP whatever the codec (AVIF's lossless mode needs an identity matrix, and lossless
// WebP is what facemorph has always written).
TextureCodec stored_texture_codec(TextureCodec codec, int quality);

}  // namespace facemorph
