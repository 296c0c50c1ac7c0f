// Sparse symmetric positive-definite factorisation for the encoder's large systems (the QIEM step,
// the linear map, the density-equalising diffusion). CHOLMOD's Cholesky (SuiteSparse, with the
// system's BLAS) when facemorph is built with it — simplicial below 45,000 unknowns, supernodal from
// them, where its dense blocks pay for its OpenMP regions (spd_solver.cpp) — else Eigen's
// simplicial LDLᵀ. Each call runs
// CHOLMOD's OpenMP regions as teams of one thread (the calling thread's setting, put back after
// the call), and OpenBLAS runs with one thread (process-wide): the encoder parallelises over frames
// (spd_solver.cpp says what that saved).
#pragma once

#include "codec/core/geometry/differential.hpp"

#include <memory>

namespace facemorph {

class SpdSolver {
 public:
  SpdSolver();
  ~SpdSolver();
  SpdSolver(const SpdSolver&) = delete;
  SpdSolver& operator=(const SpdSolver&) = delete;

  // Symbolic analysis (ordering) of the pattern; done once when the pattern does not change.
  void analyze(const SparseMatrix& A);
  // Numeric factorisation; false when A is not (numerically) positive definite.
  bool factorize(const SparseMatrix& A);
  Eigen::MatrixXd solve(const Eigen::MatrixXd& b) const;
  static const char* backend();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace facemorph
