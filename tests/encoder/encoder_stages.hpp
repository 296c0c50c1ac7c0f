// What the encoder's stage tests share: a small synthetic capture, and an encoder run through its
// first stages.
#pragma once

#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"

#include "tests/test_util.hpp"

namespace facemorph::testing {

// Map, register and sample every frame, in turn: the encoder left where the keyframes are chosen
// from (select_keyframes, choose_grid, choose_representation, build_keyframes), as
// encode_capture_stored leaves it before its driver's plan.
inline void run_to_selection(SequenceEncoder& encoder) {
  map_frames(encoder);
  register_frames(encoder);
  sample_frames(encoder);
}

// 12 frames of fmsynth's face, 3000 vertices remeshed every frame, a 128² texture, turning by
// `head_motion` degrees, with scanner noise of `noise` metres along the normal.
inline Capture small_remeshed_capture(const TempDir& dir, double head_motion, double noise = 0) {
  SynthOptions options;
  options.frames = 12;
  options.vertices = 3000;
  options.remesh = true;
  options.noise = noise;
  options.texture_size = 128;
  options.head_motion_degrees = head_motion;
  write_synthetic_capture(dir.path(), options);
  return read_capture(dir.path());
}

// Fast speech (fmsynth's talking face at speech rate 3, 24 fps) at 2000 vertices, `frames` frames:
// between few keyframes, frames whose lips the blend misses (the residual-frame and frame-patch
// tests). The caller sets the texture and remeshing.
inline SynthOptions fast_speech_options(int frames) {
  SynthOptions options;
  options.frames = frames;
  options.fps = 24;
  options.expression = Expression::kTalk;
  options.speech_rate = 3;
  options.vertices = 2000;
  return options;
}

}  // namespace facemorph::testing
