// Solves a run of SPD systems on one sparsity pattern whose matrices change a little from one to
// the next (QIEM's steps, qiem.cpp): conjugate gradients preconditioned by the Cholesky factor of an
// earlier matrix of the run, and a fresh factorisation only when that no longer converges quickly.
// A factorisation costs as much as 7 (2k unknowns) to 15 (10k) CG iterations with its factor, and
// CG on an earlier step's factor converges in 5-10 (spec/method.md §3.3, *A lagged factor*).
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/encoder/conformal/spd_solver.hpp"

#include <Eigen/Core>

namespace facemorph {

class LaggedCholesky {
 public:
  // CG stops when every column's residual is below this fraction of its right-hand side's norm
  // plus ‖A‖∞ times its solution's: the backward error of a factorisation's solve, a little
  // above rounding.
  static constexpr double kBackwardErrorTolerance = 1e-13;
  // CG gives up after this many iterations and the matrix is factored afresh.
  static constexpr int kMaxIterations = 12;
  // A solve that needed more iterations than this factors the next matrix afresh: the matrices
  // drift away from the factor's, so the next would need more still. QIEM's flows, the solves'
  // time (fmbench conformal, ICT 9.4k, ICT 2k, synth 5k-40k): 4 to 8 about alike, 6 the least.
  static constexpr int kRefactorAfter = 6;

  void analyze(const SparseMatrix& A);
  // X = A⁻¹ B. False when A's factorisation failed: A is not positive definite. CG hands A to
  // the factorisation when it meets a direction of non-positive curvature; it can also converge on
  // an indefinite A without meeting one, and that solve is returned (QIEM weighs every step by its
  // energy, which decides).
  bool solve(const SparseMatrix& A, const Eigen::MatrixXd& B, Eigen::MatrixXd& X);
  int factorizations() const { return factorizations_; }
  int cg_iterations() const { return cg_iterations_; }

 private:
  enum class Cg { kConverged, kTooSlow, kNotPositive };
  Cg conjugate_gradients(const SparseMatrix& A, const Eigen::MatrixXd& B, Eigen::MatrixXd& X);

  SpdSolver factor_;
  bool have_factor_ = false;
  bool refactor_next_ = false;
  int factorizations_ = 0;
  int cg_iterations_ = 0;
};

}  // namespace facemorph
