// The stages' settings from the encode options: the one place that says what each stage after
// sampling reads of them.
#include "codec/encoder/encode/stage_settings.hpp"

#include <algorithm>

namespace facemorph {

namespace {

// --field-error auto, the fields' rounding target: two fifths of the error the keyframes hold
// without rounding, where rounding error and the other ways to buy error down (more keyframes, a
// finer grid) cost about the same bytes for it (spec/method.md §5.3). That error is the spline's mean
// predicted error between keyframes; where the selection predicts none (one frame, every frame a
// keyframe) the error bound it is held to (held_error), so such a frame is rounded as a sequence's
// whose keyframes left exactly that, not finer than any frame of a video at the same options. The
// rounding's node displacement is mostly along the surface and reaches the point-to-surface error
// at about half its size, so it may be larger than a quadrature rule on displacements would allow.
double auto_target_error(const KeyframeSelection& chosen, const SelectionOptions& selection) {
  constexpr double kShare = 0.4, kLowest = 5e-5, kHighest = 2e-3;
  return std::clamp(kShare * held_error(chosen, selection), kLowest, kHighest);
}

}  // namespace

StageSettings stage_settings(const EncodeOptions& options) {
  StageSettings s;
  s.plan = {.selection = {.fraction = options.keyframe_fraction,
                          .error_bound = options.keyframe_error_bound,
                          .sparse_interval = options.sparse_frame_interval,
                          .p99_bound = options.keyframe_p99_bound,
                          .max_error = options.max_error,
                          .spline = options.spline,
                          .residuals = options.residual_frames},
            .reference_frame = options.reference_frame,
            .grid = options.grid,
            .density_equalising = options.density_equalising.strength != 0,
            .representation = options.representation,
            .threads = options.threads};
  s.build = {.spline = options.spline,
             .keep_holes_filled = options.keep_holes_filled,
             .texture = options.texture,
             .texture_size = options.texture_size,
             .keyframe_fit = options.keyframe_fit,
             .keyframe_fit_weight = options.keyframe_fit_weight,
             .keyframe_fit_noise = options.keyframe_fit_noise,
             .spill_keyframes = options.spill_keyframes,
             .threads = options.threads,
             .progress = options.progress};
  s.precision = options.field_precision;
  s.precision.spill = options.spill_keyframes;
  s.precision.threads = options.threads;
  s.predicted_fields = options.predicted_fields;
  s.auto_field_error = options.auto_field_error;
  s.residual_frames = options.residual_frames;
  s.patch_bound = options.patch_bound;
  s.texture = {.quality = options.texture_quality,
               .codec = options.texture_codec,
               .coding = options.texture_coding,
               .share = options.share_textures,
               .threads = options.threads};
  s.threads = options.threads;
  return s;
}

PlanSettings plan_settings(const EncodeOptions& options) { return stage_settings(options).plan; }
BuildSettings build_settings(const EncodeOptions& options) { return stage_settings(options).build; }
TextureSettings texture_settings(const EncodeOptions& options) { return stage_settings(options).texture; }

FieldPrecisionOptions field_precision_options(const StageSettings& settings, const KeyframeSelection& chosen) {
  FieldPrecisionOptions precision = settings.precision;
  if (settings.auto_field_error) precision.target_error = auto_target_error(chosen, settings.plan.selection);
  return precision;
}

FieldPrecisionOptions field_precision_options(const EncodeOptions& options, const KeyframeSelection& chosen) {
  return field_precision_options(stage_settings(options), chosen);
}

}  // namespace facemorph
