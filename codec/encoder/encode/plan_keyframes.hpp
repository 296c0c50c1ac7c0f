// The plan stage (select, N, representation) as the driver runs it: its own settings, derived once
// from the encode options (plan_settings), and the state units it reads (PlanFrames), so that it
// takes neither the encoder nor its options.
#pragma once

#include "codec/core/sequence/sequence.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/encode_options.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/frame_sampler.hpp"
#include "codec/encoder/encode/representation_choice.hpp"
#include "codec/encoder/encode/selection_samples.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"

#include <optional>
#include <vector>

namespace facemorph {

// Exactly what the plan stage reads of the encode options.
struct PlanSettings {
  SelectionOptions selection;  // the keyframe selection's (its pose_centre set by select_keyframes from the samples)
  int reference_frame = 0;
  int grid = 0;                                  // N; 0: automatic
  bool density_equalising = false;               // a density-equalising reparametrisation was asked for (strength > 0)
  std::optional<Representation> representation;  // unset: choose_representation decides
  int threads = 0;
};
// The plan stage's settings from the encode's options (the reference as it is now: after frames dropped).
PlanSettings plan_settings(const EncodeOptions& options);

// What the plan stage reads of the encode's state after sample_frames.
struct PlanFrames {
  const std::vector<CaptureFrame>& frames;  // the frames kept: their times
  const SelectionSamples& selection;        // sample_frames's
  const FrameMaps& maps;                    // map_frames's: the reference's map
  FrameSampler sampler;                     // the frames' registered surfaces
};

// 4. The keyframes, by the spline's predicted error on the selection grid (settings.selection).
// kInternal once the selection's samples are released.
KeyframeSelection select_keyframes(const PlanSettings& settings, const SelectionSamples& selection);
// 5. N (settings.grid, or automatic: spec/method.md §7.6), the floor's target from the capture's
// noise and, given the keyframes `chosen`, the error the spline makes between them; what the
// automatic choice measured goes to `report` (grid_floors, grid_target, grid_term, ...), whose
// registration figures (frames_without_interior_landmarks, radial_equalising) it reads.
int choose_grid(const PlanSettings& settings, const PlanFrames& frames, EncodeReport& report, const KeyframeSelection* chosen = nullptr);
// The reference's decoded floor on G of size `n` as hl+t (what choose_grid measures from where the
// RMS terms are done): for a candidate at a coarser N than that, which the grid stage read through
// its resampled floor alone (SequenceEncoder::choose_by_bytes). Infinite where the fields do not
// reconstruct (such a candidate is not stored as positions: it is not a candidate).
EncodeReport::DecodedFloor decoded_fields_floor(const PlanSettings& settings, const PlanFrames& frames, int n);
// Each of `keyframes`' (frame indices) own resampled floor on G of size `n`: its sampled surface
// against its captured frame, the 99th percentile / diagonal, as choose_grid measures the reference's.
// The rounding's worst-region bound holds a keyframe whose floor is larger to what it leaves of the
// target (round_fields.cpp; spec/method.md §5.3). One sampling and one surface distance a keyframe,
// the keyframes on up to `threads` threads (0: one per hardware thread).
std::vector<double> keyframe_floor_p99s(const PlanFrames& frames, const std::vector<int>& keyframes, int n, int threads);
// 5½ What the keyframes store where settings.representation leaves it open: where most frames
// were registered without interior landmarks, the hl+t fields and the positions of `chosen`'s
// keyframes blended at the frames midway between up to kBlendTrials pairs of them, on G of `grid`
// (compare_blends: the fine features are what blend apart, and a coarser grid does not show
// them); xyz where the fields come out farther by more than kFieldsBlendMargin, or on a radially
// spread disk. For the caller to adopt (SequenceEncoder::adopt_representation); sets
// report.seconds_representation.
struct RepresentationDecision {
  Representation representation = Representation::kHLT;
  BlendComparison blend;
};
RepresentationDecision choose_representation(const PlanSettings& settings, const PlanFrames& frames, const KeyframeSelection& chosen,
                                             int grid, EncodeReport& report);

}  // namespace facemorph
