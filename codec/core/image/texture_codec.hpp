// The codecs a keyframe texture may be stored in, what the container records and the reader and
// writer agree on (spec/container.md §8): the encoding and decoding themselves are the writer's
// (codec/writer/image/image_encode.hpp) and the decoder's (codec/decoder/image/image_decode.hpp).
#pragma once

#include "codec/core/util/enum_names.hpp"

#include <cstdint>
#include <string>

namespace facemorph {

// The lossy codecs a keyframe texture may be stored in (spec/container.md §8).
enum class TextureCodec { kAvif, kWebp };
// Each codec's name (settings, command lines) and the number a TEXR chunk stores (§8). A TGOP's
// AVIF image sequence is number 3 (file_layout::kTextureAvifSequence), not a codec of a still.
inline constexpr CodedEnumName<TextureCodec, uint32_t> kTextureCodecs[] = {{TextureCodec::kAvif, "avif", 2},
                                                                           {TextureCodec::kWebp, "webp", 1}};
static_assert(is_one_to_one(kTextureCodecs));
const char* texture_codec_name(TextureCodec codec);         // "avif", "webp"
TextureCodec parse_texture_codec(const std::string& name);  // throws kInvalidArgument
// The codec a texture asked for in `codec` at `quality` is stored in: a quality above 100 is
// lossless WebP whatever the codec (AVIF's lossless mode needs an identity matrix, and lossless
// WebP is what facemorph has always written).
TextureCodec stored_texture_codec(TextureCodec codec, int quality);

}  // namespace facemorph
