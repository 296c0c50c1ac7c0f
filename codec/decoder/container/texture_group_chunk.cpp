// A group's keyframe textures as one AV1 image sequence, TGOP (spec/container.md §8.1, format
// 2.1): the group's first keyframe, the image codec (3), and one AVIF file holding exactly the
// group's keyframes' textures in order, each predicted from those before it.
#include "codec/decoder/container/chunk_readers.hpp"

#include "codec/decoder/image/image_decode.hpp"

namespace facemorph::file_layout {

namespace {

// The chunk's own fields checked against the index's place and the codecs this decoder reads; the
// AVIF file after them.
std::span<const uint8_t> sequence_of(std::span<const uint8_t> payload, const std::string& where, uint32_t first) {
  format::ByteReader r(payload, where);
  const uint32_t number = r.read<uint32_t>("the group's first keyframe");
  if (number != first)
    corrupt(where, "starts at keyframe " + std::to_string(number) + ", the index places it at keyframe " + std::to_string(first));
  const uint32_t codec = r.read<uint32_t>("the image codec");
  if (codec != kTextureAvifSequence) {
    throw Error(ErrorCode::kUnsupported,
                where + ": image codec " + std::to_string(codec) + " (this decoder reads an AVIF image sequence, 3, in TGOP)");
  }
  return payload.subspan(kTextureGroupPreambleBytes);
}

}  // namespace

TextureGroupReader::TextureGroupReader(std::vector<uint8_t> payload, const std::string& where, uint32_t first, uint32_t count,
                                       uint32_t size)
    : payload_(std::move(payload)),
      sequence_(std::make_unique<AvifSequenceReader>(sequence_of(payload_, where, first), where, count, size)) {}

std::vector<uint64_t> texture_group_sample_bytes(std::span<const uint8_t> payload, const std::string& where, uint32_t first, uint32_t count,
                                                 uint32_t size) {
  return avif_sequence_sample_bytes(sequence_of(payload, where, first), where, count, size);
}

}  // namespace facemorph::file_layout
