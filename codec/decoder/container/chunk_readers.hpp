// The readers of a .fmv file's chunks (spec/container.md), one file each (header_chunk, index_chunk,
// residual_chunk, keyframe_group_chunk, texture_chunk, texture_group_chunk): every value checked
// where it enters. What they share with the writers is codec/core/container/file_layout.hpp.
#pragma once

#include "codec/core/container/file_layout.hpp"
#include "codec/decoder/image/image_decode.hpp"

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph::file_layout {

// Reads and checks a header. `minor_version`: the file's; one this decoder knows (kMinorVersion or
// older) defines every byte of its header, and a byte past its last field is corrupt; a later one
// may append up to kMaxAppendedBytes, which are skipped.
FileHeader read_header(std::span<const uint8_t> payload, const std::string& source, const DecoderLimits& limits,
                       const KeyframesHeld& keyframes_held, uint16_t minor_version);
// The most bytes a header chunk may decompress to (§5, §10.2): its fixed fields, the fixed nodes of
// the largest G that `max_grid_n` allows, the strings within kMaxHeaderStringBytes and the appended
// fields of a later minor version. Checked against the chunk's stated size before it is decompressed.
uint64_t max_header_bytes(int max_grid_n);
// The same for the index of the header's keyframes (§6): times, the pose varints at their longest,
// the offsets, and what a later minor version may append.
uint64_t max_index_bytes(const FileHeader& h);
// A payload that held `remaining` bytes after the fields of its version: corrupt in a file of a
// minor version this decoder knows, skipped up to kMaxAppendedBytes in a later one.
void check_appended_bytes(size_t remaining, uint16_t minor_version, const std::string& where);

// Checks the times (bounds, separation) and pose codes (bounds) as it reads; the offsets are the
// caller's to check against the chunks.
std::vector<IndexEntry> read_index(std::span<const uint8_t> payload, const std::string& source, const FileHeader& h,
                                   uint16_t minor_version);

// Reads and checks a payload against the header (first time, fps) and the keyframes' times: every
// check of §7.4, kCorrupt naming the residual; kLimit where their memory passes `max_memory_bytes`.
std::vector<ResidualFrame> read_residuals(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                          const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version);

// What the chunks of frames between keyframes (RSDW, PTCH) share:
// - read_item_count: the items' count (the payload's first uint32, `count_name` naming it), kCorrupt
//   where it is not 1 to `max` or the bytes after it cannot give each item `min_bytes`: refused
//   before anything is allocated. `items`: their plural ("residual frames").
// - read_item_time: an item's time, coded as its change from the previous item's code `q` (64ths of
//   a frame period from the first time; updated), kCorrupt naming the item (`name`) where it does
//   not come after the previous one or not strictly between two keyframes. With the keyframe
//   interval it falls in (residual_interval). item_time: the same for a change read otherwise
//   (format 2.5's range-coded PTCH), kCorrupt naming `source`.
uint32_t read_item_count(format::ByteReader& r, const char* count_name, const char* items, uint32_t max, size_t min_bytes);
struct ItemTime {
  double time = 0;
  int interval = 0;
};
// An item's name in an error ("frame patch 1234"), spelt out only when there is one: a chunk holds
// up to millions of items, and a string per item was a heap allocation each (spec/container.md §10.5).
struct ItemName {
  const char* kind;  // "frame patch"
  uint64_t index;
  std::string str() const { return std::string(kind) + " " + std::to_string(index); }
};
ItemTime read_item_time(format::ByteReader& r, const char* change_name, ItemName name, const Sequence& shape,
                        const std::vector<double>& key_times, int64_t& q);
ItemTime item_time(int64_t change, const std::string& source, ItemName name, const Sequence& shape,
                   const std::vector<double>& key_times, int64_t& q);

// Reads and checks a PTCH payload against the header (first time, fps) and the keyframes' times:
// every check of §7.5 (varints in a file stamped 2.4, §7.5.1's range-coded stream from 2.5 on),
// kCorrupt naming the patch; kLimit where their memory passes `max_memory_bytes`.
std::vector<FramePatch> read_patches(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                     const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version);

// Reads the fields of a group of `count` keyframes from keyframe `first` on, one keyframe at a
// time, in order, so that a caller may stop between two (a decode call's work limit, §10.3) and go
// on later with the same reader: it holds the payload, the stream's place and models, and the last
// keyframe's codes. `h` must outlive it. `minor_version`: the file's (2.5 added a predictor, §7.2).
// `levels_chunk`: the payload is a KGLV chunk's (2.6: the levels predictor may follow id 3).
class KeyframeGroupReader {
 public:
  KeyframeGroupReader(std::vector<uint8_t> payload, std::string where, const FileHeader& h, uint32_t first, uint32_t count,
                      uint16_t minor_version, bool levels_chunk = false);
  ~KeyframeGroupReader();
  KeyframeGroupReader(const KeyframeGroupReader&) = delete;
  KeyframeGroupReader& operator=(const KeyframeGroupReader&) = delete;
  // The keyframe of the group read() decodes next (count: none left).
  uint32_t next() const;
  // Decodes keyframe first + next(), charging `work` (null: unbounded) its values first, so that a
  // stop leaves the reader where it was. The key holds the fields and hole level: its fields pass
  // validate_fields and its hole levels are finite and within kMaxHoleLevel (corrupt, naming the
  // keyframe and the node). `end`: where its part of the stream ended from the payload's start.
  Keyframe read(WorkMeter* work, uint64_t& end);
  // After the group's last keyframe: kCorrupt unless the stream ends exactly there.
  void expect_end() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// The image codec a TEXR payload names, from its first 8 bytes (kUnsupported for an unknown one).
TextureCodec texture_codec_of(std::span<const uint8_t> payload, const std::string& where, uint32_t number);
Image read_texture(std::span<const uint8_t> payload, const std::string& where, uint32_t number, uint32_t size);

// Reads the textures of the group of `count` keyframes starting at `first` one frame at a time, in
// order (KeyframeGroupReader's counterpart: it holds the payload and the AV1 decoder's state), after
// checking the chunk's first keyframe, codec and its image sequence's count and size against the
// container's (corrupt, naming `where`, before any pixel).
class TextureGroupReader {
 public:
  TextureGroupReader(std::vector<uint8_t> payload, const std::string& where, uint32_t first, uint32_t count, uint32_t size);
  // The frame of the group read() decodes next (count: none left).
  uint32_t next() const { return sequence_->next(); }
  // Decodes frame next(): its RGB image where `convert`, else an empty one (every frame is decoded,
  // as later ones are predicted from it).
  Image read(bool convert) { return sequence_->read(convert); }

 private:
  std::vector<uint8_t> payload_;  // the sequence reads it where it lies
  std::unique_ptr<AvifSequenceReader> sequence_;
};
// The bytes of each of the group's keyframes' AV1 samples, in order (fminfo). Throws as TextureGroupReader.
std::vector<uint64_t> texture_group_sample_bytes(std::span<const uint8_t> payload, const std::string& where, uint32_t first, uint32_t count,
                                                 uint32_t size);

}  // namespace facemorph::file_layout
