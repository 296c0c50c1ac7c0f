// The keyframe fit's band factor against Eigen's dense one, and its refusals.
#include "codec/encoder/keyframes/banded_cholesky.hpp"

#include "format/error.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>
#include <Eigen/Cholesky>

#include <deque>
#include <random>

namespace facemorph {
namespace {

// Fills `a` with a random matrix of its band, diagonally dominant (so positive definite), and
// returns the same matrix dense.
Eigen::MatrixXd random_band(SymmetricBand& a, std::mt19937& random) {
  std::uniform_real_distribution<double> value(-1, 1);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(a.size(), a.size());
  for (int i = 0; i < a.size(); ++i) {
    for (int j = std::max(0, i - a.band()); j <= i; ++j) {
      const double v = i == j ? 2.0 * (a.band() + 1) : value(random);
      a.at(i, j) = v;
      dense(i, j) = dense(j, i) = v;
    }
  }
  return dense;
}

TEST(BandedCholesky, IsTheDenseFactorWithinTheBandAndZeroOutside) {
  std::mt19937 random(7);
  for (const auto& [size, band] : {std::pair{1, 0}, std::pair{9, 1}, std::pair{40, 3}, std::pair{12, 11}}) {
    SymmetricBand a(size, band);
    const Eigen::MatrixXd dense = random_band(a, random);
    const BandedCholesky factor(a);
    const Eigen::MatrixXd l = dense.llt().matrixL();
    for (int i = 0; i < size; ++i) {
      for (int j = 0; j <= i; ++j) {
        if (i - j <= band) {
          EXPECT_NEAR(factor.at(i, j), l(i, j), 1e-12) << size << " " << band << " (" << i << ", " << j << ")";
        } else {
          EXPECT_NEAR(l(i, j), 0, 1e-12) << "the dense factor fills outside the band";
        }
      }
    }
  }
}

// The fit's streamed solve: rows of B in, forward substitution holding `band` rows, then back
// substitution from the last, against Eigen's dense solve of A X = B.
TEST(BandedCholesky, StreamedSubstitutionSolvesTheSystemRowByRow) {
  std::mt19937 random(11);
  for (const auto& [size, band] : {std::pair{1, 0}, std::pair{2, 1}, std::pair{7, 0}, std::pair{50, 3}, std::pair{30, 5}}) {
    SymmetricBand a(size, band);
    const Eigen::MatrixXd dense = random_band(a, random);
    const Eigen::MatrixXd b = Eigen::MatrixXd::Random(size, 4);
    const BandedCholesky factor(a);
    std::vector<Eigen::VectorXd> y(static_cast<size_t>(size));
    std::deque<Eigen::VectorXd> window;
    for (int k = 0; k < size; ++k) {
      Eigen::VectorXd row = b.row(k).transpose();
      factor.forward(k, row, window);
      y[static_cast<size_t>(k)] = row;
      window.push_back(row);
      if (static_cast<int>(window.size()) > band) window.pop_front();
    }
    window.clear();
    const Eigen::MatrixXd x = dense.ldlt().solve(b);
    for (int k = size - 1; k >= 0; --k) {
      Eigen::VectorXd row = y[static_cast<size_t>(k)];
      factor.backward(k, row, window);
      EXPECT_LT((row - x.row(k).transpose()).cwiseAbs().maxCoeff(), 1e-12) << size << " " << band << " row " << k;
      window.push_front(row);
      if (static_cast<int>(window.size()) > band) window.pop_back();
    }
    if (size > 2 && band > 0) {
      Eigen::VectorXd row = b.row(2).transpose();
      testing::expect_error(ErrorCode::kInternal, "forward step 2", [&] { factor.forward(2, row, {}); });
    }
  }
}

TEST(BandedCholesky, RefusesAMatrixThatIsNotPositiveDefiniteAndReadsOnlyItsBand) {
  SymmetricBand a(3, 1);
  a.at(0, 0) = 1;
  a.at(1, 0) = 2;  // makes the second pivot 1 − 4 < 0
  a.at(1, 1) = 1;
  a.at(2, 2) = 1;
  testing::expect_error(ErrorCode::kNumerical, "not positive definite at row 1", [&] { BandedCholesky factor(a); });
  testing::expect_error(ErrorCode::kInternal, "outside the band", [&] { a.at(2, 0) = 1; });
  EXPECT_EQ(a.at(0, 1), 2) << "symmetric";
  testing::expect_error(ErrorCode::kInvalidArgument, "negative", [] { SymmetricBand(-1, 0); });
}

}  // namespace
}  // namespace facemorph
