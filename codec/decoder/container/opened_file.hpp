// A .fmv file opened for reading piece by piece (spec/container.md §10.2): the chunks walked, the
// header and index read and checked; keyframes and textures decoded when asked for. What
// decode_sequence_file (every keyframe at once) and the on-demand source of an opened file
// (file_source.cpp) share. Internal to the decoder library.
#pragma once

#include "codec/core/container/file_layout.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "format/container.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>

namespace facemorph {

class OpenedFile {
 public:
  // How many keyframes' fields, surfaces and textures the caller holds at once, given the file's
  // keyframe count and spline: for the memory estimate of §10.1, checked from the header.
  using KeyframesHeld = std::function<uint64_t(uint32_t keyframes, SplineKind spline)>;
  // Walks the chunks and reads the header and index of `bytes` (which must outlive this object),
  // every check of §10.2 steps 1-5 but the keyframes' own (every index entry points at a chunk of
  // its kind). Throws as decode_sequence_file.
  OpenedFile(std::span<const uint8_t> bytes, std::string source, const DecoderLimits& limits, const KeyframesHeld& keyframes_held);
  ~OpenedFile();
  OpenedFile(const OpenedFile&) = delete;
  OpenedFile& operator=(const OpenedFile&) = delete;

  const std::string& source() const;
  // The sequence without keyframes: grid, representation, spline, rate, times, units, pose centre.
  const Sequence& shape() const;
  // The residual frames and frame patches (§7.4, §7.5), moved out of shape() to the caller, which
  // then holds the only copy: the budget counts them once (§10.1), so they are held once (a copy
  // of 3.9 million patches, which a 58 KB range-coded PTCH holds, is 250 MB). describe() still
  // counts them.
  struct Frames {
    std::vector<ResidualFrame> residuals;
    std::vector<FramePatch> patches;
  };
  Frames take_frames();
  size_t keyframe_count() const;
  double keyframe_time(size_t k) const;
  // Keyframe k's pose, from the index (checked there: a proper rotation, a translation in bounds).
  const RigidPose& keyframe_pose(size_t k) const;
  // The header's fixed nodes (GridFields::fixed_nodes of every keyframe).
  size_t fixed_node_count() const;
  bool has_texture() const;
  bool has_holes() const;
  int texture_size() const;
  // Float64 values of one keyframe's arrays (fields and hole level), as the header fixes them.
  uint64_t values_per_keyframe() const;
  // The largest payload, once decompressed, of any keyframe or texture chunk: what decoding one
  // holds besides its product.
  // What the header holds for as long as the file is open: its strings and fixed nodes (at most
  // 4 MiB and 4 bytes a node of G), counted against the budget (spec/container.md §10.1).
  uint64_t header_bytes() const;
  uint64_t largest_payload() const;
  // Keyframes are decoded in runs: a run's first keyframe stands alone, each later one needs the one
  // before it (an intra period; a single keyframe where every keyframe is coded alone).
  size_t run_length() const;
  size_t run_of(size_t k) const { return k / run_length(); }

  // A run decoded one keyframe at a time, in order, so that a caller may stop between two (a decode
  // call's work limit, spec/container.md §10.3) and go on later with the same reader, which holds
  // what the run's decoding needs (the payload, a stream's place, an image decoder's frames).
  template <typename T>
  class RunReader {
   public:
    virtual ~RunReader() = default;
    // The keyframe read() decodes next; end(): one past the run's last.
    virtual size_t next() const = 0;
    virtual size_t end() const = 0;
    // Decodes keyframe next(), charging `work` (null: unbounded) first, so that a stop leaves the
    // reader where it was; after any other failure the reader is not to be used again. Returns the
    // item, or nothing where it is not `wanted` and need not be made (a texture frame is decoded,
    // as later ones are predicted from it, but not converted). `bytes`: what it takes in the file
    // (a keyframe's fields; 0 for textures).
    virtual std::optional<T> read(WorkMeter* work, bool wanted, uint64_t& bytes) = 0;
    // After the run's last keyframe: the checks of its end (a group's stream ends exactly there).
    virtual void finish() const = 0;
  };
  // The run of keyframes' fields from first_of_run, each checked as §7 says; an item holds
  // everything but the texture (time and pose from the index). Charged its values.
  std::unique_ptr<RunReader<Keyframe>> read_fields(size_t first_of_run) const;
  // The run of textures from first_of_run (a still, or a group's sequence), each checked as §8 /
  // §8.1 say. Charged each frame's pixels.
  std::unique_ptr<RunReader<Image>> read_textures(size_t first_of_run) const;

  // Decodes keyframes first_of_run .. last (last within the run of first_of_run; read_fields),
  // calling `take(k, key, field_bytes)` for each in order; the stream's end is checked where last
  // is the run's last. field_bytes: what keyframe k's fields take in the file.
  void decode_run(size_t first_of_run, size_t last, const std::function<void(size_t, Keyframe&&, uint64_t)>& take,
                  WorkMeter* work = nullptr) const;
  // The keyframe whose stored texture keyframe k shows: k itself, or in a file of shared textures
  // (format 2.2) the first keyframe naming the same TEXR. decode_texture(k) decodes the owner's.
  size_t texture_owner(size_t k) const;
  // Textures are decoded in runs too: one keyframe's still (TEXR), or a group's image sequence
  // (TGOP, format 2.1), in which keyframe k is decoded from the group's first up to it.
  size_t texture_run_length() const;
  // What decoding a texture run holds besides its payload and product: the AV1 decoder's frames
  // for a group's sequence (§10.1), 0 for stills.
  uint64_t texture_decoder_bytes() const;
  // Decodes the textures of keyframes first_of_run .. last (within one texture run; read_textures),
  // handing take(k, image) those for which wanted(k), in order.
  void decode_textures(size_t first_of_run, size_t last, const std::function<bool(size_t)>& wanted,
                       const std::function<void(size_t, Image&&)>& take, WorkMeter* work = nullptr) const;
  // Every keyframe's fields, run by run, in order (decode_run over the whole file).
  void decode_every_keyframe(const std::function<void(size_t, Keyframe&&, uint64_t)>& take) const;
  // Every stored texture once, run by run (each group's sequence decoded once): take(k, image) for
  // each keyframe k that owns its texture (texture_owner(k) == k); keyframes sharing it get none.
  void decode_every_texture(const std::function<void(size_t, Image&&)>& take) const;
  // Keyframe k's texture, its size checked against the header's (has_texture()); in a file with
  // texture groups, its group's sequence decoded up to k.
  Image decode_texture(size_t k) const;
  // The image codec keyframe k's texture is stored in, without decoding it.
  TextureCodec texture_codec(size_t k) const;
  // Every chunk's checksum (§3), without decoding anything.
  void verify_checksums() const;
  // The file's description (versions, grid, metadata, chunk totals, each texture's bytes); the
  // keyframes' field bytes are the caller's, from decode_run.
  // split_texture_groups: a texture group's bytes divided among its keyframes by their AV1 samples
  // (which parses each group's AVIF); false gives each group's whole chunk to its first keyframe and
  // reads no texture payload (what opening a file costs: the header and index).
  SequenceFileInfo describe(bool split_texture_groups = true) const;
  // Decodes every keyframe's fields and texture once, one at a time, and verifies every checksum:
  // throws what the first fault throws. `info`: describe() with every keyframe's field bytes;
  // `each`: given every keyframe (its texture left empty) as it is decoded, in order.
  void check_every_keyframe(SequenceFileInfo* info, const std::function<void(size_t, const Keyframe&)>& each = {}) const;
  // The header and index as read and checked, and the chunks: for a tool that copies chunks from
  // file to file without decoding them (the segment joiner).
  const file_layout::FileHeader& header() const;
  const std::vector<file_layout::IndexEntry>& index() const;
  const format::ContainerReader& container() const;

 private:
  const format::ChunkView& texture_chunk(size_t k) const;
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace facemorph
