// Every stage's settings after sampling, derived once from the encode options by the driver
// (SequenceEncoder::encode_sampled, the segmented encode's stages): the plan's, the build's, the
// field precision's, the residual and patch fits', the texture stage's. The stages take these, not
// EncodeOptions, so that what each reads of the options is written in one place.
#pragma once

#include "codec/encoder/encode/build_stage.hpp"
#include "codec/encoder/encode/encode_options.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/plan_keyframes.hpp"
#include "codec/encoder/encode/texture_stage.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"

namespace facemorph {

struct StageSettings {
  PlanSettings plan;    // select, N, representation
  BuildSettings build;  // the keyframes on G
  // The field precision's: options.field_precision with the encode's spill and threads; its target
  // set from the plan where auto_field_error (field_precision_options).
  FieldPrecisionOptions precision;
  bool predicted_fields = true;  // false: no search, the fields left at 16-bit precision
  bool auto_field_error = true;
  bool residual_frames = true;  // residual frames fitted where the selection took fewer keyframes for them
  double patch_bound = 0.01;    // frame patches above this decoded 99th-percentile error; 0: none
  TextureSettings texture;
  int threads = 0;
};

// The settings of every stage after sampling, from `options` as they are now (the reference frame
// after frames were dropped).
StageSettings stage_settings(const EncodeOptions& options);
// One stage's, for a caller that runs that stage alone (the tests, the bench): stage_settings's part.
// (plan_settings: plan_keyframes.hpp.)
BuildSettings build_settings(const EncodeOptions& options);
TextureSettings texture_settings(const EncodeOptions& options);
// The field precision's options for the keyframes `chosen`: with auto_field_error, two fifths of
// their mean predicted error as the target, or where they predict none (one frame, every frame a
// keyframe) of the error bound the selection is held to (held_error), within [0.005%, 0.2%].
FieldPrecisionOptions field_precision_options(const StageSettings& settings, const KeyframeSelection& chosen);
FieldPrecisionOptions field_precision_options(const EncodeOptions& options, const KeyframeSelection& chosen);

}  // namespace facemorph
