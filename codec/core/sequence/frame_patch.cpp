// Frame patches: sparse lattice displacements between keyframes (spec/method.md §7.19).
#include "codec/core/sequence/frame_patch.hpp"

#include "codec/core/sequence/residual_weights.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <string>

namespace facemorph {

void validate_patches(const std::vector<double>& key_times, const std::vector<FramePatch>& patches) {
  for (size_t p = 0; p < patches.size(); ++p) {
    const FramePatch& f = patches[p];
    const auto fail = [&](const std::string& what) {
      throw Error(ErrorCode::kInvalidArgument, "frame patch " + std::to_string(p) + ": " + what);
    };
    checked_frame_interval(key_times, f.time, p > 0 ? &patches[p - 1].time : nullptr, fail);
    if (f.lattice < kMinPatchLattice || f.lattice > kMaxPatchLattice)
      fail("lattice " + std::to_string(f.lattice) + " outside " + std::to_string(kMinPatchLattice) + ".." +
           std::to_string(kMaxPatchLattice));
    if (f.displacements.size() != f.nodes.size()) fail("not one displacement per node");
    const int64_t count = int64_t{f.lattice} * f.lattice;
    for (size_t n = 0; n < f.nodes.size(); ++n) {
      if (f.nodes[n] < 0 || f.nodes[n] >= count || (n > 0 && f.nodes[n] <= f.nodes[n - 1]))
        fail("node indices must increase within the lattice's " + std::to_string(count));
      if (!f.displacements[n].allFinite()) fail("a displacement is not finite");
    }
  }
}

namespace {

// The lattice cell of coordinate x ∈ [−1, 1] (clamped) and x's fraction across it.
std::pair<int, double> lattice_cell(double x, int lattice) {
  const double f = (x + 1) / 2 * (lattice - 1);
  const int i = std::clamp(static_cast<int>(std::floor(f)), 0, lattice - 2);
  return {i, f - i};
}

// The patch's displacements on every lattice node (zeros where it stores none).
std::vector<Vec3> dense_lattice(const FramePatch& patch) {
  std::vector<Vec3> dense(static_cast<size_t>(patch.lattice) * static_cast<size_t>(patch.lattice), Vec3::Zero());
  for (size_t n = 0; n < patch.nodes.size(); ++n) dense[static_cast<size_t>(patch.nodes[n])] = patch.displacements[n];
  return dense;
}

Vec3 bilinear(const std::vector<Vec3>& dense, int lattice, const Vec2& w) {
  const auto [i, s] = lattice_cell(w.x(), lattice);
  const auto [j, u] = lattice_cell(w.y(), lattice);
  const auto at = [&](int a, int b) -> const Vec3& { return dense[static_cast<size_t>(b) * static_cast<size_t>(lattice) + a]; };
  return (1 - u) * ((1 - s) * at(i, j) + s * at(i + 1, j)) + u * ((1 - s) * at(i, j + 1) + s * at(i + 1, j + 1));
}

}  // namespace

Vec3 patch_displacement(const FramePatch& patch, const Vec2& w) { return bilinear(dense_lattice(patch), patch.lattice, w); }

std::vector<Vec3> frame_patch_displacements(const std::vector<double>& key_times, const std::vector<FramePatch>& patches, double t,
                                            const std::vector<Vec2>& disk_points) {
  const int i = patches.empty() ? -1 : residual_interval(key_times, t);
  if (i < 0) return {};
  // The nodes either side of t within its interval: a patch there, or the interval's keyframe (0).
  const auto after = std::upper_bound(patches.begin(), patches.end(), t, [](double x, const FramePatch& f) { return x < f.time; });
  const FramePatch* left =
      after != patches.begin() && std::prev(after)->time > key_times[static_cast<size_t>(i)] ? &*std::prev(after) : nullptr;
  const FramePatch* right = after != patches.end() && after->time < key_times[static_cast<size_t>(i) + 1] ? &*after : nullptr;
  if (!left && !right) return {};
  const double t0 = left ? left->time : key_times[static_cast<size_t>(i)], t1 = right ? right->time : key_times[static_cast<size_t>(i) + 1];
  const double u = (t - t0) / (t1 - t0);
  std::vector<Vec3> out(disk_points.size(), Vec3::Zero());
  // (1 − u) d_left + u d_right: at a patch's own time exactly its displacement.
  for (const auto& [patch, weight] : {std::pair{left, 1 - u}, std::pair{right, u}}) {
    if (!patch || weight == 0) continue;
    const std::vector<Vec3> dense = dense_lattice(*patch);
    for (size_t n = 0; n < disk_points.size(); ++n) out[n] += weight * bilinear(dense, patch->lattice, disk_points[n]);
  }
  return out;
}

}  // namespace facemorph
