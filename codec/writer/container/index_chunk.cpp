// The keyframe index, KIDX (spec/container.md §6), as the writer lays it out; the reader is
// codec/decoder/container/index_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include "format/byte_writer.hpp"

namespace facemorph::file_layout {

using format::ByteWriter;

// Each kind of number in a run of its own, which the chunk's zstd packs: the times, each pose
// component's changes from keyframe to keyframe, the group offsets, the texture offsets.
std::vector<uint8_t> write_index(const std::vector<IndexEntry>& entries, const FileHeader& h) {
  ByteWriter w;
  w.write(static_cast<uint32_t>(entries.size()));
  for (const IndexEntry& e : entries) w.write(e.time);
  for (size_t i = 0; i < kPoseCodes; ++i) {
    int64_t previous = 0;
    for (const IndexEntry& e : entries) {
      write_varint(w, e.pose[i] - previous);
      previous = e.pose[i];
    }
  }
  for (size_t k = 0; k < entries.size(); k += h.group_size()) w.write(entries[k].group_offset);
  if (h.texture_groups()) {  // one TGOP per group (format 2.1)
    for (size_t k = 0; k < entries.size(); k += h.group_size()) w.write(entries[k].texture_offset);
  } else if (h.has_texture()) {
    for (const IndexEntry& e : entries) w.write(e.texture_offset);
  }
  return w.take();
}

}  // namespace facemorph::file_layout
