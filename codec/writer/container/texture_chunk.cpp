// A keyframe's texture, TEXR (spec/container.md §8), and a group's textures as one AV1 image
// sequence, TGOP (§8.1, format 2.1), as the writer codes them; the readers are
// codec/decoder/container/texture_chunk.cpp and texture_group_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include "codec/writer/image/image_encode.hpp"
#include "format/byte_writer.hpp"

#include <algorithm>

namespace facemorph::file_layout {

std::vector<uint8_t> write_texture(const Image& texture, uint32_t number, TextureCodec codec, int quality) {
  format::ByteWriter w;
  w.write(number);
  w.write(code_of(kTextureCodecs, stored_texture_codec(codec, quality)));
  w.bytes(encode_texture(codec, texture, quality));
  return w.take();
}

bool uses_texture_groups(bool has_texture, const SequenceFileMetadata& metadata) {
  if (!has_texture || metadata.texture_coding != TextureCoding::kSequence || metadata.texture_codec != TextureCodec::kAvif) return false;
  const std::vector<int>& qualities = metadata.keyframe_texture_qualities;
  if (qualities.empty()) return metadata.texture_quality <= 100;
  return std::all_of(qualities.begin(), qualities.end(), [](int q) { return q <= 100; });
}

TextureGroupWriter::TextureGroupWriter(size_t first, int quality) : first_(first), sequence_(quality) {}

std::vector<uint8_t> TextureGroupWriter::finish() {
  format::ByteWriter w;
  w.write(static_cast<uint32_t>(first_));
  w.write(kTextureAvifSequence);
  w.bytes(sequence_.finish());
  return w.take();
}

}  // namespace facemorph::file_layout
