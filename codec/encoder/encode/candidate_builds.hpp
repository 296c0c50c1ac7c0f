// The keyframes of the choice by bytes at equal error, built once per N (spec/method.md §7.14).
//
// The choice codes the same keyframes several times: hl+t and xyz at N, the winner at a coarser N,
// the best again at twice the field step, and the density-equalised disk's at its own N. Each build
// samples every frame at G's nodes (the keyframe fit reads them all): on ict2k24 2.5 s of the
// representation stage's 12.4 s for one candidate at N = 257. What a build makes before its fields
// (the fitted surfaces, hole levels, textures and poses) depends only on N and the disk, not on the
// representation or the field step, so a build at an N is kept unrounded with its surfaces, and a
// later candidate at that N is made from it: its fields by keyframe_fields from the same surfaces
// and fixed nodes, everything else copied. The arrays are those a new build makes, so the files
// are unchanged (cmp on ict2k24, fast24, sample60, ict24). A build at a new N takes its textures
// from a kept build too (any_kept): they depend on the disk and the keyframes, which one
// CandidateBuilds never changes, not on N; sampling them was a third of Medusa's build time.
#pragma once

#include "codec/encoder/encode/build_stage.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"

#include <functional>
#include <map>
#include <memory>

namespace facemorph {

class CandidateBuilds {
 public:
  // `mode`: where the copies keep their arrays (BuildSettings::spill_keyframes); `threads` make them.
  CandidateBuilds(SpillMode mode, int threads) : mode_(mode), threads_(threads) {}

  // Keeps a copy of `built` (unrounded, just built at its N with `surfaces`, `report` as the build
  // left it) for later candidates at that N, in place of any kept there before.
  void keep(const StoredSequence& built, KeyframeSurfaces surfaces, const EncodeReport& report);
  // Whether a build at `n` is kept.
  bool kept(int n) const { return kept_.count(n) > 0; }
  // A kept build at any N, or null: the textures of a build at another N (the same keyframes on the
  // same disk, as every build kept here is: the choice keeps one CandidateBuilds a disk), which do
  // not depend on N (SequenceEncoder::build's `textures_from`).
  const StoredSequence* any_kept() const { return kept_.empty() ? nullptr : kept_.begin()->second.sequence.get(); }
  // The keyframes at `n` in `representation`, unrounded: made from the build kept at `n` (the
  // report's build figures set as that build set them, seconds_keyframes what the copy took), else
  // built by `build` (which fills the surfaces it is given and `report`) and kept.
  std::unique_ptr<StoredSequence> get(Representation representation, int n,
                                      const std::function<std::unique_ptr<StoredSequence>(KeyframeSurfaces*)>& build,
                                      EncodeReport& report);

 private:
  struct Kept {
    std::unique_ptr<StoredSequence> sequence;
    KeyframeSurfaces surfaces;
    // What the build put in the report (build_keyframes).
    int texture_size = 0;
    std::vector<int32_t> folds;
    int peak_held = 0;
    uint64_t spilled_bytes = 0;
  };
  // `from`'s keyframes with fields in `representation` (copied where it is from's, else made from
  // `surfaces`).
  std::unique_ptr<StoredSequence> copy(const StoredSequence& from, const KeyframeSurfaces& surfaces, Representation representation) const;

  SpillMode mode_;
  int threads_;
  std::map<int, Kept> kept_;
};

}  // namespace facemorph
