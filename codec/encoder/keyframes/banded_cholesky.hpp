// The Cholesky factor of a symmetric positive definite band matrix (the keyframe fit's normal
// matrix: a frame's spline weights reach a few neighbouring keyframes, so it couples only those).
// L Lᵀ = A with L lower triangular and as banded as A; O(size · band²) to make, size · (band + 1)
// numbers to hold, where the dense factor of a long capture's thousands of keyframes would not fit.
// Solving with it needs only the `band` rows next to each one, which lets the fit stream its
// right-hand sides through forward and back substitution (sequence_encoder.cpp).
#pragma once

#include <Eigen/Core>

#include <deque>
#include <vector>

namespace facemorph {

class SymmetricBand {
 public:
  SymmetricBand(int size, int band);
  int size() const { return size_; }
  int band() const { return band_; }
  // A(i, j) for |i − j| ≤ band (either order: the matrix is symmetric).
  double& at(int i, int j);
  double at(int i, int j) const;

 private:
  int size_, band_;
  std::vector<double> values_;  // row i: A(i, i − band) .. A(i, i)
};

class BandedCholesky {
 public:
  // Throws kNumerical where A is not positive definite (a pivot not above 0).
  explicit BandedCholesky(const SymmetricBand& a);
  int size() const { return factor_.size(); }
  int band() const { return factor_.band(); }
  // L(i, j) for j ≤ i ≤ j + band.
  double at(int i, int j) const { return factor_.at(i, j); }
  // Solving A X = B a row of B at a time (each row a vector: the fit's rows are surfaces), holding
  // only the `band` rows next to the one solved. Forward substitution's step k: `row` (B's row k)
  // becomes y_k of L y = B, given y_{k − m} .. y_{k − 1} in `before` (m = min(k, band), oldest
  // first). Back substitution's step k: `row` (y_k) becomes X's row k of Lᵀ X = y, given X's rows
  // k + 1 .. k + m in `after` (nearest first). kInternal for another m.
  void forward(int k, Eigen::VectorXd& row, const std::deque<Eigen::VectorXd>& before) const;
  void backward(int k, Eigen::VectorXd& row, const std::deque<Eigen::VectorXd>& after) const;

 private:
  SymmetricBand factor_;
};

}  // namespace facemorph
