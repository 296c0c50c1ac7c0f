// The GMF's displacement fields (method-notes §5): the standard thin-plate spline with an affine
// part, and the paper's n×n grid of r² log r centres fitted as a displacement.
#include "codec/encoder/registration/registration.hpp"

#include "codec/encoder/registration/thin_plate_kernel.hpp"
#include "format/error.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <string>

namespace facemorph {
namespace {

// G(r) = r² log r = ½ r² log r² is thin_plate_kernel (thin_plate_kernel.hpp), and ∇ₓG(|x - c|) =
// (log r² + 1)(x - c). Both tend to 0 at r = 0, where the formulas give 0·(-inf) = NaN: masked
// there (zero_at_centre; notes §5, point 4).
//
// d and ∇d are evaluated a block of points at a time, centre by centre over the points, which the
// compiler vectorises: with AVX2 where the CPU has it, chosen at load time (target_clones), four
// points a step. Each point's sums still run over the centres in order, and neither clone contracts
// to FMA, so every point gets the same bits in any block, alone or not, on any CPU. One point
// (operator(), value_and_gradient) is a block of one. `fmbench kernels` times them against the
// kernel as it was (std::log, one point at a time): the blocks 0.33-0.43x its time here.

// d(x_p) into (dx, dy).
__attribute__((target_clones("avx2", "default"))) void thin_plate_values(const ThinPlateDisplacement& d, const double* __restrict x,
                                                                         const double* __restrict y, double* __restrict dx,
                                                                         double* __restrict dy, size_t n) {
  for (size_t p = 0; p < n; ++p) {
    dx[p] = d.offset.x() + (d.linear(0, 0) * x[p] + d.linear(0, 1) * y[p]);
    dy[p] = d.offset.y() + (d.linear(1, 0) * x[p] + d.linear(1, 1) * y[p]);
  }
  for (size_t i = 0; i < d.centres.size(); ++i) {
    const double cx = d.centres[i].x(), cy = d.centres[i].y();
    const double wx = d.weights(static_cast<Eigen::Index>(i), 0), wy = d.weights(static_cast<Eigen::Index>(i), 1);
    for (size_t p = 0; p < n; ++p) {
      const double ex = x[p] - cx, ey = y[p] - cy;
      const double g = thin_plate_kernel(ex * ex + ey * ey);
      dx[p] += g * wx;
      dy[p] += g * wy;
    }
  }
}

// ∇d(x_p) row by row: gradient[2k + l][p] = ∂d_k/∂x_l.
struct GradientBlock {
  double* entry[4];
};

// d(x_p) into (dx, dy), as thin_plate_values gives it, and ∇d(x_p) into `gradient`. Every array
// __restrict: with eight of them the compiler would need more overlap checks than it makes before
// it vectorises, and without them stays scalar (measured: the bijection check 25% of Medusa's CPU
// scalar, 7% vectorised).
__attribute__((target_clones("avx2", "default"))) void thin_plate_values_and_gradients(const ThinPlateDisplacement& d,
                                                                                       const double* __restrict x,
                                                                                       const double* __restrict y, double* __restrict dx,
                                                                                       double* __restrict dy, GradientBlock gradient,
                                                                                       size_t n) {
  double* __restrict const g00 = gradient.entry[0];
  double* __restrict const g01 = gradient.entry[1];
  double* __restrict const g10 = gradient.entry[2];
  double* __restrict const g11 = gradient.entry[3];
  for (size_t p = 0; p < n; ++p) {
    dx[p] = d.offset.x() + (d.linear(0, 0) * x[p] + d.linear(0, 1) * y[p]);
    dy[p] = d.offset.y() + (d.linear(1, 0) * x[p] + d.linear(1, 1) * y[p]);
    g00[p] = d.linear(0, 0);
    g01[p] = d.linear(0, 1);
    g10[p] = d.linear(1, 0);
    g11[p] = d.linear(1, 1);
  }
  for (size_t i = 0; i < d.centres.size(); ++i) {
    const double cx = d.centres[i].x(), cy = d.centres[i].y();
    const double wx = d.weights(static_cast<Eigen::Index>(i), 0), wy = d.weights(static_cast<Eigen::Index>(i), 1);
    for (size_t p = 0; p < n; ++p) {
      const double ex = x[p] - cx, ey = y[p] - cy;
      const double r2 = ex * ex + ey * ey;
      // One logarithm serves both: G = ½ r² log r², ∇G = (log r² + 1)(x - c).
      const double log_r2 = thin_plate_log(r2);
      const double g = zero_at_centre(0.5 * r2 * log_r2, r2);
      const double slope = zero_at_centre(log_r2 + 1, r2);
      dx[p] += g * wx;
      dy[p] += g * wy;
      const double ax = slope * wx, ay = slope * wy;
      g00[p] += ax * ex;
      g01[p] += ax * ey;
      g10[p] += ay * ex;
      g11[p] += ay * ey;
    }
  }
}

constexpr size_t kThinPlateBlock = 256;  // a block's displacements and gradients stay in L1

void check_points(const std::vector<Vec2>& points, const std::vector<Vec2>& displacements, const char* what) {
  if (points.size() != displacements.size()) {
    throw Error(ErrorCode::kInvalidArgument, std::string(what) + ": " + std::to_string(points.size()) + " points but " +
                                                 std::to_string(displacements.size()) + " displacements");
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite() || !displacements[i].allFinite()) {
      throw Error(ErrorCode::kInvalidArgument, std::string(what) + ": point " + std::to_string(i) + " is not finite");
    }
  }
}

}  // namespace

Vec2 ThinPlateDisplacement::operator()(const Vec2& x) const {
  Vec2 d;
  thin_plate_values(*this, &x.x(), &x.y(), &d.x(), &d.y(), 1);
  return d;
}

void ThinPlateDisplacement::displace(std::span<double> x, std::span<double> y) const {
  if (x.size() != y.size()) throw Error(ErrorCode::kInternal, "thin-plate displacement: unequal coordinate blocks");
  double dx[kThinPlateBlock], dy[kThinPlateBlock];
  for (size_t first = 0; first < x.size(); first += kThinPlateBlock) {
    const size_t n = std::min(kThinPlateBlock, x.size() - first);
    thin_plate_values(*this, x.data() + first, y.data() + first, dx, dy, n);
    for (size_t p = 0; p < n; ++p) {
      x[first + p] += dx[p];
      y[first + p] += dy[p];
    }
  }
}

void ThinPlateDisplacement::displace_with_jacobians(std::span<double> x, std::span<double> y, std::span<Eigen::Matrix2d> jacobians) const {
  if (x.size() != y.size() || x.size() != jacobians.size()) {
    throw Error(ErrorCode::kInternal, "thin-plate displacement: unequal coordinate and Jacobian blocks");
  }
  double dx[kThinPlateBlock], dy[kThinPlateBlock], g[4][kThinPlateBlock];
  for (size_t first = 0; first < x.size(); first += kThinPlateBlock) {
    const size_t n = std::min(kThinPlateBlock, x.size() - first);
    thin_plate_values_and_gradients(*this, x.data() + first, y.data() + first, dx, dy, {g[0], g[1], g[2], g[3]}, n);
    for (size_t p = 0; p < n; ++p) {
      // The chain rule through the step, D[(id + d) ∘ h] = (I + ∇d(h)) Dh, entry by entry.
      Eigen::Matrix2d& J = jacobians[first + p];
      const double a00 = 1 + g[0][p], a01 = g[1][p], a10 = g[2][p], a11 = 1 + g[3][p];
      J = (Eigen::Matrix2d() << a00 * J(0, 0) + a01 * J(1, 0), a00 * J(0, 1) + a01 * J(1, 1),  //
           a10 * J(0, 0) + a11 * J(1, 0), a10 * J(0, 1) + a11 * J(1, 1))
              .finished();
      x[first + p] += dx[p];
      y[first + p] += dy[p];
    }
  }
}

Vec2 ThinPlateDisplacement::value_and_gradient(const Vec2& x, Eigen::Matrix2d& gradient) const {
  Vec2 d;
  double g[4];
  thin_plate_values_and_gradients(*this, &x.x(), &x.y(), &d.x(), &d.y(), {&g[0], &g[1], &g[2], &g[3]}, 1);
  gradient << g[0], g[1], g[2], g[3];
  return d;
}

Eigen::Matrix2d ThinPlateDisplacement::gradient(const Vec2& x) const {
  Eigen::Matrix2d g;
  value_and_gradient(x, g);
  return g;
}

ThinPlateDisplacement fit_thin_plate(const std::vector<Vec2>& centres, const std::vector<Vec2>& displacements,
                                     const std::vector<double>& smoothing) {
  check_points(centres, displacements, "thin-plate spline");
  const auto n = static_cast<Eigen::Index>(centres.size());
  // The affine part takes three of the degrees of freedom: fewer centres cannot carry it.
  if (n < 3) throw Error(ErrorCode::kInvalidArgument, "thin-plate spline: needs at least 3 centres, got " + std::to_string(n));
  if (!smoothing.empty() && smoothing.size() != centres.size()) {
    throw Error(ErrorCode::kInvalidArgument,
                "thin-plate spline: " + std::to_string(smoothing.size()) + " smoothing values for " + std::to_string(n) + " centres");
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n + 3, n + 3);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n + 3, 2);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vec2& y = centres[static_cast<size_t>(i)];
    for (Eigen::Index j = 0; j < i; ++j) A(i, j) = A(j, i) = thin_plate_kernel((y - centres[static_cast<size_t>(j)]).squaredNorm());
    if (!smoothing.empty()) {
      const double s = smoothing[static_cast<size_t>(i)];
      if (!std::isfinite(s) || s < 0) throw Error(ErrorCode::kInvalidArgument, "thin-plate spline: smoothing must be finite and >= 0");
      A(i, i) = s;
    }
    A(i, n) = A(n, i) = 1;
    A(i, n + 1) = A(n + 1, i) = y.x();
    A(i, n + 2) = A(n + 2, i) = y.y();
    b.row(i) = displacements[static_cast<size_t>(i)].transpose();
  }
  // Symmetric but indefinite (the side conditions' zero block): LU with partial pivoting, and its
  // condition estimate tells a singular system (collinear or coincident centres) from a stiff one.
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  const double rcond = lu.rcond();
  const Eigen::MatrixXd x = lu.solve(b);
  if (!(rcond > 1e-14) || !x.allFinite()) {
    throw Error(ErrorCode::kNumerical, "thin-plate spline: singular system (reciprocal condition " + std::to_string(rcond) +
                                           "; collinear or coincident centres?)");
  }
  ThinPlateDisplacement out;
  out.centres = centres;
  out.weights = x.topRows(n);
  out.offset = x.row(n).transpose();
  out.linear.col(0) = x.row(n + 1).transpose();
  out.linear.col(1) = x.row(n + 2).transpose();
  return out;
}

ThinPlateDisplacement fit_paper_grid(const std::vector<Vec2>& points, const std::vector<Vec2>& displacements,
                                     const std::vector<double>& weights, int n, double epsilon_scale) {
  check_points(points, displacements, "paper grid GMF");
  if (n < 2 || n > 256) throw Error(ErrorCode::kInvalidArgument, "paper grid GMF: n must be in [2, 256], got " + std::to_string(n));
  if (!std::isfinite(epsilon_scale) || epsilon_scale < 0)
    throw Error(ErrorCode::kInvalidArgument, "paper grid GMF: epsilon must be finite and >= 0");
  if (!weights.empty() && weights.size() != points.size()) {
    throw Error(ErrorCode::kInvalidArgument,
                "paper grid GMF: " + std::to_string(weights.size()) + " weights for " + std::to_string(points.size()) + " points");
  }
  ThinPlateDisplacement out;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) out.centres.emplace_back(-1 + 2.0 * i / (n - 1), -1 + 2.0 * j / (n - 1));
  }
  const auto rows = static_cast<Eigen::Index>(points.size()), columns = static_cast<Eigen::Index>(n) * n;
  Eigen::MatrixXd S(rows, columns), d(rows, 2);
  for (Eigen::Index i = 0; i < rows; ++i) {
    const double w = weights.empty() ? 1.0 : weights[static_cast<size_t>(i)];
    if (!std::isfinite(w) || w < 0) throw Error(ErrorCode::kInvalidArgument, "paper grid GMF: weights must be finite and >= 0");
    // Row weights sqrt(ω) make the least squares the paper's weighted E_D.
    const double s = std::sqrt(w);
    for (Eigen::Index j = 0; j < columns; ++j)
      S(i, j) = s * thin_plate_kernel((points[static_cast<size_t>(i)] - out.centres[static_cast<size_t>(j)]).squaredNorm());
    d.row(i) = s * displacements[static_cast<size_t>(i)].transpose();
  }
  if (epsilon_scale == 0 && columns <= rows) {
    out.weights = S.colPivHouseholderQr().solve(d);
  } else {
    // Without an identity term Tikhonov would pull the map to 0 away from the data; as a
    // displacement it only pulls it to the Möbius map (notes §5, point 1). ε relative to the mean
    // diagonal of SᵀS so it does not depend on the scale of G (point 5).
    const Eigen::MatrixXd StS = S.transpose() * S;
    const double epsilon = (epsilon_scale > 0 ? epsilon_scale : 1e-6) * StS.trace() / (static_cast<double>(n) * n);
    out.weights = (StS + epsilon * Eigen::MatrixXd::Identity(columns, columns)).ldlt().solve(S.transpose() * d);
  }
  if (!out.weights.allFinite()) throw Error(ErrorCode::kNumerical, "paper grid GMF: the least-squares solve produced NaN");
  return out;
}

}  // namespace facemorph
