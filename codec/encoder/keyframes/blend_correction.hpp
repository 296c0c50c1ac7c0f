// The correction of a blend of keyframes that best cancels a frame's offsets from it: what the
// keyframe selection fits on its 65² samples (keyframe_selection.cpp) and the residual fit on the
// decoded surface (encode/residual_fit.cpp), both as a residual frame stores it
// (spec/method.md §7.18, format 2.3).
#pragma once

#include <span>
#include <vector>

namespace facemorph {

// The correction δ of a residual window's keys (n = columns.size() ≥ 2) minimising
//   Σ_v w_v (o_v + Σ_m δ_m a_m[v])²  under Σ_m δ_m = 0
// (o: `offsets`, a: `columns`, w: `weights`, all one per node): the last key eliminated, a ridge of
// 10⁻⁹ of the trace (keyframes alike along the offsets' directions leave the system near singular),
// each δ clamped to ±1 (past a whole keyframe's weight a blend extrapolates) and rounded to
// multiples of `step`, the last minus the sum of the others so that the sum is exactly 0. Returns
// Σ_v w_v (o_v + Σ δ_m a_m[v])² with the rounded δ; +∞ (δ empty) for fewer than 2 keys.
// kInvalidArgument where a column or the weights are not one per offset.
double fit_blend_correction(std::span<const double> offsets, const std::vector<std::vector<double>>& columns,
                            std::span<const double> weights, double step, std::vector<double>& delta);

}  // namespace facemorph
