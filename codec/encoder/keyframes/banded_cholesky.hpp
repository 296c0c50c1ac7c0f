// The Cholesky factor of a symmetric positive definite band matrix (the keyframe fit's normal
// matrix: a frame's spline weights reach a few neighbouring keyframes, so it couples only those).
// L Lᵀ = A with L lower triangular and as banded as A; O(size · band²) to make, size · (band + 1)
// numbers to hold, where the dense factor of a long capture's thousands of keyframes would not fit.
// Solving with it needs only the `band` rows next to each one, which lets the fit stream its
// right-hand sides through forward and back substitution (sequence_encoder.cpp).
#pragma once

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

 private:
  SymmetricBand factor_;
};

}  // namespace facemorph
