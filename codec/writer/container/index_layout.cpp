// Where a file's chunks after its index go, and the index that names them (spec/container.md §6):
// what the writer of a sequence and the joiner of segments (file_join.cpp) share.
#include "codec/writer/container/chunk_writers.hpp"

namespace facemorph::file_layout {

IndexLayout lay_out_index(uint64_t header_size, std::vector<IndexEntry>& entries, const FileHeader& h,
                          const std::vector<PlacedChunk>& chunks) {
  std::vector<uint8_t> named_group(entries.size(), 0), named_texture(entries.size(), 0);
  for (const PlacedChunk& c : chunks) {
    for (uint32_t k : c.group_of) named_group.at(k) = 1;
    for (uint32_t k : c.texture_of) named_texture.at(k) = 1;
  }
  for (size_t k = 0; k < entries.size(); ++k) {
    if (!named_group[k] || (h.has_texture() && !named_texture[k])) {
      throw Error(ErrorCode::kInvalidArgument, "file layout: keyframe " + std::to_string(k) + " has no chunk");
    }
  }
  IndexLayout laid;
  laid.offsets.resize(chunks.size());
  const auto place = [&](uint64_t index_size) {
    uint64_t offset = format::kPreambleBytes + header_size + index_size;
    for (size_t c = 0; c < chunks.size(); ++c) {
      laid.offsets[c] = offset;
      for (uint32_t k : chunks[c].group_of) entries[k].group_offset = offset;
      for (uint32_t k : chunks[c].texture_of) entries[k].texture_offset = offset;
      offset += chunks[c].size;
    }
    laid.end = offset;
  };
  constexpr int kIndexLayouts = 8;
  uint64_t index_size = 0;
  for (int attempt = 0; attempt <= kIndexLayouts; ++attempt) {
    place(index_size);
    const int level = attempt < kIndexLayouts ? 19 : 0;
    laid.index = format::prepare_chunk(kIndexChunk, write_index(entries, h), true, level);
    if (laid.index.total_size() == index_size) break;
    index_size = laid.index.total_size();
    if (level == 0) {  // its size does not depend on the offsets: once more with them right
      place(index_size);
      laid.index = format::prepare_chunk(kIndexChunk, write_index(entries, h), true, 0);
      break;
    }
  }
  return laid;
}

}  // namespace facemorph::file_layout
