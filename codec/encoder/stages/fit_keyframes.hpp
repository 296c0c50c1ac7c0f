// The keyframe fit (--keyframe-fit, spec/method.md §7.5): the keyframes' surfaces replaced by the
// values whose spline best matches every frame of the capture, each keyframe's move bounded by its
// frame's noise, so that a noisy capture's noise is averaged away instead of interpolated.
#pragma once

#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/encoder/encode/keyframe_store.hpp"

#include <functional>
#include <span>
#include <vector>

namespace facemorph {

// What the fit reads of the encode.
struct KeyframeFitInput {
  std::vector<int> keyframes;    // frame indices, increasing
  std::vector<double> times;     // every frame's time (seconds)
  std::vector<RigidPose> poses;  // each keyframe's head pose
  SplineKind spline = SplineKind::kCatmullRom;
  Vec3 pose_centre = Vec3::Zero();  // the face's centroid in the face frame (blend_poses)
  double weight = 1;                // μ: the extra weight of a keyframe's own frame
  double noise_factor = 3;          // κ: a keyframe moves at most κ times its frame's noise (RMS)
  int threads = 0;
  // Frame j's registered surface at disk points (capture frame); called from the threads.
  std::function<std::vector<Vec3>(int, std::span<const Vec2>)> surface;
  std::function<double(int)> noise;  // a keyframe's noise estimate (frame_noise; infinite below 5 frames)
};

// Replaces item k of `local` (keyframe k's registered surface on G in the face frame) by its fit,
// read back twice and stored in its place. Nothing changes with fewer than 2 keyframes, or as many
// as the frames.
void fit_keyframes(const KeyframeFitInput& input, const GridGeometry& geometry, SurfaceStore& local);

}  // namespace facemorph
