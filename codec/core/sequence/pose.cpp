// Rigid head poses: the weighted Kabsch fit, SO(3) log and exp, and the pose spline (method-notes
// §7 applied to the pose; spec/method.md §7).
#include "codec/core/sequence/pose.hpp"

#include "format/error.hpp"

#include <Eigen/SVD>

#include <cmath>
#include <numbers>
#include <string>

namespace facemorph {

namespace {

constexpr double kTwoPi = 2 * std::numbers::pi;

[[noreturn]] void fail(const std::string& what) { throw Error(ErrorCode::kInvalidArgument, what); }

// Whether R is a finite proper rotation to 1e-6: poses from files and fits, not exact matrices.
bool is_rotation(const Eigen::Matrix3d& r) {
  return r.allFinite() && (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-6 &&
         std::abs(r.determinant() - 1) <= 1e-6;
}

void check_rotation(const Eigen::Matrix3d& r, const std::string& what) {
  if (!is_rotation(r)) fail(what + ": not a finite proper rotation (orthonormal, det +1, to 1e-6)");
}

// rotation_log without the check, for products of checked rotations (their error adds up).
Vec3 log_of_rotation(const Eigen::Matrix3d& r) {
  // sin θ · axis from the antisymmetric part, cos θ from the trace: atan2 of both gives θ to
  // rounding at every angle, where acos loses half the digits near 0 and π.
  const Vec3 v = 0.5 * Vec3(r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1));
  const double c = 0.5 * (r.trace() - 1), s = v.norm();
  const double theta = std::atan2(s, c);
  if (c >= 0) return s > 0 ? Vec3(v * (theta / s)) : Vec3::Zero();  // θ ≤ π/2: v / s is the axis to rounding
  // θ > π/2: sin θ vanishes toward π, so take the axis from the symmetric part, (1 - c) a aᵀ, whose
  // largest column is well away from zero (1 - c > 1), and only its sign from v.
  const Eigen::Matrix3d b = 0.5 * (r + r.transpose()) - c * Eigen::Matrix3d::Identity();
  int j = 0;
  b.diagonal().maxCoeff(&j);
  Vec3 axis = b.col(j).normalized();
  if (axis.dot(v) < 0) axis = -axis;
  return theta * axis;
}

Eigen::Matrix3d skew(const Vec3& w) {
  Eigen::Matrix3d k;
  k << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return k;
}

}  // namespace

bool RigidPose::is_proper() const {
  return rotation.allFinite() && translation.allFinite() &&
         (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm() <= 1e-6 && rotation.determinant() > 0;
}

RigidPose RigidPose::inverse() const {
  RigidPose out;
  out.rotation = rotation.transpose();
  out.translation = -(out.rotation * translation);
  return out;
}

RigidPose RigidPose::operator*(const RigidPose& first) const {
  RigidPose out;
  out.rotation = rotation * first.rotation;
  out.translation = rotation * first.translation + translation;
  return out;
}

RigidPose fit_rigid_pose(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const std::vector<double>& weights) {
  const std::string name = "fit_rigid_pose: ";
  if (from.size() != to.size()) fail(name + std::to_string(from.size()) + " points to map onto " + std::to_string(to.size()));
  if (!weights.empty() && weights.size() != from.size()) {
    fail(name + std::to_string(weights.size()) + " weights for " + std::to_string(from.size()) + " points");
  }
  if (from.size() < 3) fail(name + "needs at least 3 points, got " + std::to_string(from.size()));
  double total = 0;
  Vec3 from_mean = Vec3::Zero(), to_mean = Vec3::Zero();
  for (size_t i = 0; i < from.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!std::isfinite(w) || w < 0) fail(name + "weight " + std::to_string(i) + " must be finite and non-negative");
    if (!from[i].allFinite() || !to[i].allFinite()) fail(name + "point " + std::to_string(i) + " is not finite");
    total += w;
    from_mean += w * from[i];
    to_mean += w * to[i];
  }
  if (!(total > 0) || !std::isfinite(total)) fail(name + "the weights sum to " + std::to_string(total));
  from_mean /= total;
  to_mean /= total;
  // Cross-covariance about the weighted centroids: centring first keeps a large offset (a face a metre
  // from the camera) from swamping the millimetre shape in rounding.
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < from.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    cov += (w / total) * (from[i] - from_mean) * (to[i] - to_mean).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d& u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  // R = V diag(1, 1, d) Uᵀ: d = -1 turns a reflection (mirrored or flat input) into the best proper
  // rotation by flipping the direction of least covariance.
  Eigen::Vector3d d(1, 1, (v * u.transpose()).determinant() < 0 ? -1 : 1);
  RigidPose pose;
  pose.rotation = v * d.asDiagonal() * u.transpose();
  pose.translation = to_mean - pose.rotation * from_mean;
  if (!pose.rotation.allFinite() || !pose.translation.allFinite()) {
    throw Error(ErrorCode::kNumerical, name + "the fit overflowed (coordinates too large)");
  }
  return pose;
}

Vec3 rotation_log(const Eigen::Matrix3d& rotation) {
  check_rotation(rotation, "rotation_log");
  return log_of_rotation(rotation);
}

Eigen::Matrix3d rotation_exp(const Vec3& rotation_vector) {
  const double theta = rotation_vector.norm();
  if (!rotation_vector.allFinite() || !std::isfinite(theta)) fail("rotation_exp: the rotation vector is not finite");
  // R = I + (sin θ / θ) K + ((1 - cos θ) / θ²) K², K = [w]×. The second factor as ½ (sin(θ/2) / (θ/2))²
  // avoids the cancellation in 1 - cos θ; below 1e-4 the series (error < θ⁶ / 5040) avoids 0 / 0.
  double a, b;
  if (theta < 1e-4) {
    const double t2 = theta * theta;
    a = 1 - t2 / 6 * (1 - t2 / 20);
    b = 0.5 - t2 / 24 * (1 - t2 / 30);
  } else {
    a = std::sin(theta) / theta;
    const double half = std::sin(theta / 2) / (theta / 2);
    b = 0.5 * half * half;
  }
  const Eigen::Matrix3d k = skew(rotation_vector);
  return Eigen::Matrix3d::Identity() + a * k + b * (k * k);
}

std::vector<Vec3> unwrap_rotations(const std::vector<RigidPose>& keys) {
  if (keys.empty()) fail("unwrap_rotations: no keys");
  for (size_t k = 0; k < keys.size(); ++k) check_rotation(keys[k].rotation, "unwrap_rotations: key " + std::to_string(k));
  const Eigen::Matrix3d base = keys[0].rotation.transpose();
  std::vector<Vec3> out(keys.size(), Vec3::Zero());
  for (size_t k = 1; k < keys.size(); ++k) {
    const Vec3 principal = log_of_rotation(base * keys[k].rotation);
    const Vec3& previous = out[k - 1];
    const double theta = principal.norm();
    // The same rotation is (θ + 2πn) · axis for every whole n; |that - previous| is least where
    // θ + 2πn is nearest to the previous vector's component along the axis.
    if (theta > 1e-9) {
      const Vec3 axis = principal / theta;
      const double n = std::round((axis.dot(previous) - theta) / kTwoPi);
      out[k] = (theta + kTwoPi * n) * axis;
    } else if (previous.norm() > std::numbers::pi) {
      // Within 1e-9 of the identity after more than half a turn: the axis of so small an angle is
      // rounding noise and could unwrap anywhere, so take whole turns about the previous axis (off
      // by at most the 1e-9 rad left out).
      const double length = previous.norm();
      out[k] = (kTwoPi * std::round(length / kTwoPi) / length) * previous;
    } else {
      out[k] = principal;
    }
  }
  return out;
}

RigidPose blend_poses(const std::vector<RigidPose>& keys, const SplineWeights& w, const Vec3& centre) {
  return blend_poses(keys, unwrap_rotations(keys), w, centre);
}

RigidPose blend_poses(const std::vector<RigidPose>& keys, const std::vector<Vec3>& rotation_vectors, const SplineWeights& w,
                      const Vec3& centre) {
  const std::string name = "blend_poses: ";
  if (keys.empty()) fail(name + "no keys");
  if (rotation_vectors.size() != keys.size()) {
    fail(name + std::to_string(rotation_vectors.size()) + " rotation vectors for " + std::to_string(keys.size()) + " keys");
  }
  if (w.keys.size() != w.weights.size())
    fail(name + std::to_string(w.keys.size()) + " keys with " + std::to_string(w.weights.size()) + " weights");
  if (w.keys.empty()) fail(name + "no weights");
  if (!centre.allFinite()) fail(name + "the centre is not finite");
  check_rotation(keys[0].rotation, name + "key 0");
  Vec3 xi = Vec3::Zero(), position = Vec3::Zero();
  for (size_t i = 0; i < w.keys.size(); ++i) {
    const int32_t k = w.keys[i];
    if (k < 0 || static_cast<size_t>(k) >= keys.size()) fail(name + "key " + std::to_string(k) + " of " + std::to_string(keys.size()));
    if (!std::isfinite(w.weights[i])) fail(name + "the weight of key " + std::to_string(k) + " is not finite");
    const RigidPose& key = keys[static_cast<size_t>(k)];
    check_rotation(key.rotation, name + "key " + std::to_string(k));
    const Vec3& rotation_vector = rotation_vectors[static_cast<size_t>(k)];
    if (!key.translation.allFinite() || !rotation_vector.allFinite()) fail(name + "key " + std::to_string(k) + " is not finite");
    xi += w.weights[i] * rotation_vector;
    position += w.weights[i] * key.apply(centre);
  }
  RigidPose out;
  out.rotation = keys[0].rotation * rotation_exp(xi);
  out.translation = position - out.rotation * centre;
  return out;
}

}  // namespace facemorph
