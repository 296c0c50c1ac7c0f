// Frame patches (spec/method.md §7.19, format 2.4): a captured frame between keyframes may carry a
// small displacement of the decoded surface, in the face frame, where the spline (and the residual
// frames' re-blend) cannot reach the captured shape: fast lips, eyelids. A patch is a sparse C × C
// lattice of displacements over the square [−1, 1]² holding the unit disk, interpolated bilinearly
// to G's nodes. Between the nodes of a keyframe interval (its keyframes, with a displacement of 0,
// and its patches) the displacement is linear in t, so any t stays continuous, a keyframe shows
// itself, and outside the keyframes' span (extrapolation) nothing changes.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <cstdint>
#include <vector>

namespace facemorph {

struct FramePatch {
  double time = 0;  // strictly inside a keyframe interval (t_i, t_{i+1}), seconds
  int lattice = 0;  // C: lattice nodes per side (kMinPatchLattice … kMaxPatchLattice)
  // The lattice nodes that move, strictly increasing indices b · C + a of node (a, b) at
  // (−1 + 2a/(C − 1), −1 + 2b/(C − 1)); every other node's displacement is 0.
  std::vector<int32_t> nodes;
  std::vector<Vec3> displacements;  // one per entry of `nodes`: face frame, the sequence's units
};

inline constexpr int kMinPatchLattice = 2;
inline constexpr int kMaxPatchLattice = 129;  // a decoder evaluates two patches at a time: 2 · C² · 24 B ≤ 0.8 MB

// Checks what frame_patch_displacements relies on, against the keyframes' times (strictly
// increasing): each patch's time finite and strictly inside a keyframe interval, times strictly
// increasing, C within [kMinPatchLattice, kMaxPatchLattice], node indices strictly increasing below
// C², one finite displacement per node. Throws kInvalidArgument naming the patch and the defect.
void validate_patches(const std::vector<double>& key_times, const std::vector<FramePatch>& patches);

// The displacement one patch gives the disk point w (|w| ≤ 1 for G's nodes): bilinear in the
// lattice cell holding w (w outside [−1, 1]² takes its nearest cell's extension).
Vec3 patch_displacement(const FramePatch& patch, const Vec2& w);

// The displacement of each of `disk_points` (G's nodes) at time t, face frame: the patches either
// side of t within its keyframe interval (or the interval's keyframes, with 0) interpolated linearly
// in t. Empty where no patch applies (outside the keyframes' span, at a keyframe, an interval without
// patches): the frame is the spline's. `patches` must pass validate_patches for `key_times`.
std::vector<Vec3> frame_patch_displacements(const std::vector<double>& key_times, const std::vector<FramePatch>& patches, double t,
                                            const std::vector<Vec2>& disk_points);

}  // namespace facemorph
