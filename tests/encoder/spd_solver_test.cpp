#include "codec/encoder/conformal/spd_solver.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <dlfcn.h>

#include <filesystem>
#include <random>
#include <vector>

namespace facemorph {
namespace {

using testing::shifted_grid_laplacian;

// Threads of this process now (Linux); -1 where /proc does not say.
int thread_count() {
  std::error_code error;
  int count = 0;
  for (std::filesystem::directory_iterator it("/proc/self/task", error), end; !error && it != end; it.increment(error)) ++count;
  return error ? -1 : count;
}

// The calling thread's OpenMP max-active-levels, where an OpenMP runtime is loaded (CHOLMOD's); -1 if none.
int omp_max_active_levels() {
  const auto get = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels"));
  return get ? get() : -1;
}

// Below 45,000 unknowns the solver factors by CHOLMOD's simplicial method, from them by its
// supernodal one (spd_solver.cpp): both sides of the switch solve and both report an indefinite
// matrix. n = 60 is 3,600 unknowns; n = 215 is 46,225.
class SpdSolverOnEachMethod : public ::testing::TestWithParam<int> {};

TEST_P(SpdSolverOnEachMethod, SolvesAShiftedGridLaplacianToRounding) {
  const SparseMatrix A = shifted_grid_laplacian(GetParam(), 0.01);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd x(A.rows(), 2);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] = normal(rng);
  const Eigen::MatrixXd b = A * x;
  SpdSolver solver;
  solver.analyze(A);
  ASSERT_TRUE(solver.factorize(A));
  const Eigen::MatrixXd solved = solver.solve(b);
  EXPECT_LT((A * solved - b).norm() / b.norm(), 1e-12);
  EXPECT_LT((solved - x).norm() / x.norm(), 1e-8);  // condition number ~ 8 / 0.01
}

TEST_P(SpdSolverOnEachMethod, AnIndefiniteMatrixIsReportedNotFactored) {
  SparseMatrix A = shifted_grid_laplacian(GetParam(), 0.01);
  A.coeffRef(37, 37) = -5;
  SpdSolver solver;
  solver.analyze(A);
  EXPECT_FALSE(solver.factorize(A));
}

INSTANTIATE_TEST_SUITE_P(SimplicialAndSupernodal, SpdSolverOnEachMethod, ::testing::Values(60, 215));

// The encoder runs one frame per thread, so the factorisation must run in the calling thread alone:
// CHOLMOD 3 asks for teams of four (num_threads(4)), which started three OpenMP workers beside every
// frame thread and woke them ~225k times a 20k-vertex frame (spd_solver.cpp). Run under ctest, each
// test is a process of its own, so no earlier test has started OpenMP's workers; and the calling
// thread's own OpenMP setting is what it was.
TEST(SpdSolver, FactorsInTheCallingThreadAloneAndLeavesItsOpenMpSetting) {
  const int before = thread_count();
  if (before < 0) GTEST_SKIP() << "no /proc/self/task to count threads";
  const int levels = omp_max_active_levels();
  const SparseMatrix A = shifted_grid_laplacian(215, 0.01);
  SpdSolver solver;
  solver.analyze(A);
  ASSERT_TRUE(solver.factorize(A));
  const Eigen::MatrixXd x = solver.solve(Eigen::MatrixXd::Ones(A.rows(), 1));
  EXPECT_LT((A * x - Eigen::MatrixXd::Ones(A.rows(), 1)).norm(), 1e-9 * std::sqrt(double(A.rows())));
  EXPECT_EQ(thread_count(), before) << SpdSolver::backend();
  EXPECT_EQ(omp_max_active_levels(), levels);
}

}  // namespace
}  // namespace facemorph
