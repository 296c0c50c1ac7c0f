// Geometric multigrid for K X = B on G's interior (three right-hand sides: the x, y, z of a
// surface), where K is the Dirichlet stiffness matrix of the disk grid: the 5-point stencil on the
// lattice, irregular only in the band by the rim.
//
// The decoder's fixed-point iteration solves K S⁺ = rhs(S) once per step and needs S⁺ only as
// exactly as the step is large: started from the current iterate, one V-cycle (error ×~0.1)
// leaves an inner error a tenth of the step, and the iteration's fixed point is unchanged (a
// V-cycle started from the solution returns it). The direct factor instead streams ~11 MB twice
// per solve at N = 257 and takes most of a fresh decoder's start.
//
// Levels: each coarser lattice keeps the even points (i, j) of the finer one that lie in the disk;
// prolongation is bilinear over the lattice (a parent outside the disk carries zero: the Dirichlet
// rim), restriction its transpose, and each coarse matrix the Galerkin product Pᵀ K P, so the
// rim's irregular rows need no geometry of their own. One Gauss–Seidel sweep smooths before the
// coarse correction and one, backwards, after (the cycle is a symmetric operator), in red-black
// order so that consecutive rows do not wait on each other; the coarsest level (≤ 600 unknowns) is
// factored. The residual is formed in double precision, the correction in single (see cycle()).
#pragma once

#include "codec/core/geometry/differential.hpp"

#include <array>
#include <memory>
#include <vector>

namespace facemorph {

class LatticeMultigrid {
 public:
  // `K` (SPD, n × n) on the lattice points `cells` ((i, j) of each unknown, distinct). Throws
  // kNumerical if the coarsest level cannot be factored, kInvalidArgument on sizes that disagree.
  LatticeMultigrid(const SparseMatrix& K, const std::vector<std::array<int32_t, 2>>& cells);
  ~LatticeMultigrid();
  LatticeMultigrid(const LatticeMultigrid&) = delete;
  LatticeMultigrid& operator=(const LatticeMultigrid&) = delete;

  // One V-cycle improving `x` (n points) towards K x = b in place; returns |b − K x| before it.
  // `b` may not alias `x`.
  double cycle(const Vec3* b, Vec3* x) const { return cycle(b, x, x); }
  // The same from `x` into `out` (which may be `x`; neither may alias `b`).
  double cycle(const Vec3* b, const Vec3* x, Vec3* out) const;
  // V-cycles from `x` until |b − K x| ≤ relative_residual × |b|; the cycles that took (one more
  // is run to measure the last), or −1 when `max_cycles` did not. For starts with no good guess
  // (x = 0: the harmonic surface).
  int solve(const Vec3* b, Vec3* x, double relative_residual, int max_cycles = 40) const;

  int levels() const;
  size_t bytes() const;  // memory held by the hierarchy
  Eigen::Index size() const { return n_; }

 private:
  struct Level;
  Eigen::Index n_ = 0;
  std::vector<std::unique_ptr<Level>> levels_;
  template <typename Value>
  struct PaddedRows;
  std::unique_ptr<PaddedRows<double>> fine_;  // K without its diagonal, for the residual in double precision
  Eigen::VectorXd fine_diagonal_;
  std::vector<int32_t> fine_order_;  // the place of each unknown of K in the finest level's (coloured) order
  void v_cycle(size_t level) const;
};

}  // namespace facemorph
