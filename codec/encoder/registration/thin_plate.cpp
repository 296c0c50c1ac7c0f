// The GMF's displacement fields (method-notes §5): the standard thin-plate spline with an affine
// part, and the paper's n×n grid of r² log r centres fitted as a displacement.
#include "codec/encoder/registration/registration.hpp"

#include "format/error.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <string>

namespace facemorph {
namespace {

// G(r) = r² log r = ½ r² log r², and ∇ₓG(|x - c|) = (log r² + 1)(x - c). Both tend to 0 at r = 0,
// where the formulas give 0·(-inf) = NaN: guard (notes §5, point 4).
double kernel(double r2) { return r2 < 1e-300 ? 0.0 : 0.5 * r2 * std::log(r2); }

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
  Vec2 d = offset + linear * x;
  for (size_t i = 0; i < centres.size(); ++i) {
    d += kernel((x - centres[i]).squaredNorm()) * weights.row(static_cast<Eigen::Index>(i)).transpose();
  }
  return d;
}

Vec2 ThinPlateDisplacement::value_and_gradient(const Vec2& x, Eigen::Matrix2d& gradient) const {
  Vec2 d = offset + linear * x;
  gradient = linear;
  for (size_t i = 0; i < centres.size(); ++i) {
    const Vec2 diff = x - centres[i];
    const double r2 = diff.squaredNorm();
    if (r2 < 1e-300) continue;  // G and its gradient vanish at the centre
    // One logarithm serves both: G = ½ r² log r², ∇G = (log r² + 1)(x - c). (Eigen's vectorised
    // log is slower than std::log without AVX: measured 10.8 against 7.1 ns.)
    const double log_r2 = std::log(r2);
    const Vec2 w = weights.row(static_cast<Eigen::Index>(i)).transpose();
    d += (0.5 * r2 * log_r2) * w;
    gradient += ((log_r2 + 1) * w) * diff.transpose();
  }
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
    for (Eigen::Index j = 0; j < i; ++j) A(i, j) = A(j, i) = kernel((y - centres[static_cast<size_t>(j)]).squaredNorm());
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
      S(i, j) = s * kernel((points[static_cast<size_t>(i)] - out.centres[static_cast<size_t>(j)]).squaredNorm());
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
