// QIEM: the mirror-symmetric step systems, the flow with its adaptive step, the initial sphere map.
#include "codec/encoder/conformal/qiem.hpp"

#include "format/error.hpp"

#include "codec/encoder/conformal/lagged_cholesky.hpp"
#include "codec/encoder/conformal/moebius_centring.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace facemorph {
namespace {

// The QIEM system restricted to the mirror-symmetric maps it produces. On the double cover
// x and y are even (equal on both copies) and z is odd (opposite, 0 on the boundary), and
// A = I + δt(K - D) commutes with the mirror, so A φ = b splits exactly into the Galerkin systems
// Pᵀ A P x = Pᵀ b for the even prolongation P_e (disk vertices) and the odd one P_o (interior
// vertices). Two systems of the disk's size instead of one of twice it: cheaper to factor, and the
// symmetry (boundary exactly on the equator) holds by construction. Each system is solved by a
// LaggedCholesky: from one step to the next only δt and D change, so an earlier step's factor
// preconditions CG well, and most steps factor nothing.
class SymmetricSystems {
 public:
  SymmetricSystems(const SparseMatrix& K, const DoubleCover& cover) : cover_(cover), n_(cover.disk_vertices) {
    odd_index_.assign(static_cast<size_t>(n_), -1);
    for (int i = 0; i < n_; ++i) {
      if (!cover.on_boundary[static_cast<size_t>(i)]) odd_index_[static_cast<size_t>(i)] = odd_count_++;
    }
    even_mass_.resize(n_);
    odd_mass_ = Eigen::VectorXd::Constant(odd_count_, 2.0);
    for (int i = 0; i < n_; ++i) even_mass_[i] = cover.on_boundary[static_cast<size_t>(i)] ? 1.0 : 2.0;
    std::vector<Eigen::Triplet<double>> even, odd;
    for (int c = 0; c < K.outerSize(); ++c) {
      for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
        const int r = static_cast<int>(it.row());
        const int fr = fold(r), fc = fold(static_cast<int>(it.col()));
        even.emplace_back(fr, fc, it.value());
        const int orow = odd_index_[static_cast<size_t>(fr)], ocol = odd_index_[static_cast<size_t>(fc)];
        if (orow >= 0 && ocol >= 0) odd.emplace_back(orow, ocol, sign(r) * sign(static_cast<int>(it.col())) * it.value());
      }
    }
    K_even_.resize(n_, n_);
    K_even_.setFromTriplets(even.begin(), even.end());
    K_odd_.resize(odd_count_, odd_count_);
    K_odd_.setFromTriplets(odd.begin(), odd.end());
    A_even_ = K_even_;
    A_odd_ = K_odd_;
    even_solver_.analyze(A_even_);
    odd_solver_.analyze(A_odd_);
  }

  // One step: solves [I + δt(K - D)] φ⁺ = φ for symmetric φ. False when a system's factorisation
  // failed (it is not positive definite: the step is too long).
  bool step(const Eigen::MatrixXd& phi, const Eigen::VectorXd& D, double dt, Eigen::MatrixXd& next) {
    A_even_ = K_even_ * dt;
    for (int i = 0; i < n_; ++i) A_even_.coeffRef(i, i) += even_mass_[i] * (1.0 - dt * D[i]);
    A_odd_ = K_odd_ * dt;
    Eigen::VectorXd rhs_odd(odd_count_);
    for (int i = 0; i < n_; ++i) {
      const int o = odd_index_[static_cast<size_t>(i)];
      if (o < 0) continue;
      A_odd_.coeffRef(o, o) += odd_mass_[o] * (1.0 - dt * D[i]);
      rhs_odd[o] = odd_mass_[o] * phi(i, 2);
    }
    Eigen::MatrixXd rhs_even(n_, 2);
    for (int i = 0; i < n_; ++i) rhs_even.row(i) = even_mass_[i] * phi.row(i).head<2>();
    Eigen::MatrixXd xy, z;
    if (!even_solver_.solve(A_even_, rhs_even, xy) || !odd_solver_.solve(A_odd_, rhs_odd, z)) return false;
    next.resize(phi.rows(), 3);
    for (int i = 0; i < n_; ++i) {
      const int o = odd_index_[static_cast<size_t>(i)];
      next.row(i) << xy(i, 0), xy(i, 1), o >= 0 ? z(o, 0) : 0.0;
      const int mi = cover_.mirror[static_cast<size_t>(i)];
      if (mi != i) next.row(mi) << xy(i, 0), xy(i, 1), -next(i, 2);
    }
    return next.allFinite();
  }
  // Numeric factorisations so far, both systems together.
  int factorizations() const { return even_solver_.factorizations() + odd_solver_.factorizations(); }

 private:
  int fold(int v) const { return v < n_ ? v : cover_.mirror[static_cast<size_t>(v)]; }
  double sign(int v) const { return v < n_ ? 1.0 : -1.0; }

  const DoubleCover& cover_;
  int n_;
  int odd_count_ = 0;
  std::vector<int> odd_index_;
  Eigen::VectorXd even_mass_, odd_mass_;  // Pᵀ P: 2 for vertices with two copies, 1 on the boundary
  SparseMatrix K_even_, K_odd_, A_even_, A_odd_;
  LaggedCholesky even_solver_, odd_solver_;
};

}  // namespace

FlowResult spherical_flow(const SparseMatrix& K, const Eigen::VectorXd& areas, const DoubleCover& cover, Eigen::MatrixXd phi,
                          const ConformalOptions& options) {
  const Eigen::Index N = K.rows();
  auto energy_of = [&](const Eigen::MatrixXd& p) { return 0.5 * (p.transpose() * (K * p)).trace(); };
  auto project = [&](Eigen::MatrixXd& p) {
    for (Eigen::Index i = 0; i < N; ++i) p.row(i).normalize();
    centre_by_moebius(p, areas, cover);
  };
  project(phi);
  double energy = energy_of(phi);
  SymmetricSystems systems(K, cover);
  FlowResult result;
  // The fixed point K φ = D φ does not depend on δt, only the path does. 0.9 / max D keeps
  // I + δt(K - D) SPD, but on crowded faces max D is set by a few tiny triangles and that step is
  // far too short for the rest. So start at twice it and grow δt by 1.25 after every step that
  // lowered the energy at the first try (halve it when a try did not). A long step can make the
  // matrix indefinite; a failed factorisation, like a rise in energy, just halves the step.
  // Measured (spec/method.md §3.3): growth 1.25 of {1, 1.25, 1.5, 2, 4}, start 2x of {1, 2, 4, 8, 16}
  // took fewest factorisations on synthetic, Medusa and ICT frames.
  double growth = 2.0;
  for (int step = 0; step < options.max_iterations; ++step) {
    const Eigen::MatrixXd Kphi = K * phi;
    const Eigen::VectorXd D = (Kphi.array() * phi.array()).rowwise().sum();
    const double max_d = D.maxCoeff();
    if (!(max_d > 0) || !std::isfinite(max_d))
      throw Error(ErrorCode::kNumerical, "QIEM: degenerate map (max D = " + std::to_string(max_d) + ")");
    Eigen::MatrixXd next;
    double next_energy = energy;
    bool accepted = false, rejected = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      const double dt = growth * 0.9 / max_d;
      if (systems.step(phi, D, dt, next)) {
        project(next);
        next_energy = energy_of(next);
        accepted = next_energy <= energy * (1 + 1e-12);
      }
      if (!accepted) {
        growth = std::max(growth * 0.5, 1.0 / 64);
        rejected = true;
      }
    }
    if (!accepted) throw Error(ErrorCode::kNumerical, "QIEM: no step lowers the energy");
    growth = std::min(growth * (rejected ? 1.0 : 1.25), 1e6);
    phi = std::move(next);
    const double change = std::abs(energy - next_energy) / energy;
    energy = next_energy;
    result.iterations = step + 1;
    if (change < options.energy_tolerance) {
      result.factorizations = systems.factorizations();
      result.phi = std::move(phi);
      result.energy = energy;
      return result;
    }
  }
  throw Error(ErrorCode::kNotConverged, "QIEM: no convergence in " + std::to_string(options.max_iterations) + " steps");
}

Eigen::MatrixXd initial_sphere_map(const std::vector<Vec2>& w, const DoubleCover& cover) {
  Eigen::MatrixXd phi(cover.vertex_count(), 3);
  for (int i = 0; i < cover.disk_vertices; ++i) {
    const Vec2& p = w[static_cast<size_t>(i)];
    const double r2 = p.squaredNorm();
    phi.row(i) << 2 * p.x() / (1 + r2), 2 * p.y() / (1 + r2), (r2 - 1) / (1 + r2);
    const int mi = cover.mirror[static_cast<size_t>(i)];
    if (mi != i) phi.row(mi) << phi(i, 0), phi(i, 1), -phi(i, 2);
  }
  return phi;
}

}  // namespace facemorph
