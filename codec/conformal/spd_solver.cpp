#include "codec/conformal/spd_solver.hpp"

#ifdef FACEMORPH_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#else
#include <Eigen/SparseCholesky>
#endif

namespace facemorph {

#ifdef FACEMORPH_HAVE_CHOLMOD
struct SpdSolver::Impl {
  Eigen::CholmodSupernodalLLT<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "cholmod-supernodal"; }
#else
struct SpdSolver::Impl {
  Eigen::SimplicialLDLT<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "eigen-simplicial-ldlt"; }
#endif

SpdSolver::SpdSolver() : impl_(std::make_unique<Impl>()) {
#ifdef FACEMORPH_HAVE_CHOLMOD
  // A failed factorisation is an expected outcome (the caller shortens the step); CHOLMOD must not
  // print about it on the user's terminal.
  impl_->solver.cholmod().print = 0;
  impl_->solver.cholmod().error_handler = nullptr;
#endif
}
SpdSolver::~SpdSolver() = default;

void SpdSolver::analyze(const SparseMatrix& A) { impl_->solver.analyzePattern(A); }

bool SpdSolver::factorize(const SparseMatrix& A) {
  impl_->solver.factorize(A);
  return impl_->solver.info() == Eigen::Success;
}

Eigen::MatrixXd SpdSolver::solve(const Eigen::MatrixXd& b) const { return impl_->solver.solve(b); }

}  // namespace facemorph
