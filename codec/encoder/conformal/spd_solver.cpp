#include "codec/encoder/conformal/spd_solver.hpp"

#ifdef FACEMORPH_HAVE_CHOLMOD
#include <dlfcn.h>
#include <Eigen/CholmodSupport>
#include <mutex>
#else
#include <Eigen/SparseCholesky>
#endif

namespace facemorph {

#ifdef FACEMORPH_HAVE_CHOLMOD
struct SpdSolver::Impl {
  Eigen::CholmodSupernodalLLT<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "cholmod-supernodal"; }

namespace {

// One solver thread in each thread that factors. The encoder gives its cores to frames (one frame
// per thread); CHOLMOD's supernodal factorisation opens an OpenMP team per supernode (225k teams for
// one 20k-vertex frame), and the BLAS under it has its own thread pool, so two frame threads ran
// four to six threads on two cores, spinning. Measured (fmbench conformal --sweep on 6 frames of
// 20k vertices, --threads 2): CPU time 5.2 → 3.2 s, wall 9.2 → 4.8 s. Looked up at run time: the
// BLAS may not be OpenBLAS, and OpenMP's thread count is per thread, set before its first team.
void one_solver_thread_here() {
  thread_local bool done = false;
  if (done) return;
  done = true;
  using SetThreads = void (*)(int);
  if (auto omp = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "omp_set_num_threads"))) omp(1);
  static std::once_flag blas;
  std::call_once(blas, [] {
    if (auto openblas = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) openblas(1);
  });
}

}  // namespace
#else
struct SpdSolver::Impl {
  Eigen::SimplicialLDLT<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "eigen-simplicial-ldlt"; }
namespace {
void one_solver_thread_here() {}  // Eigen's factorisation is single-threaded
}  // namespace
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

void SpdSolver::analyze(const SparseMatrix& A) {
  one_solver_thread_here();
  impl_->solver.analyzePattern(A);
}

bool SpdSolver::factorize(const SparseMatrix& A) {
  one_solver_thread_here();
  impl_->solver.factorize(A);
  return impl_->solver.info() == Eigen::Success;
}

Eigen::MatrixXd SpdSolver::solve(const Eigen::MatrixXd& b) const { return impl_->solver.solve(b); }

}  // namespace facemorph
