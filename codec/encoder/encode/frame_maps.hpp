// The map stage's state (stages/map_frames.cpp): every frame's map in its store, what the report
// and the later stages keep of each in memory (its summary, its texture's path), and the reference's
// map pinned in memory, since every stage reads it.
#pragma once

#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/frame_store.hpp"
#include "codec/encoder/encode/sampled_frame.hpp"

#include <filesystem>
#include <memory>
#include <vector>

namespace facemorph {

class FrameMaps {
 public:
  // Forgets every map, summary, texture path and pin, making room for `count` maps in a store of
  // `mode` (the summaries and paths are the caller's to fill: map_frames sizes them, the staged
  // encode's assembling encoder adds them a frame at a time).
  void start(size_t count, FrameStore::Mode mode);
  FrameStore& store() { return *store_; }
  const FrameStore& store() const { return *store_; }
  size_t size() const { return store_->size(); }
  // Frame i's map: the pinned one, or read back from the store (its prepared mesh left empty, see
  // FrameStore::put) and held in memory as long as the pointer is. Thread-safe.
  std::shared_ptr<const MappedFrame> frame(int i) const;
  // Keeps frame i's map in memory from here on (the reference's): read from the store, the map
  // pinned before released first; `map` given, that one.
  std::shared_ptr<const MappedFrame> pin(int i);
  void pin(int i, std::shared_ptr<const MappedFrame> map);
  // Whether frame i has colour to store: a texture image with UVs, or vertex colours (spec/capture.md).
  bool has_texture(int i) const;
  // Keeps the frames at indices `kept` (increasing) of the `before` frames, renumbered 0.. in that
  // order; the pin follows its frame (a dropped frame loses it). Parts not yet made for `before`
  // frames stay as they are.
  void keep(const std::vector<size_t>& kept, size_t before);

  std::vector<FrameSummary> summaries;          // per frame, what the report gives of its map
  std::vector<std::filesystem::path> textures;  // per frame, its texture image (empty: none)

 private:
  std::unique_ptr<FrameStore> store_ = std::make_unique<FrameStore>();
  int pinned_index_ = -1;  // the frame pinned_ holds (-1: none)
  std::shared_ptr<const MappedFrame> pinned_;
};

}  // namespace facemorph
