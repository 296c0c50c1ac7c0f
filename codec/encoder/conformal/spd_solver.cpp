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
  Eigen::CholmodDecomposition<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "cholmod"; }

namespace {

// CHOLMOD's simplicial LLᵀ below this many unknowns, its supernodal LLᵀ from it. The supernodal
// factorisation is the faster one on large systems (dense BLAS on its supernodes), but CHOLMOD 3
// opens OpenMP regions per supernode, and each, even as a team of one (below), ends on a futex
// wake: a system call per region, which this machine's virtualised kernel makes dear (perf on
// ICT 9.4k's encode: 8% of the samples in libgomp and 13% in the kernel). The map's whole time,
// one thread (`fmbench conformal synth:V --method qiem`), simplicial against supernodal: 5k
// vertices 0.11 against 0.19 s, 10k 0.29 / 0.37, 20k 0.71 / 0.84-0.88, 30k 1.21 / 1.27,
// 40k 1.48 / 1.66, 50k 2.39 / 2.24-2.29, 60k 3.62 / 2.97, 100k 6.8 / 4.8-5.2 s. The QIEM
// systems have one unknown a vertex (spec/method.md §3.3).
constexpr Eigen::Index kSimplicialBelowUnknowns = 45000;

// One solver thread in each thread that factors. The encoder gives its cores to frames (one frame
// per thread); CHOLMOD's supernodal factorisation opens an OpenMP team per supernode (225k teams for
// one 20k-vertex frame), and the BLAS under it has its own thread pool, so two frame threads ran
// four to six threads on two cores, spinning. Measured (fmbench conformal --sweep on 6 frames of
// 20k vertices, --threads 2): CPU time 5.2 → 3.2 s, wall 9.2 → 4.8 s. Looked up at run time: the
// BLAS may not be OpenBLAS, and libgomp is there only as CHOLMOD's dependency.
void one_blas_thread() {
  static std::once_flag blas;
  std::call_once(blas, [] {
    using SetThreads = void (*)(int);
    if (auto openblas = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) openblas(1);
  });
}

// OpenMP's teams of one, for one CHOLMOD call, in this thread only. omp_set_num_threads(1) is not
// enough: CHOLMOD 3 (SuiteSparse 5) asks for its supernodal loops' teams with num_threads(4), which
// overrides it, so every frame's ~225k teams woke three workers on futexes (17% of perf's samples of
// the sample's encode at --threads 1; its system time 4.8-6.0 -> 3.6-3.7 s with this, spec/method.md
// §3.3, which does not account for the quiet machine's 70.5 s). max-active-levels 0 makes every
// region a team of one whatever it asks; it is an ICV of the calling thread, set back afterwards so
// that a program that calls the encoder keeps its own OpenMP settings.
class OpenMpTeamsOfOne {
 public:
  OpenMpTeamsOfOne() {
    one_blas_thread();
    if (omp().get && omp().set) {
      saved_ = omp().get();
      omp().set(0);
    }
  }
  ~OpenMpTeamsOfOne() {
    if (saved_ >= 0) omp().set(saved_);
  }
  OpenMpTeamsOfOne(const OpenMpTeamsOfOne&) = delete;
  OpenMpTeamsOfOne& operator=(const OpenMpTeamsOfOne&) = delete;

 private:
  struct Functions {
    int (*get)() = nullptr;
    void (*set)(int) = nullptr;
  };
  static const Functions& omp() {
    static const Functions functions{
        reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels")),
        reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"))};
    return functions;
  }
  int saved_ = -1;
};

}  // namespace
#else
struct SpdSolver::Impl {
  Eigen::SimplicialLDLT<SparseMatrix> solver;
};
const char* SpdSolver::backend() { return "eigen-simplicial-ldlt"; }
namespace {
struct OpenMpTeamsOfOne {
  OpenMpTeamsOfOne() {}  // Eigen's factorisation is single-threaded
};
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
  const OpenMpTeamsOfOne teams;
#ifdef FACEMORPH_HAVE_CHOLMOD
  impl_->solver.setMode(A.rows() < kSimplicialBelowUnknowns ? Eigen::CholmodSimplicialLLt : Eigen::CholmodSupernodalLLt);
#endif
  impl_->solver.analyzePattern(A);
}

bool SpdSolver::factorize(const SparseMatrix& A) {
  const OpenMpTeamsOfOne teams;
  impl_->solver.factorize(A);
  return impl_->solver.info() == Eigen::Success;
}

Eigen::MatrixXd SpdSolver::solve(const Eigen::MatrixXd& b) const {
  const OpenMpTeamsOfOne teams;
  return impl_->solver.solve(b);
}

}  // namespace facemorph
