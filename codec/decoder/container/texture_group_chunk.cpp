// A group's keyframe textures as one AV1 image sequence, TGOP (spec/container.md §8.1, format
// 2.1): the group's first keyframe, the image codec (3), and one AVIF file holding exactly the
// group's keyframes' textures in order, each predicted from those before it.
#include "codec/core/container/file_layout.hpp"

#include "codec/decoder/image/image_codec.hpp"
#include "format/byte_writer.hpp"

#include <algorithm>

namespace facemorph::file_layout {

namespace {

constexpr uint32_t kTextureAvifSequence = 3;  // the format's number for an AVIF image sequence
constexpr size_t kPreambleBytes = 8;          // the first keyframe and the codec

// The chunk's own fields checked against the index's place and the codecs this decoder reads; the
// AVIF file after them.
std::span<const uint8_t> sequence_of(std::span<const uint8_t> payload, const std::string& where, uint32_t first) {
  format::ByteReader r(payload, where);
  const uint32_t number = r.read<uint32_t>("the group's first keyframe");
  if (number != first) corrupt(where, "starts at keyframe " + std::to_string(number) + ", the index places it at keyframe " + std::to_string(first));
  const uint32_t codec = r.read<uint32_t>("the image codec");
  if (codec != kTextureAvifSequence) {
    throw Error(ErrorCode::kUnsupported, where + ": image codec " + std::to_string(codec) + " (this decoder reads an AVIF image sequence, 3, in TGOP)");
  }
  return payload.subspan(kPreambleBytes);
}

}  // namespace

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

TextureGroupReader::TextureGroupReader(std::vector<uint8_t> payload, const std::string& where, uint32_t first, uint32_t count, uint32_t size)
    : payload_(std::move(payload)), sequence_(std::make_unique<AvifSequenceReader>(sequence_of(payload_, where, first), where, count, size)) {}

std::vector<uint64_t> texture_group_sample_bytes(std::span<const uint8_t> payload, const std::string& where, uint32_t first, uint32_t count, uint32_t size) {
  return avif_sequence_sample_bytes(sequence_of(payload, where, first), where, count, size);
}

}  // namespace facemorph::file_layout
