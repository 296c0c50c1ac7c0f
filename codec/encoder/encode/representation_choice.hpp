// Which representation blends a capture's keyframes closer to the frames between them: the fields
// (hl+t) or the positions (xyz). Blending H, λ, a and b of features that lie at different places on
// the keyframes' disks (frames registered without interior landmarks) does not blend the surfaces,
// and a frame between two keyframes then shows both features half-way; positions blend into one
// surface however the disks are matched (spec/method.md §7.14). The encoder measures both blends on
// a few frames between keyframes instead of assuming either.
#pragma once

#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/sequence/spline.hpp"

#include <cstddef>
#include <memory>
#include <vector>

namespace facemorph {

// A frame between keyframes: its time and its registered surface on G in the face frame.
struct BlendTrial {
  double time = 0;
  std::vector<Vec3> surface;  // every node of G
};

struct BlendComparison {
  double fields_error = 0;     // mean over the trials of the symmetric RMS distance, over the frame's diagonal
  double positions_error = 0;  // the same for the blend of positions
  int trials = 0;
  int not_converged = 0;  // field blends the decoder did not settle (measured as they stood; one that diverged counts as infinitely far)
};

// `keys[k]`: keyframe k's registered surface on G (face frame, every node), or empty where no trial's
// spline weights reach it; `key_times` every keyframe's time. Each trial is decoded from the hl+t
// fields blended with the spline's weights at its time (fixed-frame nodes: the union of the given
// keyframes' folds, as build takes the union of every keyframe's) and compared with the positions
// blended the same way.
// Trials run on up to `threads` threads (0: one per core). Throws kInvalidArgument for sizes that
// do not match G or a trial that needs a keyframe left empty.
BlendComparison compare_blends(const std::shared_ptr<const GridGeometry>& geometry, const std::vector<double>& key_times, SplineKind spline,
                               const std::vector<std::vector<Vec3>>& keys, const std::vector<BlendTrial>& trials, int threads);

// The representation's automatic choice (EncodeOptions::representation unset), its first step:
// xyz where the blended fields miss the frames between keyframes by more than this times the
// blended positions (a margin for the measurement's noise), over at most kBlendTrials frames.
// Where the fields stay in the running, the encoder then codes both and keeps the fewer bytes at
// equal error (SequenceEncoder::choose_by_bytes, representation_rate.hpp): alike blends do not
// mean alike bytes (ICT: xyz 6-11% smaller at the same step; spec/method.md §7.14).
inline constexpr double kFieldsBlendMargin = 1.1;
inline constexpr int kBlendTrials = 12;

// The pairs of neighbouring keyframes (k: keyframes[k] and keyframes[k + 1], frame indices) with a
// frame between them, kBlendTrials of them at most, spread evenly over those pairs (the first and the
// last kept): where choose_representation blends.
std::vector<size_t> blend_trial_pairs(const std::vector<int>& keyframes);
// What an unset representation becomes after `blend` was measured: xyz where the fields came out
// farther than kFieldsBlendMargin times the positions (a diverged blend is infinitely far), else hl+t.
Representation representation_for(const BlendComparison& blend);

}  // namespace facemorph
