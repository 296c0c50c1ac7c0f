#include "codec/encoder/conformal/lagged_cholesky.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace facemorph {
namespace {

using testing::shifted_grid_laplacian;

// QIEM's matrices in small: M + δt (L - M D) with a mass M of 1 and 2, δt growing by 1.25 a step
// and D drifting a little, as the flow's do once it has settled.
SparseMatrix step_matrix(const SparseMatrix& L, double dt, double drift) {
  SparseMatrix A = L * dt;
  for (Eigen::Index i = 0; i < A.rows(); ++i) {
    const double mass = i % 7 == 0 ? 1.0 : 2.0;
    const double d = 0.01 * (1 + drift * std::sin(0.37 * double(i)));
    A.coeffRef(i, i) += mass * (1 - dt * d);
  }
  return A;
}

Eigen::MatrixXd random_columns(Eigen::Index rows, Eigen::Index columns, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd x(rows, columns);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] = normal(rng);
  return x;
}

// Readies `lagged` for L's step matrices: the first (δt = 1) analysed, factored and solved with.
void prime(LaggedCholesky& lagged, const SparseMatrix& L, unsigned seed) {
  const SparseMatrix first = step_matrix(L, 1.0, 0);
  lagged.analyze(first);
  Eigen::MatrixXd X;
  ASSERT_TRUE(lagged.solve(first, random_columns(L.rows(), 2, seed), X));
}

// ‖A‖∞, the largest absolute row sum.
double infinity_norm(const SparseMatrix& A) { return (A.cwiseAbs() * Eigen::VectorXd::Ones(A.cols())).maxCoeff(); }

// Every solve of a drifting run is as good as a factorisation's (backward error to the solver's
// tolerance, the solution to the direct solve's within the condition number's reach), and most of
// them factor nothing: a CG that does not converge, or a preconditioner that is not applied, sends
// every step to the factorisation and fails the count.
TEST(LaggedCholesky, ADriftingRunSolvesToRoundingWithFewFactorisations) {
  const SparseMatrix L = shifted_grid_laplacian(40, 0.0);
  LaggedCholesky lagged;
  lagged.analyze(step_matrix(L, 1.0, 0));
  const int steps = 12;
  double dt = 1.0;
  for (int step = 0; step < steps; ++step, dt *= 1.25) {
    const SparseMatrix A = step_matrix(L, dt, 0.02 * step);
    const Eigen::MatrixXd B = random_columns(A.rows(), 2, 11 + step);
    Eigen::MatrixXd X;
    ASSERT_TRUE(lagged.solve(A, B, X)) << "step " << step;
    SpdSolver direct;
    direct.analyze(A);
    ASSERT_TRUE(direct.factorize(A));
    const Eigen::MatrixXd exact = direct.solve(B);
    for (int j = 0; j < 2; ++j) {
      const double residual = (B.col(j) - A * X.col(j)).lpNorm<Eigen::Infinity>();
      EXPECT_LE(residual, LaggedCholesky::kBackwardErrorTolerance *
                              (B.col(j).lpNorm<Eigen::Infinity>() + infinity_norm(A) * X.col(j).lpNorm<Eigen::Infinity>()))
          << "step " << step << " column " << j;
      EXPECT_LT((X.col(j) - exact.col(j)).norm() / exact.col(j).norm(), 1e-9) << "step " << step << " column " << j;
    }
  }
  EXPECT_LE(lagged.factorizations(), steps / 2);  // QIEM on ICT 9.4k: 6 of 22
  EXPECT_GT(lagged.cg_iterations(), 0);
}

// A column of zeros is solved by zeros beside a column that needs CG's iterations.
TEST(LaggedCholesky, AZeroColumnStaysZeroBesideAnother) {
  const SparseMatrix L = shifted_grid_laplacian(30, 0.0);
  LaggedCholesky lagged;
  ASSERT_NO_FATAL_FAILURE(prime(lagged, L, 3));
  Eigen::MatrixXd X;
  Eigen::MatrixXd B = random_columns(L.rows(), 2, 4);
  B.col(1).setZero();
  const SparseMatrix A = step_matrix(L, 1.25, 0.05);
  ASSERT_TRUE(lagged.solve(A, B, X));
  EXPECT_EQ(lagged.factorizations(), 1);
  EXPECT_EQ(X.col(1).lpNorm<Eigen::Infinity>(), 0.0);
  EXPECT_LT((B.col(0) - A * X.col(0)).norm() / B.col(0).norm(), 1e-11);
}

// A matrix that is not positive definite is reported as the factorisation would, even when an
// earlier factor is there to precondition CG (CG meets its negative curvature, or gives up, and
// the factorisation decides). A step too long for QIEM makes such a matrix.
TEST(LaggedCholesky, AnIndefiniteMatrixIsReportedWithAnEarlierFactorAtHand) {
  const SparseMatrix L = shifted_grid_laplacian(30, 0.0);
  LaggedCholesky lagged;
  ASSERT_NO_FATAL_FAILURE(prime(lagged, L, 5));
  Eigen::MatrixXd X;
  SparseMatrix indefinite = step_matrix(L, 1.25, 0);
  for (int i : {37, 400, 611}) indefinite.coeffRef(i, i) = -50;
  EXPECT_FALSE(lagged.solve(indefinite, random_columns(L.rows(), 2, 6), X));
  // And the solver recovers: the next positive definite matrix is solved.
  const SparseMatrix A = step_matrix(L, 1.25, 0);
  const Eigen::MatrixXd B = random_columns(L.rows(), 2, 7);
  ASSERT_TRUE(lagged.solve(A, B, X));
  EXPECT_LT((B - A * X).norm() / B.norm(), 1e-11);
}

// A matrix far from the factor's (δt a hundred times shorter) is still solved to rounding: CG gives
// up or converges, and either way the answer is right.
TEST(LaggedCholesky, AMatrixFarFromTheFactorsIsStillSolved) {
  const SparseMatrix L = shifted_grid_laplacian(30, 0.0);
  LaggedCholesky lagged;
  ASSERT_NO_FATAL_FAILURE(prime(lagged, L, 8));
  Eigen::MatrixXd X;
  const SparseMatrix A = step_matrix(L, 0.01, 0);
  const Eigen::MatrixXd B = random_columns(L.rows(), 2, 9);
  ASSERT_TRUE(lagged.solve(A, B, X));
  EXPECT_LT((B - A * X).norm() / B.norm(), 1e-11);
}

}  // namespace
}  // namespace facemorph
