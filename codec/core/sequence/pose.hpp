// The rigid head pose (spec/method.md §7): a rotation and a translation per keyframe, fitted by
// weighted least squares (Kabsch, no scale) and blended between keyframes with the same spline
// weights as every other stored quantity. Rotations are blended in the log map, translations as
// the path of a point.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/sequence/spline.hpp"

#include <Eigen/Core>

#include <vector>

namespace facemorph {

// x ↦ rotation · x + translation. Default: the identity.
struct RigidPose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // proper: orthonormal, det +1
  Vec3 translation = Vec3::Zero();                         // in the units of the points it moves

  Vec3 apply(const Vec3& point) const { return rotation * point + translation; }
  // The pose undoing this one: inverse().apply(apply(x)) = x to rounding.
  RigidPose inverse() const;
  // This after `first`: (a * b).apply(x) = a.apply(b.apply(x)).
  RigidPose operator*(const RigidPose& first) const;
  // Finite, with a rotation orthonormal to 1e-6 and of determinant +1 (no reflection): what a
  // decoder accepts from a file.
  bool is_proper() const;
};

// The proper rigid motion that best maps `from` onto `to`: the one minimising
// Σ_i w_i |R from_i + t - to_i|², by Kabsch/Umeyama without scale. `weights` is one non-negative
// weight per point, or empty for equal weights. The result is always a proper rotation (det +1).
// For mirrored input, the best proper rotation replaces the reflection. For degenerate input (all
// weighted points on a line or at one point), one of the equally good rotations is returned.
// Throws kInvalidArgument: `from` and `to` (or `weights`) of different sizes, fewer than 3 points,
// a non-finite coordinate or weight, a negative weight, or a total weight of zero.
RigidPose fit_rigid_pose(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const std::vector<double>& weights = {});

// The rotation vector (axis · angle, radians, angle in [0, π]) of the rotation matrix R, accurate
// to rounding for every angle. Near 0 there is no division by a vanishing sine. Near π the axis
// comes from the symmetric part of R, with its sign from the antisymmetric part. At exactly π
// either sign is a valid answer. Throws kInvalidArgument when R is not finite or not a proper
// rotation to 1e-6 (|RᵀR - I| or det R - 1).
Vec3 rotation_log(const Eigen::Matrix3d& rotation);

// The rotation about axis w / |w| by the angle |w| (radians; any size): Rodrigues' formula, with a
// series where |w| is small. exp(log R) = R and log(exp w) = w for |w| < π, to rounding. Throws
// kInvalidArgument for a non-finite w.
Eigen::Matrix3d rotation_exp(const Vec3& rotation_vector);

// The rotation vectors of keys[k].rotation relative to keys[0]: ξ_k = log(R_0ᵀ R_k), unwrapped along
// k. Each ξ_k is the representative, (θ + 2πn) · axis over whole n, nearest to ξ_{k-1}, so the
// sequence is continuous even where the head turns past π from keys[0]. Assumes consecutive keys
// less than π apart: a head turns far less between keyframes. Throws kInvalidArgument for an empty
// list or a rotation rotation_log rejects.
std::vector<Vec3> unwrap_rotations(const std::vector<RigidPose>& keys);

// The pose at the time whose spline weights are `w` (KeyframeSpline::weights, keys indexing `keys`):
//   rotation  R_0 exp(Σ c_k ξ_k), with ξ_k from unwrap_rotations (the chart centred at keys[0]);
//   position  of `centre` (face coordinates, the units of the translations) is Σ c_k keys[k].apply(centre),
//             and the translation follows from it and the rotation.
// Any weights that reproduce linear data reproduce exactly a rotation at constant angular speed about
// a fixed axis through `centre`, combined with a translation linear in t. Centring the chart at keys[0]
// rather than the identity makes that hold whatever the starting orientation. Blending the path of
// `centre` rather than of the origin keeps a head turning about itself exact. Otherwise, a head far from
// the origin (the camera) would swing the translation on a wide arc. Pass a point near the head, e.g.
// the centroid of the face frame's surface. The blend is a spline of rotation vectors. It is accurate
// while the keys stay well within π of keys[0] (a head turns far less) and remains continuous beyond.
// At a keyframe's own time (a single weight 1) the key's pose is returned to rounding. Throws
// kInvalidArgument: no keys, keys and weights of different sizes, a key index out of range, a non-finite
// weight or centre, or a key whose rotation is not proper (see rotation_log). Unwraps every key on each
// call: O(K) logarithms; a player blending many frames passes unwrap_rotations(keys) once to the
// overload below.
RigidPose blend_poses(const std::vector<RigidPose>& keys, const SplineWeights& w, const Vec3& centre = Vec3::Zero());

// As above, with `rotation_vectors` = unwrap_rotations(keys) computed once. Throws kInvalidArgument
// also when the sizes differ or a rotation vector is not finite.
RigidPose blend_poses(const std::vector<RigidPose>& keys, const std::vector<Vec3>& rotation_vectors, const SplineWeights& w,
                      const Vec3& centre = Vec3::Zero());

}  // namespace facemorph
