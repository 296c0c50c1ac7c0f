// The container's outer layer (spec/container.md §2-3): a preamble (magic, version) and a sequence
// of chunks, each with a type, flags, sizes and a CRC-32, optionally zstd-compressed, closed by an
// end chunk. It knows chunk types and bytes, nothing of what the payloads mean: the sequence file
// (codec/container) gives them meaning.
#pragma once

#include <array>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace facemorph::format {

class SpillFile;

inline constexpr std::array<uint8_t, 8> kMagic = {0x89, 'F', 'M', 'V', '\r', '\n', 0x1A, '\n'};
inline constexpr uint16_t kMajorVersion = 2;  // a reader refuses another major version
inline constexpr uint16_t kMinorVersion = 6;  // later minors only append fields, chunk types and codings (2.1: texture groups; 2.2: shared
                                              // textures; 2.3: residual frames; 2.4: frame patches; 2.5: linear along the rim,
                                              // range-coded patches, the header dictionary;
                                              // 2.6: the levels predictor, KGLV)
inline constexpr size_t kPreambleBytes = 16;
inline constexpr size_t kChunkHeaderBytes = 24;
inline constexpr size_t kChunkTrailerBytes = 4;
inline constexpr uint64_t kMaxPayloadBytes = uint64_t{1} << 30;  // stored or decompressed
inline constexpr std::string_view kEndChunk = "FEND";

inline constexpr uint16_t kNoDictionary = UINT16_MAX;
inline constexpr uint16_t kDictionaryMinorVersion = 5;  // the header dictionary's first version

// Which file a container is: its magic and the version its writer writes and its reader reads (the
// same major only). The chunk layer is shared: the facemorph file (.fmv) and the staged encode's
// part file (.fms, spec/part-file.md) are both containers of this kind, told apart by the magic.
struct ContainerKind {
  std::array<uint8_t, 8> magic;
  uint16_t major = 0, minor = 0;
  const char* name = "";  // in errors: "facemorph container"
  // The first minor version whose chunks may be compressed against the header dictionary (chunk
  // flag bit 2, header_dictionary.hpp); kNoDictionary where none may.
  uint16_t dictionary_minor = kNoDictionary;
};
inline constexpr ContainerKind kSequenceContainer{kMagic, kMajorVersion, kMinorVersion, "facemorph container", kDictionaryMinorVersion};

// Chunk flags (spec/container.md §3). Other bits are reserved: written 0, rejected when set.
inline constexpr uint32_t kChunkCompressed = 1;  // the payload is one zstd frame
inline constexpr uint32_t kChunkCritical = 2;    // a reader that does not know the type must refuse the file
inline constexpr uint32_t kChunkDictionary = 4;  // format 2.5: the zstd frame is compressed against the header dictionary
inline constexpr uint32_t kChunkKnownFlags = kChunkCompressed | kChunkCritical;  // in every version

// A chunk as found in a file: where it is, and its stored payload as a view into the file's bytes.
struct ChunkView {
  std::string type;  // four characters [A-Z0-9]
  uint32_t flags = 0;
  uint64_t offset = 0;    // of the chunk header in the file
  uint64_t raw_size = 0;  // the payload's size once decompressed
  std::span<const uint8_t> stored;
  uint32_t crc = 0;  // as stored
  bool compressed() const { return (flags & kChunkCompressed) != 0; }
  bool critical() const { return (flags & kChunkCritical) != 0; }
  bool against_dictionary() const { return (flags & kChunkDictionary) != 0; }
  uint64_t total_size() const { return kChunkHeaderBytes + stored.size() + kChunkTrailerBytes; }
};

// A chunk ready to be written: its payload already compressed (or not), so its size is known before
// it is placed (the index needs the offsets of later chunks).
struct PreparedChunk {
  std::string type;
  uint32_t flags = 0;
  uint64_t raw_size = 0;
  std::vector<uint8_t> stored;
  uint64_t total_size() const { return kChunkHeaderBytes + stored.size() + kChunkTrailerBytes; }
};

// Prepares a chunk. With `zstd_level` > 0 the payload is compressed and kept compressed only where
// that is smaller; with `dictionary` too, it is also compressed against the header dictionary, and
// the smallest of the three is kept (flag bit 2 where it is the dictionary's frame). Throws
// kInvalidArgument for a type that is not four [A-Z0-9] characters, the end chunk's type, or a
// payload over kMaxPayloadBytes.
enum class Dictionary { kNone, kHeader };
PreparedChunk prepare_chunk(std::string_view type, std::vector<uint8_t> payload, bool critical, int zstd_level = 0,
                            Dictionary dictionary = Dictionary::kNone);

// Builds a container: the preamble, then chunks in the order added, then the end chunk. In memory,
// or streamed to `out` as each chunk is added (memory holds one chunk).
class ContainerWriter {
 public:
  explicit ContainerWriter(const ContainerKind& kind = kSequenceContainer);
  explicit ContainerWriter(std::ostream& out, const ContainerKind& kind = kSequenceContainer);
  // Appends a chunk and returns its offset in the file. Streamed, throws kIo as soon as `out`
  // fails (a full disk).
  uint64_t add(const PreparedChunk& chunk);
  uint64_t size() const { return size_; }  // the file's so far (after finish(), all of it)
  // Appends the end chunk and returns the file's bytes (nothing when streamed); the writer is
  // empty afterwards.
  std::vector<uint8_t> finish();
  // What the end chunk adds to a container's size.
  static uint64_t end_chunk_size();

 private:
  void flush();

  std::ostream* out_ = nullptr;
  std::vector<uint8_t> bytes_;  // all of the file in memory; streamed, what is not yet written
  uint64_t size_ = 0;
  uint32_t chunk_count_ = 0;
};

// Where a writer keeps the chunks it has prepared until it knows their order and offsets (a
// container's index comes before the chunks it points at): in memory; in an unlinked temporary
// file (spill_file.hpp), so that a writer streaming a long file holds one chunk, not the file; or
// only their sizes, for a writer that measures a file without writing it.
class ChunkSpool {
 public:
  enum class Keep { kMemory, kSpill, kSizes };
  explicit ChunkSpool(Keep keep);
  ~ChunkSpool();
  ChunkSpool(const ChunkSpool&) = delete;
  ChunkSpool& operator=(const ChunkSpool&) = delete;
  // Keeps `chunk` and returns its number (0, 1, ... in the order added).
  size_t add(PreparedChunk chunk);
  // Chunk `id` as it will be in the file: header, stored payload and trailer.
  uint64_t total_size(size_t id) const;
  // Chunk `id` as added. Throws kInvalidArgument where only sizes are kept, kIo where the temporary
  // file cannot be read back.
  PreparedChunk get(size_t id) const;
  // The chunks' payload bytes the spool holds in memory (0 unless Keep::kMemory).
  uint64_t bytes_held() const { return bytes_held_; }

 private:
  struct Kept;
  Keep keep_;
  std::vector<Kept> chunks_;
  std::unique_ptr<SpillFile> file_;
  uint64_t bytes_held_ = 0;
};

// Reads a container from its bytes (which must outlive the reader). The constructor checks the
// preamble and walks every chunk header to the end chunk (sizes, flags, types, what follows the end
// chunk); payload CRCs are checked when a payload is taken, or all at once by verify(). Every error
// names `source`, the chunk and its offset: kTruncated when the bytes end early, kCorrupt for a bad
// magic, checksum or impossible value, kUnsupported for another major version or an unknown
// critical chunk. `max_chunks`: kLimit past that many chunks, before the list of them grows further
// (a file's size alone does not bound it where the file is mapped rather than read).
class ContainerReader {
 public:
  ContainerReader(std::span<const uint8_t> file, std::string source, uint64_t max_chunks = UINT64_MAX,
                  const ContainerKind& kind = kSequenceContainer);

  uint16_t major_version() const { return major_; }
  uint16_t minor_version() const { return minor_; }
  const std::string& source() const { return source_; }
  // Every chunk before the end chunk, in file order (unknown, non-critical types included).
  const std::vector<ChunkView>& chunks() const { return chunks_; }
  // The chunk starting at `offset` (an index entry), or kCorrupt naming `what`.
  const ChunkView& chunk_at(uint64_t offset, const std::string& what) const;
  // The payload, its CRC checked and decompressed to exactly raw_size bytes (kCorrupt otherwise;
  // against the header dictionary where the chunk's flag bit 2 says so).
  // A raw size over `max_bytes` (the caller's memory budget) is kLimit before anything is
  // allocated, a stored payload's as a compressed one's; a compressed payload is allocated as it decompresses, so a frame that announces
  // more than it holds costs what it holds.
  std::vector<uint8_t> payload(const ChunkView& chunk, uint64_t max_bytes = kMaxPayloadBytes) const;
  // Checks every chunk's CRC.
  void verify() const;
  // "chunk KEYF at offset 1234" for messages.
  std::string describe(const ChunkView& chunk) const;

 private:
  std::span<const uint8_t> file_;
  std::string source_;
  uint16_t major_ = 0, minor_ = 0;
  uint32_t known_flags_ = kChunkKnownFlags;  // with kChunkDictionary from the kind's dictionary_minor on
  std::vector<ChunkView> chunks_;
};

}  // namespace facemorph::format
