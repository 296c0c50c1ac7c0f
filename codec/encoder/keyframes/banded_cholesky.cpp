#include "codec/encoder/keyframes/banded_cholesky.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <utility>

namespace facemorph {

SymmetricBand::SymmetricBand(int size, int band) : size_(size), band_(band) {
  if (size < 0 || band < 0) throw Error(ErrorCode::kInvalidArgument, "band matrix: a negative size or band");
  values_.assign(static_cast<size_t>(size) * static_cast<size_t>(band + 1), 0.0);
}

double& SymmetricBand::at(int i, int j) {
  if (i < j) std::swap(i, j);
  if (j < 0 || i >= size_ || i - j > band_)
    throw Error(ErrorCode::kInternal, "band matrix: (" + std::to_string(i) + ", " + std::to_string(j) + ") outside the band");
  return values_[static_cast<size_t>(i) * static_cast<size_t>(band_ + 1) + static_cast<size_t>(band_ - (i - j))];
}

double SymmetricBand::at(int i, int j) const { return const_cast<SymmetricBand&>(*this).at(i, j); }

BandedCholesky::BandedCholesky(const SymmetricBand& a) : factor_(a.size(), a.band()) {
  const int b = a.band();
  for (int i = 0; i < a.size(); ++i) {
    for (int j = std::max(0, i - b); j <= i; ++j) {
      double s = a.at(i, j);
      for (int m = std::max(0, i - b); m < j; ++m) s -= factor_.at(i, m) * factor_.at(j, m);
      if (i == j) {
        if (!(s > 0)) throw Error(ErrorCode::kNumerical, "band matrix: not positive definite at row " + std::to_string(i));
        factor_.at(i, i) = std::sqrt(s);
      } else {
        factor_.at(i, j) = s / factor_.at(j, j);
      }
    }
  }
}

void BandedCholesky::forward(int k, Eigen::VectorXd& row, const std::deque<Eigen::VectorXd>& before) const {
  const int m = static_cast<int>(before.size());
  if (k < 0 || k >= size() || m != std::min(k, band()))
    throw Error(ErrorCode::kInternal, "band solve: forward step " + std::to_string(k) + " given " + std::to_string(m) + " rows before it");
  for (int i = 0; i < m; ++i) row -= at(k, k - m + i) * before[static_cast<size_t>(i)];
  row /= at(k, k);
}

void BandedCholesky::backward(int k, Eigen::VectorXd& row, const std::deque<Eigen::VectorXd>& after) const {
  const int m = static_cast<int>(after.size());
  if (k < 0 || k >= size() || m != std::min(size() - 1 - k, band()))
    throw Error(ErrorCode::kInternal, "band solve: back step " + std::to_string(k) + " given " + std::to_string(m) + " rows after it");
  for (int i = 0; i < m; ++i) row -= at(k + 1 + i, k) * after[static_cast<size_t>(i)];
  row /= at(k, k);
}

}  // namespace facemorph
