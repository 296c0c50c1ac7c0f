// Where the encoder keeps the keyframe selection's samples of every frame (spec/method.md §7.15).
//
// The selection ranks every frame against candidate keyframe sets on the 65² grid: each frame's
// face-frame positions and normals there, 79 kB a frame as floats, the one thing of every frame the
// encoder still held until the keyframes were chosen (160 MB for 2010 frames; a one-hour capture at
// 30 fps would need 8.5 GB). Spilled, each frame's samples go to the encoder's temporary file as
// they are made and come back when the selection asks, through a cache of the most recently used
// (its refinement moves one keyframe at a time and predicts the frames around it: a window that
// slides along the capture). Times, poses and diagonals stay in memory: every stage reads them.
#pragma once

#include "codec/encoder/encode/spill_file.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"

#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

namespace facemorph {

class SelectionStore final : public SelectionFrames {
 public:
  // `outlines`: every frame's time, pose and diagonal (the encoder's, which outlive the store; their
  // vectors are not read). kMemory keeps every frame's samples; kSpill at most `cache_bytes` of them.
  SelectionStore(const std::vector<SelectionFrame>& outlines, SpillMode mode, uint64_t cache_bytes);
  SelectionStore(const SelectionStore&) = delete;
  SelectionStore& operator=(const SelectionStore&) = delete;

  // Frame i's samples (its local and normal vectors; the rest is the outline's), once per frame
  // (a frame already read back would stay cached as it was). Thread-safe for different i. Throws
  // kIo when the file cannot be written.
  void put(size_t i, std::vector<Eigen::Vector3f>&& local, std::vector<Eigen::Vector3f>&& normal);

  size_t size() const override { return outlines_.size(); }
  const SelectionFrame& outline(size_t i) const override { return outlines_.at(i); }
  // Frame i with its samples: from the cache, or read back (kInternal for a frame never put).
  std::shared_ptr<const SelectionFrame> sampled(size_t i) const override;

  int peak_held() const { return count_->peak.load(); }  // frames' samples in memory at once (the cache's and those handed out)
  uint64_t spilled_bytes() const { return file_.size(); }
  uint64_t reads() const;  // samples read back from the file (cache misses)

 private:
  std::shared_ptr<const SelectionFrame> assemble(size_t i, std::vector<Eigen::Vector3f>&& local,
                                                 std::vector<Eigen::Vector3f>&& normal) const;

  const std::vector<SelectionFrame>& outlines_;
  SpillMode mode_;
  uint64_t cache_bytes_ = 0;  // kSpill: what the cache may hold
  uint64_t frame_bytes_ = 0;  // one frame's samples as stored
  SpillFile file_;
  std::shared_ptr<ResidentCount> count_ = std::make_shared<ResidentCount>();
  mutable std::mutex mutex_;
  std::vector<SpillFile::Record> records_;
  std::vector<char> stored_;
  mutable std::vector<std::shared_ptr<const SelectionFrame>> in_memory_;  // kMemory: every frame; kSpill: those cached
  mutable std::list<size_t> recent_;                                      // kSpill: cached frames, most recently used first
  mutable std::unordered_map<size_t, std::list<size_t>::iterator> where_;
  mutable uint64_t reads_ = 0;
};

}  // namespace facemorph
