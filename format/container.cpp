#include "format/container.hpp"

#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/checksum.hpp"
#include "format/error.hpp"
#include "format/header_dictionary.hpp"
#include "format/spill_file.hpp"
#include "format/zstd_frame.hpp"

#include <algorithm>
#include <ostream>

namespace facemorph::format {

namespace {

bool valid_type(std::string_view type) {
  return type.size() == 4 && std::all_of(type.begin(), type.end(), [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); });
}

void write_chunk(std::vector<uint8_t>& out, std::string_view type, uint32_t flags, uint64_t raw_size, std::span<const uint8_t> stored) {
  ByteWriter w;
  w.bytes({reinterpret_cast<const uint8_t*>(type.data()), 4});
  w.write(flags);
  w.write(static_cast<uint64_t>(stored.size()));
  w.write(raw_size);
  w.bytes(stored);
  w.write(crc32(w.data()));
  out.insert(out.end(), w.data().begin(), w.data().end());
}

}  // namespace

PreparedChunk prepare_chunk(std::string_view type, std::vector<uint8_t> payload, bool critical, int zstd_level, Dictionary dictionary) {
  if (!valid_type(type) || type == kEndChunk) {
    throw Error(ErrorCode::kInvalidArgument, "chunk type '" + std::string(type) + "' is not four characters [A-Z0-9] (or is reserved)");
  }
  if (payload.size() > kMaxPayloadBytes) throw Error(ErrorCode::kInvalidArgument, "chunk " + std::string(type) + " payload over 1 GiB");
  PreparedChunk chunk;
  chunk.type = std::string(type);
  chunk.flags = critical ? kChunkCritical : 0;
  chunk.raw_size = payload.size();
  if (zstd_level > 0 && !payload.empty()) {
    std::vector<uint8_t> packed = compress_frame(payload, zstd_level);
    uint32_t flags = kChunkCompressed;
    if (dictionary == Dictionary::kHeader) {
      std::vector<uint8_t> against = compress_frame(payload, zstd_level, header_dictionary());
      if (against.size() < packed.size()) {
        packed = std::move(against);
        flags |= kChunkDictionary;
      }
    }
    if (packed.size() < payload.size()) {
      chunk.flags |= flags;
      chunk.stored = std::move(packed);
      return chunk;
    }
  }
  chunk.stored = std::move(payload);
  return chunk;
}

ContainerWriter::ContainerWriter(const ContainerKind& kind) {
  ByteWriter w;
  w.bytes(kind.magic);
  w.write(kind.major);
  w.write(kind.minor);
  w.write(crc32(w.data()));
  bytes_ = w.take();
  size_ = bytes_.size();
}

ContainerWriter::ContainerWriter(std::ostream& out, const ContainerKind& kind) : ContainerWriter(kind) {
  out_ = &out;
  flush();
}

void ContainerWriter::flush() {
  if (out_ == nullptr) return;
  out_->write(reinterpret_cast<const char*>(bytes_.data()), static_cast<std::streamsize>(bytes_.size()));
  // Failing at once: a full disk would otherwise take every chunk still to come.
  if (!*out_) throw Error(ErrorCode::kIo, "write failed (disk full?)");
  bytes_.clear();
}

uint64_t ContainerWriter::add(const PreparedChunk& chunk) {
  const uint64_t offset = size_;
  write_chunk(bytes_, chunk.type, chunk.flags, chunk.raw_size, chunk.stored);
  size_ += chunk.total_size();
  ++chunk_count_;
  flush();
  return offset;
}

std::vector<uint8_t> ContainerWriter::finish() {
  ByteWriter count;
  count.write(chunk_count_);
  write_chunk(bytes_, kEndChunk, kChunkCritical, count.size(), count.data());
  size_ += end_chunk_size();
  chunk_count_ = 0;
  flush();
  return std::move(bytes_);
}

uint64_t ContainerWriter::end_chunk_size() { return kChunkHeaderBytes + sizeof(uint32_t) + kChunkTrailerBytes; }

struct ChunkSpool::Kept {
  std::string type;
  uint32_t flags = 0;
  uint64_t raw_size = 0, stored_size = 0;
  std::vector<uint8_t> stored;  // Keep::kMemory
  SpillFile::Record record;     // Keep::kSpill
};

ChunkSpool::ChunkSpool(Keep keep) : keep_(keep) {
  if (keep == Keep::kSpill) file_ = std::make_unique<SpillFile>("the container's chunks");
}

ChunkSpool::~ChunkSpool() = default;

size_t ChunkSpool::add(PreparedChunk chunk) {
  Kept kept{std::move(chunk.type), chunk.flags, chunk.raw_size, chunk.stored.size(), {}, {}};
  if (keep_ == Keep::kMemory) kept.stored = std::move(chunk.stored);
  if (keep_ == Keep::kSpill) kept.record = file_->append(reinterpret_cast<const char*>(chunk.stored.data()), chunk.stored.size());
  bytes_held_ += kept.stored.size();
  chunks_.push_back(std::move(kept));
  return chunks_.size() - 1;
}

uint64_t ChunkSpool::total_size(size_t id) const { return kChunkHeaderBytes + chunks_.at(id).stored_size + kChunkTrailerBytes; }

PreparedChunk ChunkSpool::get(size_t id) const {
  const Kept& kept = chunks_.at(id);
  if (keep_ == Keep::kSizes) throw Error(ErrorCode::kInvalidArgument, "chunk spool: only the chunks' sizes are kept");
  PreparedChunk chunk{kept.type, kept.flags, kept.raw_size, kept.stored};
  if (keep_ == Keep::kSpill) {
    const std::vector<char> bytes = file_->read(kept.record);
    chunk.stored.assign(bytes.begin(), bytes.end());
  }
  return chunk;
}

ContainerReader::ContainerReader(std::span<const uint8_t> file, std::string source, uint64_t max_chunks, const ContainerKind& kind)
    : file_(file), source_(std::move(source)) {
  ByteReader r(file, source_);
  if (file.size() >= kind.magic.size() && !std::equal(kind.magic.begin(), kind.magic.end(), file.begin())) {
    throw Error(ErrorCode::kCorrupt, source_ + ": not a " + kind.name + " (bad magic)");
  }
  r.skip(kind.magic.size(), "the magic");
  major_ = r.read<uint16_t>("the major version");
  minor_ = r.read<uint16_t>("the minor version");
  const uint32_t crc = r.read<uint32_t>("the preamble checksum");
  if (crc != crc32(file.first(12))) throw Error(ErrorCode::kCorrupt, source_ + ": preamble checksum mismatch");
  // Flag bit 2 came with the header dictionary: in an older file it is a reserved bit.
  if (minor_ >= kind.dictionary_minor) known_flags_ |= kChunkDictionary;
  if (major_ == 1 && kind.magic == kMagic) {
    // Format 1.x was written by facemorph 0.2-0.7 only, before the format was frozen at 2.0.
    throw Error(ErrorCode::kUnsupported, source_ + ": format version 1." + std::to_string(minor_) +
                                             " is an experimental version this decoder does not read; encode the capture again");
  }
  if (major_ != kind.major) {
    throw Error(ErrorCode::kUnsupported, source_ + ": format version " + std::to_string(major_) + "." + std::to_string(minor_) +
                                             " (this reader reads " + std::to_string(kind.major) + ".x)");
  }
  while (true) {
    ChunkView chunk;
    chunk.offset = r.position();
    const std::string at = " at offset " + std::to_string(chunk.offset);
    const auto type = r.bytes(4, "a chunk type");
    chunk.type.assign(type.begin(), type.end());
    if (!valid_type(chunk.type)) throw Error(ErrorCode::kCorrupt, source_ + ": chunk" + at + " has an invalid type");
    const std::string name = "chunk " + chunk.type + at;
    chunk.flags = r.read<uint32_t>("a chunk's flags");
    const uint64_t stored = r.read<uint64_t>("a chunk's size");
    chunk.raw_size = r.read<uint64_t>("a chunk's size");
    if ((chunk.flags & ~known_flags_) != 0) throw Error(ErrorCode::kCorrupt, source_ + ": " + name + " sets reserved flags");
    if (chunk.against_dictionary() && !chunk.compressed())
      throw Error(ErrorCode::kCorrupt, source_ + ": " + name + " sets the dictionary flag (bit 2) on a payload that is not compressed");
    if (stored > kMaxPayloadBytes || chunk.raw_size > kMaxPayloadBytes)
      throw Error(ErrorCode::kCorrupt, source_ + ": " + name + " announces over 1 GiB");
    if (!chunk.compressed() && chunk.raw_size != stored)
      throw Error(ErrorCode::kCorrupt, source_ + ": " + name + " has inconsistent sizes");
    if (stored + kChunkTrailerBytes > r.remaining()) {
      throw Error(ErrorCode::kTruncated, source_ + ": truncated: " + name + " needs " + std::to_string(stored + kChunkTrailerBytes) +
                                             " bytes, only " + std::to_string(r.remaining()) + " left");
    }
    chunk.stored = r.bytes(static_cast<size_t>(stored), "a chunk's payload");
    chunk.crc = r.read<uint32_t>("a chunk's checksum");
    if (chunk.type == kEndChunk) {
      if (crc32(file.subspan(chunk.offset, kChunkHeaderBytes + stored)) != chunk.crc) {
        throw Error(ErrorCode::kCorrupt, source_ + ": checksum mismatch in the end chunk" + at);
      }
      ByteReader end(chunk.stored, source_ + " end chunk");
      const uint32_t count = end.read<uint32_t>("the chunk count");
      if (count != chunks_.size()) {
        throw Error(ErrorCode::kCorrupt, source_ + ": the end chunk counts " + std::to_string(count) + " chunks, the file holds " +
                                             std::to_string(chunks_.size()));
      }
      if (r.remaining() != 0)
        throw Error(ErrorCode::kCorrupt, source_ + ": " + std::to_string(r.remaining()) + " bytes after the end chunk");
      return;
    }
    if (chunks_.size() >= max_chunks) {
      throw Error(ErrorCode::kLimit, source_ + ": more than " + std::to_string(max_chunks) +
                                         " chunks, over the limit the keyframe limit sets (max_keyframes)");
    }
    chunks_.push_back(std::move(chunk));
    if (r.remaining() == 0) throw Error(ErrorCode::kTruncated, source_ + ": truncated: the file ends without its end chunk");
  }
}

const ChunkView& ContainerReader::chunk_at(uint64_t offset, const std::string& what) const {
  auto it = std::lower_bound(chunks_.begin(), chunks_.end(), offset, [](const ChunkView& c, uint64_t o) { return c.offset < o; });
  if (it == chunks_.end() || it->offset != offset) {
    throw Error(ErrorCode::kCorrupt, source_ + ": " + what + " points at offset " + std::to_string(offset) + ", where no chunk starts");
  }
  return *it;
}

std::string ContainerReader::describe(const ChunkView& chunk) const {
  return "chunk " + chunk.type + " at offset " + std::to_string(chunk.offset);
}

std::vector<uint8_t> ContainerReader::payload(const ChunkView& chunk, uint64_t max_bytes) const {
  if (crc32(file_.subspan(chunk.offset, kChunkHeaderBytes + chunk.stored.size())) != chunk.crc) {
    throw Error(ErrorCode::kCorrupt, source_ + ": checksum mismatch in " + describe(chunk));
  }
  if (!chunk.compressed()) {
    if (chunk.stored.size() > max_bytes) {
      throw Error(ErrorCode::kLimit, source_ + ": " + describe(chunk) + " holds " + std::to_string(chunk.stored.size()) +
                                         " bytes, over the memory limit of " + std::to_string(max_bytes));
    }
    return {chunk.stored.begin(), chunk.stored.end()};
  }
  if (announced_size(chunk.stored) != chunk.raw_size) {
    throw Error(ErrorCode::kCorrupt, source_ + ": " + describe(chunk) + ": the zstd frame does not announce the chunk's size");
  }
  if (!possible_content_size(chunk.stored.size(), chunk.raw_size)) {
    throw Error(ErrorCode::kCorrupt, source_ + ": " + describe(chunk) + " announces " + std::to_string(chunk.raw_size) + " bytes from " +
                                         std::to_string(chunk.stored.size()) + ", more than zstd can expand");
  }
  if (chunk.raw_size > max_bytes) {
    throw Error(ErrorCode::kLimit, source_ + ": " + describe(chunk) + " decompresses to " + std::to_string(chunk.raw_size) +
                                       " bytes, over the memory limit of " + std::to_string(max_bytes));
  }
  if (chunk.against_dictionary()) {
    // Its checksum is what tells a frame made against other bytes (or none) from one made against these.
    if (!has_content_checksum(chunk.stored))
      throw Error(ErrorCode::kCorrupt, source_ + ": " + describe(chunk) + ": a zstd frame against the header dictionary without its content checksum");
    std::optional<std::vector<uint8_t>> out = decompress_frame_growing(chunk.stored, chunk.raw_size, header_dictionary());
    if (!out) throw Error(ErrorCode::kCorrupt, source_ + ": " + describe(chunk) + ": does not decompress against the header dictionary (damaged, or made against other bytes)");
    return std::move(*out);
  }
  std::optional<std::vector<uint8_t>> out = decompress_frame_growing(chunk.stored, chunk.raw_size);
  if (!out) throw Error(ErrorCode::kCorrupt, source_ + ": " + describe(chunk) + ": damaged zstd payload");
  return std::move(*out);
}

void ContainerReader::verify() const {
  for (const ChunkView& chunk : chunks_) {
    if (crc32(file_.subspan(chunk.offset, kChunkHeaderBytes + chunk.stored.size())) != chunk.crc) {
      throw Error(ErrorCode::kCorrupt, source_ + ": checksum mismatch in " + describe(chunk));
    }
  }
}

}  // namespace facemorph::format
