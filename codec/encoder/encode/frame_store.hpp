// Where the encoder keeps its frames' maps between stages (spec/method.md §7.15).
//
// A mapped frame is ~4 MB in memory (10k vertices: the prepared mesh, the surface as mapped, its
// disk), and every stage after mapping comes back to it: registration, the selection grid, the
// keyframe fit on G (every frame, once N is known) and the keyframes' textures. Kept in memory, a
// 2000-frame capture held 9 GB. The store writes each map to a temporary file as it is made (1.1 MB
// a frame: the prepared mesh is left out) and reads it back when a stage asks, so only the frames
// being worked on are in memory. Mapping again instead would cost the mapping's time (about half
// an encode) once more for each stage; reading a map back is too quick to show in stage times.
#pragma once

#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/spill_file.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace facemorph {

class FrameStore {
 public:
  // kSpill: maps go to an unlinked temporary file (in TMPDIR), memory holds those in use; kMemory:
  // maps stay in memory (what the encoder did before: memory grows with the capture).
  using Mode = SpillMode;
  explicit FrameStore(Mode mode = Mode::kSpill);
  ~FrameStore();
  FrameStore(const FrameStore&) = delete;
  FrameStore& operator=(const FrameStore&) = delete;

  Mode mode() const { return mode_; }
  // Forgets every frame and makes room for `count` (the file, if any, is emptied).
  void reset(size_t count);
  size_t size() const { return items_.size(); }
  // Stores frame i (i < size()); may be called from several threads for different i. Spilled, the
  // frame's prepared mesh is not written: its map's surface is the same surface (a few edges
  // split), and what a later stage needs of the mesh (its counts, its holes) is kept beside it.
  // Throws kIo when the temporary file cannot be written (a full disk: TMPDIR names another).
  void put(size_t i, MappedFrame&& frame);
  // Stores frame i as the bytes (serialize's form) `source` gives whenever the frame is asked for:
  // a map kept in a part file is read from there (staged_encode.hpp), not copied into the store.
  void put_source(size_t i, SpilledItems<MappedFrame>::Source source) { items_.put_source(i, std::move(source)); }
  // Frame i as stored: read back from the file (a copy counted in held() until released) or the
  // one in memory. Thread-safe. Throws kInternal for a frame never stored, kIo on a failed read.
  std::shared_ptr<const MappedFrame> get(size_t i) const { return items_.get(i); }
  // Keeps the frames at indices `kept` (increasing), renumbered 0.. in that order (the dropped
  // frames' bytes stay in the file until reset).
  void keep(const std::vector<size_t>& kept) { items_.keep(kept); }

  // Accounting, for the report and the tests: how many frames' maps (or meshes being mapped) are in
  // memory now and at most since the last reset. A Hold counts one while it lives: the encoder takes
  // one around a frame it reads and maps before put.
  using Counter = ResidentCount;
  using Hold = ResidentHold;
  [[nodiscard]] Hold hold() const { return Hold(counter_); }
  int held() const { return counter_->now.load(); }
  int peak_held() const { return counter_->peak.load(); }
  uint64_t spilled_bytes() const { return items_.spilled_bytes(); }  // the file's size (0 in memory)

  // The byte form of a frame in the file (no prepared mesh): what put writes and get reads. Public
  // for the round-trip test.
  static std::vector<char> serialize(const MappedFrame& frame);
  static MappedFrame deserialize(const char* bytes, size_t size);

 private:
  Mode mode_;
  // Shared with the frames handed out, which may outlive the store.
  std::shared_ptr<Counter> counter_;
  SpilledItems<MappedFrame> items_;
};

}  // namespace facemorph
