// Laplace-Beltrami reconstruction on G (paper Algorithm 1 with method-notes §8 corrections).
#include "facemorph/error.hpp"
#include "facemorph/reconstruct.hpp"

#include "codec/reconstruct/triple_solver.hpp"

#include <cmath>
#include <cstdio>

namespace facemorph {

namespace {

// Anderson acceleration (Walker & Ni 2011, "type II") of the fixed-point iteration S -> G(S): the
// next iterate combines the last few G values so as to minimise the linear model of the residual
// G(S) - S. The plain iteration contracts by about 0.45 per step on faces; this one far faster.
// Safeguarded by a restart: when the residual |G(S) - S| grows, the history (a linear model of a
// map that is far from linear there) is dropped and the plain step taken. Unguarded, it wandered
// and never converged on smooth analytic bumps that the plain iteration solves in 10-40 steps
// (tests/decoder/reconstruct_test.cpp); guarded, real faces take the same steps as before.
class AndersonMixer {
 public:
  explicit AndersonMixer(int depth) : depth_(depth) {}

  // Returns the next iterate from the current one `x` and its image `g` (overwritten in place).
  void step(const Eigen::MatrixXd& x, Eigen::MatrixXd& g) {
    if (depth_ <= 0) return;
    f_ = g - x;
    const double residual = f_.norm();
    if (has_previous_ && residual > previous_residual_) {
      dF_.clear();
      dG_.clear();
      oldest_ = 0;
      has_previous_ = false;
    }
    if (has_previous_) {
      if (static_cast<int>(dF_.size()) < depth_) {
        dF_.emplace_back(f_ - previous_f_);
        dG_.emplace_back(g - previous_g_);
      } else {
        dF_[static_cast<size_t>(oldest_)] = f_ - previous_f_;
        dG_[static_cast<size_t>(oldest_)] = g - previous_g_;
        oldest_ = (oldest_ + 1) % depth_;
      }
    }
    previous_f_ = f_;
    previous_g_ = g;
    previous_residual_ = residual;
    has_previous_ = true;
    const auto m = static_cast<Eigen::Index>(dF_.size());
    if (m == 0) return;
    // Least squares min |f - ΔF γ| through the m x m normal equations (m is small).
    Eigen::MatrixXd A(m, m);
    Eigen::VectorXd b(m);
    for (Eigen::Index i = 0; i < m; ++i) {
      b[i] = dF_[static_cast<size_t>(i)].cwiseProduct(f_).sum();
      for (Eigen::Index j = 0; j <= i; ++j) A(i, j) = A(j, i) = dF_[static_cast<size_t>(i)].cwiseProduct(dF_[static_cast<size_t>(j)]).sum();
    }
    A.diagonal().array() += 1e-12 * A.diagonal().maxCoeff();
    const Eigen::VectorXd gamma = A.ldlt().solve(b);
    if (!gamma.allFinite()) return;
    for (Eigen::Index i = 0; i < m; ++i) g.noalias() -= gamma[i] * dG_[static_cast<size_t>(i)];
  }

 private:
  int depth_;
  bool has_previous_ = false;
  int oldest_ = 0;  // once the ring is full, the slot overwritten next
  double previous_residual_ = 0;
  Eigen::MatrixXd f_, previous_f_, previous_g_;
  std::vector<Eigen::MatrixXd> dF_, dG_;
};

}  // namespace

struct Reconstructor::Impl {
  SparseMatrix K_II, K_IB;  // interior-interior and interior-rim blocks of the stiffness matrix
  std::unique_ptr<TripleSolver> solver;
  Eigen::VectorXd mass;     // lumped mass of the interior nodes
  std::vector<Vec3> last;      // the previous result...
  std::vector<Vec3> before;    // ...and the one before: the warm start extrapolates from both
};

Reconstructor::Reconstructor(int grid_n)
    : geometry_(std::make_unique<GridGeometry>(make_disk_grid(grid_n))), impl_(std::make_unique<Impl>()) {
  const SparseMatrix& K = geometry_->stiffness();
  const int interior = geometry_->interior_count();
  const int rim = geometry_->grid().rim_count;
  std::vector<Eigen::Triplet<double>> ii, ib;
  for (int c = 0; c < K.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (r >= interior) continue;
      if (c < interior) ii.emplace_back(r, c, it.value());
      else ib.emplace_back(r, c - interior, it.value());
    }
  }
  impl_->K_II.resize(interior, interior);
  impl_->K_II.setFromTriplets(ii.begin(), ii.end());
  impl_->K_IB.resize(interior, rim);
  impl_->K_IB.setFromTriplets(ib.begin(), ib.end());
  impl_->mass = geometry_->mass().head(interior);
  impl_->solver = std::make_unique<TripleSolver>(impl_->K_II);  // once per grid: SPD (Dirichlet on the rim)
}

Reconstructor::~Reconstructor() = default;

void Reconstructor::forget_warm_start() {
  impl_->last.clear();
  impl_->before.clear();
}

size_t Reconstructor::factorization_bytes() const { return impl_->solver->bytes(); }

ReconstructResult Reconstructor::reconstruct(const GridFields& fields, const ReconstructOptions& options) {
  const GridGeometry& geometry = *geometry_;
  const DiskGrid& grid = geometry.grid();
  const auto interior = static_cast<size_t>(grid.interior_count);
  validate_fields(fields);
  if (fields.grid_n != grid.n) {
    throw Error(ErrorCode::kInvalidArgument, "fields were made for N = " + std::to_string(fields.grid_n) + ", the reconstructor's grid has N = " +
                                                 std::to_string(grid.n));
  }
  ReconstructResult result;
  result.positions.resize(grid.nodes.size());
  std::copy(fields.rim.begin(), fields.rim.end(), result.positions.begin() + static_cast<long>(interior));
  if (fields.representation == Representation::kXYZ) {
    std::copy(fields.positions.begin(), fields.positions.end(), result.positions.begin());
    result.converged = true;
    impl_->before = std::move(impl_->last);
    impl_->last = result.positions;
    return result;
  }
  const bool tangential = fields.representation == Representation::kHLT;

  const auto n_int = static_cast<Eigen::Index>(interior);
  Eigen::MatrixXd rim(grid.rim_count, 3);
  Vec3 lo = fields.rim[0], hi = lo;
  for (int k = 0; k < grid.rim_count; ++k) {
    rim.row(k) = fields.rim[static_cast<size_t>(k)].transpose();
    lo = lo.cwiseMin(fields.rim[static_cast<size_t>(k)]);
    hi = hi.cwiseMax(fields.rim[static_cast<size_t>(k)]);
  }
  const double diameter = std::max((hi - lo).norm(), 1e-300);
  const Eigen::MatrixXd boundary_rhs = -(impl_->K_IB * rim);
  std::vector<double> normal_scale(interior);  // 2 H λ²
  for (size_t v = 0; v < interior; ++v) normal_scale[v] = 2 * fields.mean_curvature[v] * std::exp(2 * fields.log_conformal_factor[v]);

  // The single-precision factor solves to ~4e-7; tolerances below 1e-6 get a refinement step.
  const bool refine = options.tolerance < 1e-6;
  auto solve = [&](const Eigen::MatrixXd& b) { return refine ? impl_->solver->solve_refined(b) : impl_->solver->solve(b); };
  Eigen::MatrixXd S(n_int, 3);
  if (options.start != nullptr) {
    if (options.start->size() != grid.nodes.size()) {
      throw Error(ErrorCode::kInvalidArgument, "reconstruction start has " + std::to_string(options.start->size()) + " positions for a grid of " +
                                                   std::to_string(grid.nodes.size()) + " nodes");
    }
    for (Eigen::Index v = 0; v < n_int; ++v) {
      const Vec3& p = (*options.start)[static_cast<size_t>(v)];
      if (!p.allFinite()) throw Error(ErrorCode::kInvalidArgument, "reconstruction start is not finite at node " + std::to_string(v));
      S.row(v) = p.transpose();
    }
  } else if (impl_->last.size() == grid.nodes.size()) {
    // A sequence: start from the last surface, extrapolated linearly through the one before it
    // (the prediction error is second order in the time step).
    const bool extrapolate = options.extrapolate_warm_start && impl_->before.size() == grid.nodes.size();
    for (Eigen::Index v = 0; v < n_int; ++v) {
      const Vec3& last = impl_->last[static_cast<size_t>(v)];
      S.row(v) = (extrapolate ? Vec3(2 * last - impl_->before[static_cast<size_t>(v)]) : last).transpose();
    }
  } else {
    S = solve(boundary_rhs);  // the harmonic surface spanning the rim
  }
  auto store = [&](const Eigen::MatrixXd& s) {
    for (Eigen::Index v = 0; v < n_int; ++v) result.positions[static_cast<size_t>(v)] = s.row(v).transpose();
  };
  store(S);

  // Fixed-frame nodes (the band, crowded nodes) have their vectors in frames of the boundary
  // curve: known for the whole solve.
  std::vector<int32_t> fixed_index(tangential ? interior : 0, -1);
  std::vector<Vec3> fixed_vectors;
  if (tangential) {
    const auto frames = geometry.boundary_frames(fields.rim, fields.fixed_nodes);
    fixed_vectors.resize(frames.size());
    for (size_t i = 0; i < frames.size(); ++i) {
      const Vec3& c = fields.fixed_laplacian[i];
      fixed_vectors[i] = c.x() * frames[i][0] + c.y() * frames[i][1] + c.z() * frames[i][2];
      fixed_index[static_cast<size_t>(fields.fixed_nodes[i])] = static_cast<int32_t>(i);
    }
  }
  std::vector<Vec3> tu, tv, n, previous_n;
  Eigen::MatrixXd rhs(n_int, 3);
  AndersonMixer anderson(options.anderson_depth);
  for (int iteration = 1; iteration <= options.max_iterations; ++iteration) {
    geometry.frames(result.positions, tu, tv, n);
    if (options.damping < 1 && !previous_n.empty()) {
      for (size_t v = 0; v < interior; ++v) {
        n[v] = ((1 - options.damping) * previous_n[v] + options.damping * n[v]).normalized();
        tu[v] = (tu[v] - tu[v].dot(n[v]) * n[v]).normalized();
        tv[v] = n[v].cross(tu[v]);
      }
    }
    previous_n = n;
    for (size_t v = 0; v < interior; ++v) {
      Vec3 F;
      if (tangential && fixed_index[v] >= 0) {
        F = fixed_vectors[static_cast<size_t>(fixed_index[v])];
      } else {
        F = normal_scale[v] * n[v];
        if (tangential) F += fields.tangential_u[v] * tu[v] + fields.tangential_v[v] * tv[v];
      }
      // K S = -M Δ_h S: K_II S_I = -M F - K_IB S_rim.
      rhs.row(static_cast<Eigen::Index>(v)) = boundary_rhs.row(static_cast<Eigen::Index>(v)) - impl_->mass[static_cast<Eigen::Index>(v)] * F.transpose();
    }
    Eigen::MatrixXd next = solve(rhs);
    if (!next.allFinite()) throw Error(ErrorCode::kNumerical, "reconstruction produced a non-finite surface at iteration " + std::to_string(iteration));
    double change2 = 0;
    for (Eigen::Index v = 0; v < n_int; ++v) change2 = std::max(change2, (next.row(v) - S.row(v)).squaredNorm());
    result.change = std::sqrt(change2) / diameter;
    anderson.step(S, next);
    S.swap(next);
    store(S);
    result.iterations = iteration;
    if (result.change < options.tolerance) {
      result.converged = true;
      break;
    }
  }
  impl_->before = std::move(impl_->last);
  impl_->last = result.positions;
  if (!result.converged && options.throw_on_failure) {
    char text[160];
    std::snprintf(text, sizeof text, "reconstruction did not converge in %d iterations (last change %.3g of the rim diameter, tolerance %.3g)",
                  result.iterations, result.change, options.tolerance);
    throw Error(ErrorCode::kNotConverged, text);
  }
  return result;
}

}  // namespace facemorph
