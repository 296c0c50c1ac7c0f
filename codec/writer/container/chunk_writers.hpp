// The writers of a .fmv file's chunks (spec/container.md), the readers' counterparts
// (codec/decoder/container/chunk_readers.hpp): what an encoder links and a player does not.
#pragma once

#include "codec/core/container/file_layout.hpp"
#include "codec/writer/image/image_encode.hpp"

#include <cstdint>
#include <memory>
#include <span>
#include <optional>
#include <string>
#include <vector>

namespace facemorph::file_layout {

// The header of a file of the outline's keyframes, all sharing the fixed-frame nodes `fixed`.
std::vector<uint8_t> write_header(const SequenceOutline& s, const std::vector<int32_t>& fixed, const SequenceFileMetadata& metadata,
                                  TextureLayout textures);

std::vector<uint8_t> write_index(const std::vector<IndexEntry>& entries, const FileHeader& h);

// The payload of the outline's residual frames (not empty): times on the file's lattice
// (residual_time), corrections multiples of a power of two 2^-e (e <= kMaxResidualStepExponent)
// summing to 0 exactly; kInvalidArgument otherwise.
std::vector<uint8_t> write_residuals(const SequenceOutline& outline);

// The PTCH payload of the outline's frame patches (not empty), in format 2.5's range-coded coding
// (§7.5.1): times on the file's lattice (residual_time), every displacement component a whole
// multiple of one step; kInvalidArgument otherwise.
std::vector<uint8_t> write_patches(const SequenceOutline& outline);

// An item's time in either chunk (the readers' read_item_time): written as its change from the
// previous item's code `previous` (updated) in 64ths of a frame period from the outline's first
// time. False, writing nothing, where the time is not on that lattice, not after the previous one or
// past kMaxTimeCode.
bool write_item_time(format::ByteWriter& w, double time, const SequenceOutline& outline, int64_t& previous);
// The same change, not written (format 2.5's range-coded PTCH codes it); nullopt where
// write_item_time writes nothing.
std::optional<int64_t> item_time_change(double time, const SequenceOutline& outline, int64_t& previous);

// ---- Where the chunks after the index go (index_layout.cpp) ----

// A chunk after the index, in file order: its size in the file (header, payload and checksum), and
// the keyframes whose index entries name it, as their group's KGOP or as their texture (a TEXR or
// their group's TGOP).
struct PlacedChunk {
  uint64_t size = 0;
  std::vector<uint32_t> group_of, texture_of;
};
struct IndexLayout {
  format::PreparedChunk index;    // the KIDX chunk, its entries' offsets set
  std::vector<uint64_t> offsets;  // each placed chunk's
  uint64_t end = 0;               // where the end chunk goes
};
// The index of `entries` (their times and poses as given) over `chunks` placed in order after the
// preamble, a header chunk of `header_size` bytes and the index itself. The index's size depends
// on the offsets it holds (it is compressed), so it is laid out again until its size stays put,
// and stored uncompressed (a size the offsets do not change) in the unlikely case it keeps
// changing. kInvalidArgument where a keyframe is named by no group or, in a file with textures, by
// no texture chunk.
IndexLayout lay_out_index(uint64_t header_size, std::vector<IndexEntry>& entries, const FileHeader& h,
                          const std::vector<PlacedChunk>& chunks);

// Where a keyframe's field bytes go: each of its 14 arrays' bits (spec/container.md §7.1's order)
// under the prediction the group writer chooses for it (from nothing, or from `previous`'s codes
// where that costs less in all), each counted with fresh models by the range coder's own cost. An
// estimate of the array's share of the stream: the stream's models carry over from array to array
// where they are shared (b from a, ...) and from keyframe to keyframe. fminfo --field-bytes prints it.
// `minor_version`: the file's, whose predictors the writer chose among (§7.2: 2.5 added one).
std::vector<double> keyframe_array_bits(const Keyframe& key, const Keyframe* previous, const FieldCoding& coding, const GridFacts& grid,
                                        uint16_t minor_version);

// A group's payload from its keyframes first, first + 1, … given in order (their fields and hole
// levels only: times and poses are the index's), one at a time: what is kept between them is the
// previous keyframe's codes and the range coder's state. `coding` and `grid` outlive the writer;
// every keyframe's arrays have one set of lengths (the caller checks). `minor_version`: the file's,
// whose predictors it may choose (§7.2; an older one than the writer's own only in tests' files).
class KeyframeGroupWriter {
 public:
  KeyframeGroupWriter(size_t first, const FieldCoding& coding, const GridFacts& grid, uint16_t minor_version = format::kMinorVersion);
  ~KeyframeGroupWriter();
  KeyframeGroupWriter(const KeyframeGroupWriter&) = delete;
  KeyframeGroupWriter& operator=(const KeyframeGroupWriter&) = delete;
  void add(const Keyframe& key);
  std::vector<uint8_t> finish();
  // After finish: KGOP, or KGLV where the group uses the levels predictor (format 2.6) and is smaller so.
  std::string_view chunk_type() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

std::vector<uint8_t> write_texture(const Image& texture, uint32_t number, TextureCodec codec, int quality);

// Whether a file with textures (or not: `has_texture`) written with `metadata` stores them in TGOP
// chunks: textures, the sequence coding, AVIF, and every keyframe's quality lossy (≤ 100).
bool uses_texture_groups(bool has_texture, const SequenceFileMetadata& metadata);
// The payload of a group of keyframes' textures from keyframe `first` on, at `quality` (the finest
// of their qualities): the images given in order, one at a time.
class TextureGroupWriter {
 public:
  TextureGroupWriter(size_t first, int quality);
  void add(const Image& texture) { sequence_.add(texture); }
  std::vector<uint8_t> finish();

 private:
  size_t first_;
  AvifSequenceWriter sequence_;
};

}  // namespace facemorph::file_layout
