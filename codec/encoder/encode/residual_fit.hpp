// Residual frames fitted to what the decoder shows (spec/method.md §7.18, format 2.3).
//
// The keyframe selection predicts each frame from the keyframes' own captured frames, on its 65²
// samples, and fits a residual there to decide where residuals can take the place of keyframes. The
// decoder blends something else: the keyframes the keyframe fit (§7.5) moved and the field rounding
// (§5.3) rounded. A correction fitted against the first need not lower the error of the second (on
// Medusa half the held-out frames decoded worse). So once the keyframes are stored, each frame
// between them is decoded, its correction fitted against that decoded surface and the frame's own
// registered surface on G, and the correction kept only where decoding with it lowers the frame's
// error: the decoder's error at every captured frame is then never above the spline's alone.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/sequence/residual_weights.hpp"

#include <functional>
#include <span>
#include <vector>

namespace facemorph {

class StoredSequence;

// What the fit reads of the capture's frames, registered and sampled (registered_frames,
// sequence_encoder.hpp): frame j's time and bbox diagonal, and its registered surface at disk
// points of G (capture frame). `surface` is called from several threads at once (the fit's).
struct RegisteredFrames {
  std::vector<double> times;
  std::vector<double> diagonals;
  std::function<std::vector<Vec3>(int frame, std::span<const Vec2> nodes)> surface;
};

// A fitted correction is kept where the frame decodes with it at least this fraction closer to its
// captured surface. Lower than the selection's kResidualMinGain: that one judges a prediction, this
// one what the decoder shows, and on a noisy capture the frame's own noise is most of its error
// (fmsynth fast speech, 0.3% noise: 14 of 43 frames gained a tenth, all 43 at least 2%).
inline constexpr double kDecodedResidualMinGain = 0.02;

// What fit_decoded_residuals did, for the encoder's report (errors: RMS of the offsets along the
// captured frame's normals on G, area-weighted, over its bbox diagonal, as decoded).
struct ResidualFitReport {
  int frames_fitted = 0;                     // frames between keyframes whose decoded error was above kResidualFloor
  int frames_improved = 0;                   // frames whose decoded error the correction lowered by kDecodedResidualMinGain or more
  int frames_worse = 0;                      // frames a correction fitted for, that decoded no better with it (left at 0)
  int residuals = 0;                         // residual frames stored (improved frames, and 0's beside them in their intervals)
  double mean_before = 0, worst_before = 0;  // over the frames between keyframes, the spline's alone
  double mean_after = 0, worst_after = 0;    // with the residuals kept
  double seconds = 0;                        // the fit's time, decoding included
  // Keyframes the selection took fewer for the residuals (KeyframeSelection::spline_keyframes less
  // the keyframes): 0 where they did not pay (residuals_pay), and the encoder fitted none.
  int keyframes_saved = 0;
};

// The residual frames for `stored` (its keyframes, fields as the file will hold them, no residuals
// yet), capture frames `keyframes` of `frames`: every frame strictly between the first and last
// keyframe decoded from `stored`, its correction fitted (fit_blend_correction, `step`) to the
// decoded surface's offsets from the frame's registered surface along its normals, linearised in
// the keyframes' decoded surfaces; each frame then decoded with its correction (at its time on the
// file's lattice, residuals_on_file_times) and the correction kept where the decoded error falls
// by kDecodedResidualMinGain or more. An interval with a correction kept has a residual at every frame
// (the others 0: the decoder interpolates between an interval's residuals); one without has none.
// Leaves `stored`'s residuals empty; `report` (optional) is filled. The decodes run on up to
// `threads` threads (0: one per core), one decoder each; the result is the same for any count.
std::vector<ResidualFrame> fit_decoded_residuals(const RegisteredFrames& frames, StoredSequence& stored, const std::vector<int>& keyframes,
                                                 double step, ResidualFitReport* report = nullptr, int threads = 1);

}  // namespace facemorph
