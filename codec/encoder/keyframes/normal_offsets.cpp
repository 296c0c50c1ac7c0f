#include "codec/encoder/keyframes/normal_offsets.hpp"

#include <algorithm>

namespace facemorph {

namespace {

// Nodes a block: its local positions (3 doubles each) stay in the first-level cache.
constexpr size_t kOffsetBlock = 256;

// sum[j] += w · values[j] for j < n: the keys' coordinates as one flat run of floats.
__attribute__((target_clones("avx2", "default"))) void add_scaled_floats(double* __restrict sum, const float* __restrict values, double w,
                                                                         size_t n) {
  for (size_t j = 0; j < n; ++j) sum[j] += w * static_cast<double>(values[j]);
}

// The rotation's rows 0 and 1 as Eigen's packets compute them, ((x r0 + y r1) + z r2); row 2, the
// one left over, as its unrolled sum splits it, x r0 + (y r1 + z r2). The dot product likewise:
// (dx nx + dy ny) + dz nz.
__attribute__((target_clones("avx2", "default"))) void normal_offsets_of_block(
    const double* __restrict local, const double* __restrict rotation, const double* __restrict translation, const double* __restrict world,
    const float* __restrict normals, size_t n, double* __restrict offsets) {
  const double r00 = rotation[0], r10 = rotation[1], r20 = rotation[2];  // column-major
  const double r01 = rotation[3], r11 = rotation[4], r21 = rotation[5];
  const double r02 = rotation[6], r12 = rotation[7], r22 = rotation[8];
  const double t0 = translation[0], t1 = translation[1], t2 = translation[2];
  for (size_t v = 0; v < n; ++v) {
    const double x = local[3 * v], y = local[3 * v + 1], z = local[3 * v + 2];
    const double p0 = ((x * r00 + y * r01) + z * r02) + t0;
    const double p1 = ((x * r10 + y * r11) + z * r12) + t1;
    const double p2 = (x * r20 + (y * r21 + z * r22)) + t2;
    const double d0 = p0 - world[3 * v], d1 = p1 - world[3 * v + 1], d2 = p2 - world[3 * v + 2];
    offsets[v] = (d0 * static_cast<double>(normals[3 * v]) + d1 * static_cast<double>(normals[3 * v + 1])) +
                 d2 * static_cast<double>(normals[3 * v + 2]);
  }
}

}  // namespace

void predicted_normal_offsets(std::span<const Eigen::Vector3f* const> keys, std::span<const double> weights, const RigidPose& pose,
                              const Vec3* world, const Eigen::Vector3f* normals, size_t count, double* offsets) {
  double local[3 * kOffsetBlock];
  for (size_t first = 0; first < count; first += kOffsetBlock) {
    const size_t n = std::min(kOffsetBlock, count - first);
    std::fill(local, local + 3 * n, 0.0);
    for (size_t i = 0; i < keys.size(); ++i) add_scaled_floats(local, keys[i][first].data(), weights[i], 3 * n);
    normal_offsets_of_block(local, pose.rotation.data(), pose.translation.data(), world[first].data(), normals[first].data(), n,
                            offsets + first);
  }
}

}  // namespace facemorph
