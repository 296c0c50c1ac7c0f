#include "codec/encoder/conformal/lagged_cholesky.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {

void LaggedCholesky::analyze(const SparseMatrix& A) {
  factor_.analyze(A);
  have_factor_ = false;
}

bool LaggedCholesky::solve(const SparseMatrix& A, const Eigen::MatrixXd& B, Eigen::MatrixXd& X) {
  if (have_factor_ && !refactor_next_ && conjugate_gradients(A, B, X) == Cg::kConverged) return true;
  ++factorizations_;
  refactor_next_ = false;
  have_factor_ = factor_.factorize(A);
  if (!have_factor_) return false;
  X = factor_.solve(B);
  return true;
}

// Preconditioned CG on every column of B at once (one preconditioner solve for all of them), each
// column with its own step lengths, from the preconditioner's own solution.
LaggedCholesky::Cg LaggedCholesky::conjugate_gradients(const SparseMatrix& A, const Eigen::MatrixXd& B, Eigen::MatrixXd& X) {
  double norm_a = 0;  // ‖A‖∞, the largest absolute row sum (A is symmetric: column sums)
  for (int c = 0; c < A.outerSize(); ++c) {
    double sum = 0;
    for (SparseMatrix::InnerIterator it(A, c); it; ++it) sum += std::abs(it.value());
    norm_a = std::max(norm_a, sum);
  }
  const Eigen::Index columns = B.cols();
  X = factor_.solve(B);
  Eigen::MatrixXd R = B - A * X;
  Eigen::MatrixXd Z = factor_.solve(R);
  Eigen::MatrixXd P = Z;
  Eigen::VectorXd rz = (R.array() * Z.array()).colwise().sum().transpose();
  for (int iteration = 0;; ++iteration) {
    bool converged = true;
    for (Eigen::Index j = 0; j < columns; ++j) {
      const double bound = kBackwardErrorTolerance * (B.col(j).lpNorm<Eigen::Infinity>() + norm_a * X.col(j).lpNorm<Eigen::Infinity>());
      if (!(R.col(j).lpNorm<Eigen::Infinity>() <= bound)) converged = false;
    }
    if (converged) {
      refactor_next_ = iteration > kRefactorAfter;
      return Cg::kConverged;
    }
    if (iteration == kMaxIterations) return Cg::kTooSlow;
    ++cg_iterations_;
    const Eigen::MatrixXd AP = A * P;
    for (Eigen::Index j = 0; j < columns; ++j) {
      const double curvature = P.col(j).dot(AP.col(j));
      if (!(curvature > 0)) {
        if (rz[j] == 0) continue;  // this column is solved exactly: P is 0
        return Cg::kNotPositive;
      }
      const double alpha = rz[j] / curvature;
      X.col(j) += alpha * P.col(j);
      R.col(j) -= alpha * AP.col(j);
    }
    Z = factor_.solve(R);
    for (Eigen::Index j = 0; j < columns; ++j) {
      const double next = R.col(j).dot(Z.col(j));
      const double beta = rz[j] == 0 ? 0 : next / rz[j];
      P.col(j) = Z.col(j) + beta * P.col(j);
      rz[j] = next;
    }
  }
}

}  // namespace facemorph
