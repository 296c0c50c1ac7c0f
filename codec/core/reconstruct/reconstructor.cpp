// Laplace-Beltrami reconstruction on G (paper Algorithm 1 with method-notes §8 corrections).
#include "codec/core/reconstruct/reconstructor.hpp"
#include "format/error.hpp"

#include "codec/core/reconstruct/anderson_mixer.hpp"
#include "codec/core/reconstruct/lattice_multigrid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace facemorph {

// What the iteration loop carries from one iteration to the next.
struct ReconstructSuspension::State {
  std::vector<Vec3> positions;  // the iterate, every node of G
  AndersonMixer anderson;       // moved out of the reconstructor, and back on resuming
  std::vector<Vec3> previous_n;
  int next_iteration = 1;
  int lowest_at = 0;
  double lowest_change = 0;
  double change = 0;
};

ReconstructSuspension::ReconstructSuspension() = default;
ReconstructSuspension::~ReconstructSuspension() = default;
ReconstructSuspension::ReconstructSuspension(ReconstructSuspension&&) noexcept = default;
ReconstructSuspension& ReconstructSuspension::operator=(ReconstructSuspension&&) noexcept = default;
void ReconstructSuspension::clear() { state_.reset(); }

struct Reconstructor::Impl {
  SparseMatrix K_II, K_IB;                      // interior-interior and interior-rim blocks of the stiffness matrix
  std::unique_ptr<LatticeMultigrid> multigrid;  // once per grid: K_II is SPD (Dirichlet on the rim)
  Eigen::VectorXd mass;                         // lumped mass of the interior nodes
  std::vector<Vec3> last;                       // the previous result...
  std::vector<Vec3> before;                     // ...and the one before: the warm start extrapolates from both
  // Work arrays of reconstruct(), kept between calls (sizes fixed by the grid).
  AndersonMixer anderson;
  std::vector<Vec3> boundary_rhs, constant_rhs, rhs, next, tu, tv, n, previous_n;
  std::vector<double> coefficient_n, coefficient_u, coefficient_v;
  std::vector<uint8_t> fixed;

  // Keeps `surface` as the last result, the last as the one before (no allocation once warm; a
  // failed copy leaves both as they were).
  void remember(const std::vector<Vec3>& surface) {
    before.assign(surface.begin(), surface.end());
    std::swap(before, last);
  }
};

Reconstructor::Reconstructor(int grid_n) : Reconstructor(shared_grid_geometry(grid_n)) {}

Reconstructor::Reconstructor(std::shared_ptr<const GridGeometry> geometry)
    : geometry_(geometry ? std::move(geometry) : throw Error(ErrorCode::kInvalidArgument, "reconstructor: no grid geometry")),
      impl_(std::make_unique<Impl>()) {
  const SparseMatrix& K = geometry_->stiffness();
  const int interior = geometry_->interior_count();
  const int rim = geometry_->grid().rim_count;
  // G's Cartesian triangles give their diagonals a cotangent weight of exactly zero in exact
  // arithmetic and ~1e-17 in floating point: a third of K's entries. Dropped, the matrix is the
  // 5-point stencil the spec says it is (rows of at most four neighbours for the multigrid's sweeps,
  // and red-black ordering decouples them).
  double largest = 0;
  for (int c = 0; c < K.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) largest = std::max(largest, std::abs(it.value()));
  }
  const double negligible = 1e-12 * largest;
  std::vector<Eigen::Triplet<double>> ii, ib;
  for (int c = 0; c < K.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
      const int r = static_cast<int>(it.row());
      if (r >= interior || std::abs(it.value()) <= negligible) continue;
      if (c < interior)
        ii.emplace_back(r, c, it.value());
      else
        ib.emplace_back(r, c - interior, it.value());
    }
  }
  impl_->K_II.resize(interior, interior);
  impl_->K_II.setFromTriplets(ii.begin(), ii.end());
  impl_->K_IB.resize(interior, rim);
  impl_->K_IB.setFromTriplets(ib.begin(), ib.end());
  impl_->mass = geometry_->mass().head(interior);
  const std::vector<std::array<int32_t, 2>> cells(geometry_->grid().cell.begin(), geometry_->grid().cell.begin() + interior);
  impl_->multigrid = std::make_unique<LatticeMultigrid>(impl_->K_II, cells);
}

Reconstructor::~Reconstructor() = default;

void Reconstructor::forget_warm_start() {
  impl_->last.clear();
  impl_->before.clear();
}

size_t Reconstructor::solver_bytes() const { return impl_->multigrid->bytes(); }

ReconstructResult Reconstructor::reconstruct(const GridFields& fields, const ReconstructOptions& options) {
  const GridGeometry& geometry = *geometry_;
  const DiskGrid& grid = geometry.grid();
  const auto interior = static_cast<size_t>(grid.interior_count);
  validate_fields(fields);
  if (fields.grid_n != grid.n) {
    throw Error(ErrorCode::kInvalidArgument, "fields were made for N = " + std::to_string(fields.grid_n) +
                                                 ", the reconstructor's grid has N = " + std::to_string(grid.n));
  }
  ReconstructResult result;
  result.positions.resize(grid.nodes.size());
  std::copy(fields.rim.begin(), fields.rim.end(), result.positions.begin() + static_cast<long>(interior));
  if (fields.representation == Representation::kXYZ) {
    std::copy(fields.positions.begin(), fields.positions.end(), result.positions.begin());
    result.converged = true;
    impl_->remember(result.positions);
    return result;
  }
  const bool tangential = fields.representation == Representation::kHLT;

  const auto n_int = static_cast<Eigen::Index>(interior);
  Vec3 lo = fields.rim[0], hi = lo;
  for (const Vec3& p : fields.rim) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double diameter = std::max((hi - lo).norm(), 1e-300);
  Impl& work = *impl_;
  std::vector<Vec3>& boundary_rhs = work.boundary_rhs;  // -K_IB S_rim
  boundary_rhs.assign(interior, Vec3::Zero());
  for (Eigen::Index k = 0; k < impl_->K_IB.outerSize(); ++k) {  // by rim node (column)
    for (SparseMatrix::InnerIterator it(impl_->K_IB, k); it; ++it)
      boundary_rhs[static_cast<size_t>(it.row())] -= it.value() * fields.rim[static_cast<size_t>(k)];
  }

  const LatticeMultigrid& multigrid = *impl_->multigrid;
  // The iterate lives in result.positions (interior nodes first, then the rim), as frames() reads it.
  std::vector<Vec3>& S = result.positions;
  // Going on from a stop: the iterate and the loop's state as they were (the right-hand side's
  // coefficients below are the same fields' again).
  std::unique_ptr<ReconstructSuspension::State> resumed;
  if (options.suspended != nullptr && options.suspended->held()) {
    resumed = std::move(options.suspended->state_);
    if (resumed->positions.size() != S.size()) throw Error(ErrorCode::kInternal, "reconstruction resumed on another grid");
    std::copy(resumed->positions.begin(), resumed->positions.begin() + static_cast<long>(interior), S.begin());
  } else if (options.start != nullptr) {
    if (options.start->size() != grid.nodes.size()) {
      throw Error(ErrorCode::kInvalidArgument, "reconstruction start has " + std::to_string(options.start->size()) +
                                                   " positions for a grid of " + std::to_string(grid.nodes.size()) + " nodes");
    }
    for (size_t v = 0; v < interior; ++v) {
      const Vec3& p = (*options.start)[v];
      if (!p.allFinite()) throw Error(ErrorCode::kInvalidArgument, "reconstruction start is not finite at node " + std::to_string(v));
      S[v] = p;
    }
  } else if (impl_->last.size() == grid.nodes.size()) {
    // A sequence: start from the last surface, extrapolated linearly through the one before it
    // (the prediction error is second order in the time step).
    const bool extrapolate = options.extrapolate_warm_start && impl_->before.size() == grid.nodes.size();
    for (size_t v = 0; v < interior; ++v) {
      const Vec3& last = impl_->last[v];
      S[v] = extrapolate ? Vec3(2 * last - impl_->before[v]) : last;
    }
  } else {
    // The harmonic surface spanning the rim, to well under the tolerance (from nothing: a few
    // cycles more than a step takes).
    std::vector<Vec3> harmonic(interior, Vec3::Zero());
    // (Only a start: falling short of that costs steps, never accuracy.)
    multigrid.solve(boundary_rhs.data(), harmonic.data(), std::min(1e-7, 0.01 * options.tolerance));
    std::copy(harmonic.begin(), harmonic.end(), S.begin());
  }

  // The right-hand side per node is rhs = −K_IB S_rim − M F(S) with F = 2Hλ² n (+ a t_u + b t_v):
  // the coefficients of n, t_u and t_v with the mass folded in, once. Fixed-frame nodes (the band,
  // crowded nodes) have their vectors in frames of the boundary curve, known for the whole solve:
  // their rhs is constant and their coefficients zero.
  std::vector<double>& coefficient_n = work.coefficient_n;
  std::vector<double>& coefficient_u = work.coefficient_u;
  std::vector<double>& coefficient_v = work.coefficient_v;
  std::vector<Vec3>& constant_rhs = work.constant_rhs;
  std::vector<uint8_t>& fixed = work.fixed;
  coefficient_n.resize(interior);
  coefficient_u.resize(tangential ? interior : 0);
  coefficient_v.resize(tangential ? interior : 0);
  constant_rhs.assign(boundary_rhs.begin(), boundary_rhs.end());
  fixed.assign(interior, 0);
  for (size_t v = 0; v < interior; ++v) {
    const double m = impl_->mass[static_cast<Eigen::Index>(v)];
    coefficient_n[v] = m * 2 * fields.mean_curvature[v] * std::exp(2 * fields.log_conformal_factor[v]);  // M 2Hλ²
    if (tangential) {
      coefficient_u[v] = m * fields.tangential_u[v];
      coefficient_v[v] = m * fields.tangential_v[v];
    }
  }
  if (tangential) {
    const auto frames = geometry.boundary_frames(fields.rim, fields.fixed_nodes);
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto v = static_cast<size_t>(fields.fixed_nodes[i]);
      const Vec3& c = fields.fixed_laplacian[i];
      constant_rhs[v] -= impl_->mass[static_cast<Eigen::Index>(v)] * (c.x() * frames[i][0] + c.y() * frames[i][1] + c.z() * frames[i][2]);
      fixed[v] = 1;
    }
  }
  std::vector<Vec3>&tu = work.tu, &tv = work.tv, &n = work.n, &previous_n = work.previous_n, &rhs = work.rhs, &next = work.next;
  rhs.resize(interior);
  next.resize(interior);
  previous_n.clear();
  AndersonMixer& anderson = work.anderson;
  auto flat = [&](std::vector<Vec3>& points) { return AndersonMixer::Vector(points.data()->data(), 3 * n_int); };
  const bool damped = options.damping < 1;
  double lowest_change = std::numeric_limits<double>::infinity();
  int lowest_at = 0;
  int first_iteration = 1;
  if (resumed) {
    std::swap(anderson, resumed->anderson);
    previous_n = std::move(resumed->previous_n);
    first_iteration = resumed->next_iteration;
    lowest_at = resumed->lowest_at;
    lowest_change = resumed->lowest_change;
    result.change = resumed->change;
    result.iterations = first_iteration - 1;
  } else {
    anderson.restart(options.anderson_depth, 3 * n_int);
  }
  // Stops before `iteration` where the meter cannot pay for it, keeping the loop's state.
  const auto stop = [&](int iteration) {
    if (options.suspended != nullptr) {
      auto state = resumed ? std::move(resumed) : std::make_unique<ReconstructSuspension::State>();
      state->positions = S;
      std::swap(state->anderson, anderson);
      state->previous_n = previous_n;
      state->next_iteration = iteration;
      state->lowest_at = lowest_at;
      state->lowest_change = lowest_change;
      state->change = result.change;
      options.suspended->state_ = std::move(state);
    }
    options.work->refuse("reconstruction iteration " + std::to_string(iteration) + " on " + std::to_string(interior) + " nodes");
  };
  for (int iteration = first_iteration; iteration <= options.max_iterations; ++iteration) {
    if (options.work != nullptr && !options.work->afford(interior * WorkMeter::kPerNodeIteration)) stop(iteration);
    if (damped) {
      geometry.frames(S, tu, tv, n);
      if (!previous_n.empty()) {
        for (size_t v = 0; v < interior; ++v) {
          n[v] = ((1 - options.damping) * previous_n[v] + options.damping * n[v]).normalized();
          tu[v] = (tu[v] - tu[v].dot(n[v]) * n[v]).normalized();
          tv[v] = n[v].cross(tu[v]);
        }
      }
      previous_n = n;
    }
    // K S = −M Δ_h S: K_II S_I = −M F − K_IB S_rim. The frames are computed where they are used
    // (undamped): three arrays a pass would write and the next read back.
    for (size_t v = 0; v < interior; ++v) {
      if (fixed[v]) {
        rhs[v] = constant_rhs[v];
        continue;
      }
      Vec3 fu, fv, fn;
      if (damped) {
        fu = tu[v], fv = tv[v], fn = n[v];
      } else {
        geometry.frame(v, S.data(), fu, fv, fn);
      }
      Vec3 mf = coefficient_n[v] * fn;
      if (tangential) mf += coefficient_u[v] * fu + coefficient_v[v] * fv;
      rhs[v] = constant_rhs[v] - mf;
    }
    // K_II S⁺ = rhs to within a tenth of the step: one V-cycle from S (see lattice_multigrid.hpp).
    // A second cycle per step took as many steps on real clips (Medusa: 3.27 against 3.24 a
    // frame), so one: the inexact solve only slows iterations that crawl anyway.
    multigrid.cycle(rhs.data(), S.data(), next.data());
    double change2 = 0, sum2 = 0;
    for (size_t v = 0; v < interior; ++v) {
      const double d2 = (next[v] - S[v]).squaredNorm();
      change2 = std::max(change2, d2);
      sum2 += d2;  // not finite when any node is not
    }
    if (!std::isfinite(sum2))
      throw Error(ErrorCode::kNumerical, "reconstruction produced a non-finite surface at iteration " + std::to_string(iteration));
    result.change = std::sqrt(change2) / diameter;
    anderson.step(flat(S), flat(next));
    std::copy(next.begin(), next.end(), S.begin());
    result.iterations = iteration;
    if (result.change < options.tolerance) {
      result.converged = true;
      break;
    }
    if (result.change < lowest_change) {
      lowest_change = result.change;
      lowest_at = iteration;
    } else if (options.stall_iterations > 0 && iteration - lowest_at >= options.stall_iterations) {
      break;  // stopped falling: it will not converge
    }
  }
  if (!result.converged && options.throw_on_failure) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "reconstruction did not converge in %d iterations (last change %.3g of the rim diameter, tolerance %.3g)",
                  result.iterations, result.change, options.tolerance);
    throw Error(ErrorCode::kNotConverged, text);  // the warm start stays as it was
  }
  impl_->remember(result.positions);
  return result;
}

}  // namespace facemorph
