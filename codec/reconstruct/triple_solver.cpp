#include "codec/reconstruct/triple_solver.hpp"

#include "facemorph/error.hpp"

#include <Eigen/SparseCholesky>

namespace facemorph {

// Points are read as the rows of an n x 3 array.
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");

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
  if (n_ <= 65536) {
    // Row indices in 16 bits: the walk streams 6 bytes per entry instead of 8 (N <= 257).
    row16_.assign(row_.begin(), row_.end());
    row_.clear();
    row_.shrink_to_fit();
  }
  inverse_diagonal_.resize(static_cast<size_t>(n_));
  const Eigen::VectorXd D = ldlt.vectorD();  // returned by value: once, not per entry
  for (Eigen::Index i = 0; i < n_; ++i) inverse_diagonal_[static_cast<size_t>(i)] = static_cast<float>(1.0 / D[i]);
  work_.resize(static_cast<size_t>(n_));
}

void TripleSolver::solve_refined(const Vec3* b, Vec3* x) const {
  using Points = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
  solve(b, x);
  const Eigen::Map<const Points> B(b->data(), n_, 3);
  Eigen::Map<Points> X(x->data(), n_, 3);
  const Points residual = B - matrix_ * X;
  std::vector<Vec3> correction(static_cast<size_t>(n_));
  solve(reinterpret_cast<const Vec3*>(residual.data()), correction.data());
  for (size_t i = 0; i < correction.size(); ++i) x[i] += correction[i];
}

size_t TripleSolver::bytes() const {
  return row_.size() * sizeof(int32_t) + row16_.size() * sizeof(uint16_t) + value_.size() * sizeof(float) + column_start_.size() * sizeof(int32_t) +
         permutation_.size() * sizeof(int32_t) + inverse_diagonal_.size() * sizeof(float);
}

void TripleSolver::solve(const Vec3* b, Vec3* x) const {
  const auto n = static_cast<size_t>(n_);
  Float4* y = work_.data();
  for (size_t i = 0; i < n; ++i) {
    const Vec3& r = b[permutation_[i]];
    y[i] = {{static_cast<float>(r.x()), static_cast<float>(r.y()), static_cast<float>(r.z()), 0.0f}};
  }
  if (row16_.empty()) {
    walk(row_.data(), y);
  } else {
    walk(row16_.data(), y);
  }
  for (size_t i = 0; i < n; ++i) x[permutation_[i]] = Vec3(y[i].v[0], y[i].v[1], y[i].v[2]);
}

template <typename Index>
void TripleSolver::walk(const Index* row, Float4* y) const {
  const auto n = static_cast<size_t>(n_);
  const float* value = value_.data();
  // L z = y (unit lower, by columns).
  for (size_t j = 0; j < n; ++j) {
    const Float4 yj = y[j];
    for (int32_t k = column_start_[j]; k < column_start_[j + 1]; ++k) {
      Float4& t = y[static_cast<size_t>(row[k])];
      const float l = value[k];
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
      const Float4& t = y[static_cast<size_t>(row[k])];
      const float l = value[k];
      for (int c = 0; c < 4; ++c) sum.v[c] -= l * t.v[c];
    }
    y[j] = sum;
  }
}

}  // namespace facemorph
