// The least squares of a frame patch's lattice displacements (spec/method.md §7.19), with the
// samples' sums gathered once a lattice: the patch search solves the same samples for up to seven
// sets of moving nodes (one a threshold), and each entry of the normal matrix sums the same
// samples, in the same order, whichever nodes move.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <Eigen/Sparse>

#include <array>
#include <cstddef>
#include <vector>

namespace facemorph {

// A point of one surface, where on the disk it lies and the offset to the other surface.
struct OffsetSample {
  Vec2 w;
  Vec3 offset;  // to the captured surface, capture coordinates
};

// The lattice cell holding disk coordinate x (as frame_patch's bilinear interpolation takes it), and
// where in it x lies (0..1).
std::pair<int, double> patch_cell_of(double x, int lattice);

// The normal equations' solve once the samples' terms are in `entries` and `rhs` (`rows` samples
// touching a moving node): the smoothing's terms added after them, in the order a summed triplet list
// takes them, then the moving nodes' displacements (`index`: lattice node -> unknown, or -1).
std::vector<Vec3> solve_patch_normal(std::vector<Eigen::Triplet<double>> entries, const Eigen::MatrixXd& rhs, const std::vector<int>& index,
                                     int lattice, int unknowns, double smoothing, size_t rows);

// Σ over samples |bilinear(D)(w) − offset|² over the moving nodes (`index`: lattice node -> unknown,
// or -1), plus smoothing × (samples touching a moving node) / unknowns × Σ over lattice edges
// |D_a − D_b|² (a still node counts as 0), so a patch fades to 0 at its border. The result is the
// same to the bit as summing each sample's terms into the normal matrix at each solve: every entry's
// sum takes its samples in their order, from 0, then the smoothing's terms in theirs.
class PatchNormalSums {
 public:
  // Every sample's terms; `only` (where given: a node -> unknown index as solve() takes) keeps the
  // samples whose cell has a moving corner, all that a solve with that index reads.
  PatchNormalSums(const std::vector<OffsetSample>& samples, int lattice, const std::vector<int>* only = nullptr);

  int lattice() const { return lattice_; }
  // The moving nodes' displacements (capture units, one an unknown). `index` must be `only`'s where
  // one was given.
  std::vector<Vec3> solve(const std::vector<int>& index, int unknowns, double smoothing) const;

 private:
  // Node a's entry with its neighbour (a.x + dx, a.y + dy): slot (dy + 1) * 3 + dx + 1.
  static int slot(int dx, int dy) { return (dy + 1) * 3 + dx + 1; }

  int lattice_ = 0;
  std::vector<std::array<double, 9>> pair_;  // Σ w_a w_b over the samples in a cell holding both nodes
  std::vector<std::array<char, 9>> shared_;  // a sample lies in a cell holding both (the entry exists, 0 or not)
  std::vector<Vec3> rhs_;                    // Σ w_a offset over the samples in the cells around a
  std::vector<int> cell_samples_;            // samples a cell holds
};

}  // namespace facemorph
