#include "codec/reconstruct/triple_solver.hpp"

#include "facemorph/error.hpp"

#include <Eigen/SparseCholesky>

namespace facemorph {

TripleSolver::TripleSolver(const SparseMatrix& K) : n_(K.rows()), matrix_(K) {
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(K);  // AMD ordering
  if (ldlt.info() != Eigen::Success) throw Error(ErrorCode::kNumerical, "the grid Laplacian could not be factored");
  const SparseMatrix L = ldlt.matrixL();  // unit lower triangular, column-major
  const auto& P = ldlt.permutationP();    // K = Pᵀ L D Lᵀ P
  permutation_.resize(static_cast<size_t>(n_));
  for (Eigen::Index i = 0; i < n_; ++i) permutation_[static_cast<size_t>(P.indices()[i])] = static_cast<int32_t>(i);
  column_start_.assign(static_cast<size_t>(n_) + 1, 0);
  for (Eigen::Index j = 0; j < n_; ++j) {
    for (SparseMatrix::InnerIterator it(L, j); it; ++it) {
      if (it.row() == j) continue;  // the unit diagonal
      row_.push_back(static_cast<int32_t>(it.row()));
      value_.push_back(static_cast<float>(it.value()));
    }
    column_start_[static_cast<size_t>(j) + 1] = static_cast<int32_t>(row_.size());
  }
  inverse_diagonal_.resize(static_cast<size_t>(n_));
  const Eigen::VectorXd D = ldlt.vectorD();  // returned by value: once, not per entry
  for (Eigen::Index i = 0; i < n_; ++i) inverse_diagonal_[static_cast<size_t>(i)] = static_cast<float>(1.0 / D[i]);
  work_.resize(static_cast<size_t>(n_));
}

Eigen::MatrixXd TripleSolver::solve_refined(const Eigen::MatrixXd& B) const {
  Eigen::MatrixXd X = solve(B);
  X += solve(B - matrix_ * X);
  return X;
}

size_t TripleSolver::bytes() const {
  return row_.size() * (sizeof(int32_t) + sizeof(float)) + column_start_.size() * sizeof(int32_t) +
         permutation_.size() * sizeof(int32_t) + inverse_diagonal_.size() * sizeof(float);
}

Eigen::MatrixXd TripleSolver::solve(const Eigen::MatrixXd& B) const {
  const auto n = static_cast<size_t>(n_);
  Float4* y = work_.data();
  for (size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(permutation_[i]);
    y[i] = {{static_cast<float>(B(r, 0)), static_cast<float>(B(r, 1)), static_cast<float>(B(r, 2)), 0.0f}};
  }
  // L z = y (unit lower, by columns).
  for (size_t j = 0; j < n; ++j) {
    const Float4 yj = y[j];
    for (int32_t k = column_start_[j]; k < column_start_[j + 1]; ++k) {
      Float4& t = y[static_cast<size_t>(row_[static_cast<size_t>(k)])];
      const float l = value_[static_cast<size_t>(k)];
      for (int c = 0; c < 4; ++c) t.v[c] -= l * yj.v[c];
    }
  }
  for (size_t j = 0; j < n; ++j) {
    for (int c = 0; c < 4; ++c) y[j].v[c] *= inverse_diagonal_[j];
  }
  // Lᵀ x = z: column j of L is row j of Lᵀ.
  for (size_t j = n; j-- > 0;) {
    Float4 sum = y[j];
    for (int32_t k = column_start_[j]; k < column_start_[j + 1]; ++k) {
      const Float4& t = y[static_cast<size_t>(row_[static_cast<size_t>(k)])];
      const float l = value_[static_cast<size_t>(k)];
      for (int c = 0; c < 4; ++c) sum.v[c] -= l * t.v[c];
    }
    y[j] = sum;
  }
  Eigen::MatrixXd X(n_, 3);
  for (size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(permutation_[i]);
    X(r, 0) = y[i].v[0];
    X(r, 1) = y[i].v[1];
    X(r, 2) = y[i].v[2];
  }
  return X;
}

}  // namespace facemorph
