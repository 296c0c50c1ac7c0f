// The sample stage's state (spec/method.md §7.15): every frame's registered surface on the coarse
// selection grid in the face frame, with its time, rigid head pose and diagonal. sample_frames
// (stages/sample_frames.cpp) fills it, the assembling encoder from its parts' frames; the keyframe
// selection, the grid's choice and the keyframe fit read it. Its samples (79 kB a frame) are
// released once the keyframes are chosen; the outlines and the keyframes' noise stay.
#pragma once

#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/encoder/encode/selection_store.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <vector>

namespace facemorph {

class SelectionSamples {
 public:
  // N of the selection grid: 65² is ~3.3k nodes, enough to rank frames by error at a fraction of
  // the cost of G itself.
  static constexpr int kGrid = 65;

  SelectionSamples() = default;
  // The store reads the outlines where they lie: neither is copied or moved.
  SelectionSamples(const SelectionSamples&) = delete;
  SelectionSamples& operator=(const SelectionSamples&) = delete;

  // Ready for `count` frames, none sampled yet: the grid's node weights (its interior nodes' areas)
  // set, the outlines cleared, the samples of an earlier sampling dropped and a new store made
  // (kSpill: in the encoder's temporary file). Returns the grid.
  GridGeometry start(size_t count, SpillMode mode);
  // Frame i's outline, which its sampler fills (time, pose, diagonal; the reference keeps its local
  // vectors there too: centre reads them after the samples are released).
  SelectionFrame& outline(size_t i) { return outlines_[i]; }
  // Frame i's samples, once per frame; thread-safe for different i.
  void put(size_t i, std::vector<Eigen::Vector3f>&& local, std::vector<Eigen::Vector3f>&& normal);
  // Frames [0, kept) stay, the others' outlines go (the assembling encoder: its parts' dropped frames).
  void keep_first(size_t kept) { outlines_.resize(kept); }

  // Every frame's time, pose and diagonal (their vectors empty, but for the reference's local ones).
  const std::vector<SelectionFrame>& frames() const { return outlines_; }
  const std::vector<double>& weights() const { return weights_; }  // the grid's interior nodes' areas
  bool sampled() const { return samples_ != nullptr; }
  // Every frame's samples; frame i with its samples, read back from the store. kInternal once released.
  const SelectionFrames& samples() const;
  std::shared_ptr<const SelectionFrame> frame(int i) const;
  // Frame k's noise estimate (its surface against the cubic through its four nearest frames in time,
  // RMS by area, in the capture's units; infinite below 5 frames): from the samples, or, once they
  // are released, as kept for the keyframes they were released for (kInternal for another frame).
  double noise_at(int k) const;
  // Frame `reference`'s centroid in the face frame: the area-weighted mean of its local vectors.
  Vec3 centre(int reference) const;
  // Frees the samples, keeping each of `keyframes`' noise estimate (noise_at). Returns the store's
  // figures as it was freed: its peak of frames' samples in memory at once and its bytes in the
  // temporary file (none where there was no store).
  struct StoreFigures {
    int peak_held = 0;
    uint64_t spilled_bytes = 0;
  };
  std::optional<StoreFigures> release(const std::vector<int>& keyframes);

 private:
  // What the store's cache of spilled samples may hold: ~830 frames of 79 kB, more than the frames
  // the selection's refinement predicts around one keyframe (six gaps between keyframes) at 10% keyframes.
  static constexpr uint64_t kCacheBytes = uint64_t{64} << 20;

  std::vector<SelectionFrame> outlines_;  // before samples_: the store reads them
  std::vector<double> weights_;
  std::unique_ptr<SelectionStore> samples_;  // start until release
  bool released_ = false;
  std::map<int, double> released_noise_;  // after release: frame index -> noise_at at that frame
};

}  // namespace facemorph
