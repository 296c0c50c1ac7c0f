// Solves K X = B for three right-hand sides at once (the x, y, z of a surface) with a sparse
// LDLᵀ factorisation of an SPD matrix. Eigen's triangular solves stream the factor once per
// right-hand side; at N = 256 the factor (1.8M nonzeros) does not fit in cache and that streaming
// is the decoder's bottleneck. Here the factor is walked once for all three columns, in single
// precision with the coordinates padded to four floats (one SIMD operation per factor entry):
// 3-4x faster than Eigen at N = 256, with a relative error of ~4e-7, below the decoder's tolerance.
#pragma once

#include "facemorph/geometry.hpp"

#include <vector>

namespace facemorph {

class TripleSolver {
 public:
  // Factors `K` (SPD). Throws kNumerical if it is not.
  explicit TripleSolver(const SparseMatrix& K);

  // x (n points) for b (n points), to ~4e-7 relative (single-precision factor). The points are the
  // rows of the n x 3 right-hand side: the decoder keeps its surfaces as points, so no transposing
  // copies. `x` may not alias `b`.
  void solve(const Vec3* b, Vec3* x) const;
  // The same plus one step of iterative refinement in double precision: ~1e-13 relative, for
  // callers that need more than single precision (twice the cost).
  void solve_refined(const Vec3* b, Vec3* x) const;

  size_t bytes() const;  // memory held by the factor
  Eigen::Index size() const { return n_; }

 private:
  Eigen::Index n_ = 0;
  SparseMatrix matrix_;               // K itself, for the refinement residual
  std::vector<int32_t> permutation_;  // y = P b: y[i] = b[permutation_[i]]
  std::vector<int32_t> column_start_; // the strictly lower part of L, compressed by column
  std::vector<int32_t> row_;
  std::vector<uint16_t> row16_;       // row_ in 16 bits when n <= 65536 (row_ then empty)
  std::vector<float> value_;
  std::vector<float> inverse_diagonal_;
  struct alignas(16) Float4 {
    float v[4];
  };
  mutable std::vector<Float4> work_;  // x y z (and padding) per unknown
  // Both triangular solves and the diagonal on y in place, with row indices of type Index.
  template <typename Index>
  void walk(const Index* row, Float4* y) const;
};

}  // namespace facemorph
