// The optimal Möbius transform (method-notes §4): Levenberg-Marquardt on (Re a, Im a, θ) from two
// starts, the best rotation and an algebraic fit.
#include "codec/encoder/registration/registration_internal.hpp"

#include "format/error.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <optional>

namespace facemorph {
namespace {

double moebius_energy(const CheckedLandmarks& l, const DiskMoebius& m) {
  double e = 0;
  for (size_t i = 0; i < l.p.size(); ++i) e += l.w[i] * std::norm(m(l.p[i]) - l.q[i]);
  return e;
}

// a = 0, θ = arg Σ ω q p̄: the rotation minimising E_D among rotations.
DiskMoebius rotation_start(const CheckedLandmarks& l) {
  Complex sum = 0;
  for (size_t i = 0; i < l.p.size(); ++i) sum += l.w[i] * l.q[i] * std::conj(l.p[i]);
  return {0.0, std::abs(sum) > 0 ? std::arg(sum) : 0.0};
}

// f = (αz + β)/(β̄z + ᾱ) makes q (β̄p + ᾱ) - αp - β = 0 linear in (Re α, Im α, Re β, Im β): its
// least-squares solution of unit norm is the smallest right singular vector. Exact landmarks give
// the exact map; noisy ones a start close to the optimum. Empty when it leaves the disk group.
std::optional<DiskMoebius> algebraic_start(const CheckedLandmarks& l) {
  const size_t n = l.p.size();
  Eigen::MatrixXd M(2 * n, 4);
  for (size_t i = 0; i < n; ++i) {
    const Complex p = l.p[i], q = l.q[i], I(0, 1);
    const double s = std::sqrt(l.w[i]);
    const Complex column[4] = {q - p, -I * (q + p), q * p - 1.0, -I * (q * p + 1.0)};
    for (int c = 0; c < 4; ++c) {
      M(static_cast<Eigen::Index>(2 * i), c) = s * column[c].real();
      M(static_cast<Eigen::Index>(2 * i + 1), c) = s * column[c].imag();
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(M, Eigen::ComputeThinV);
  const Eigen::Vector4d v = svd.matrixV().col(3);
  const Complex alpha(v[0], v[1]), beta(v[2], v[3]);
  if (!(std::abs(alpha) > 0)) return std::nullopt;
  const Complex a = -beta / alpha;
  if (!(std::abs(a) < 1 - 1e-9)) return std::nullopt;
  return DiskMoebius{a, 2 * std::arg(alpha)};
}

MoebiusFit levenberg_marquardt(const CheckedLandmarks& l, DiskMoebius m, int max_iterations, MoebiusStart start) {
  const size_t n = l.p.size();
  Eigen::MatrixXd J(2 * n, 3);
  Eigen::VectorXd r(2 * n);
  // Residuals sqrt(ω)(f(p) - q) as (re, im) rows and their analytic Jacobian (notes §4, checked
  // against finite differences there).
  auto linearise = [&](const DiskMoebius& f) {
    const Complex rotation = std::polar(1.0, f.theta), I(0, 1);
    double e = 0;
    for (size_t i = 0; i < n; ++i) {
      const Complex z = l.p[i], den = 1.0 - std::conj(f.a) * z, value = rotation * (z - f.a) / den;
      const double s = std::sqrt(l.w[i]);
      const Complex res = s * (value - l.q[i]);
      const Complex d_ax = s * rotation * (-1.0 / den + z * (z - f.a) / (den * den));
      const Complex d_ay = s * rotation * (-I / den - I * z * (z - f.a) / (den * den));
      const Complex d_theta = s * I * value;
      const auto row = static_cast<Eigen::Index>(2 * i);
      r[row] = res.real();
      r[row + 1] = res.imag();
      J.row(row) << d_ax.real(), d_ay.real(), d_theta.real();
      J.row(row + 1) << d_ax.imag(), d_ay.imag(), d_theta.imag();
      e += std::norm(res);
    }
    return e;
  };
  double energy = linearise(m);
  double damping = -1;
  int iterations = 0;
  while (iterations < max_iterations && energy > 0) {
    ++iterations;
    const Eigen::Matrix3d JtJ = J.transpose() * J;
    const Eigen::Vector3d gradient = J.transpose() * r;
    if (damping < 0) damping = 1e-3 * std::max(JtJ.diagonal().maxCoeff(), 1e-300);
    const Eigen::Vector3d step = (JtJ + damping * Eigen::Matrix3d::Identity()).ldlt().solve(-gradient);
    if (!step.allFinite() || step.norm() < 1e-10) break;
    const DiskMoebius trial{m.a + Complex(step[0], step[1]), m.theta + step[2]};
    // Outside the disk group the formula is no automorphism: damp instead.
    if (!(std::abs(trial.a) < 1 - 1e-9)) {
      damping *= 4;
      continue;
    }
    const double trial_energy = moebius_energy(l, trial);
    if (trial_energy < energy) {
      const bool settled = energy - trial_energy <= 1e-12 * energy;
      m = trial;
      energy = linearise(m);
      damping = std::max(damping / 3, 1e-300);
      if (settled) break;
    } else {
      damping *= 4;
    }
  }
  m.theta = std::remainder(m.theta, 2 * std::numbers::pi);
  return {m, moebius_energy(l, m), iterations, start};
}

}  // namespace

MoebiusFit fit_moebius_checked(const CheckedLandmarks& landmarks, const MoebiusFitOptions& options) {
  if (options.max_iterations < 0) throw Error(ErrorCode::kInvalidArgument, "registration: max_iterations must be >= 0");
  std::optional<MoebiusFit> best;
  if (options.start != MoebiusStart::kAlgebraic) {
    best = levenberg_marquardt(landmarks, rotation_start(landmarks), options.max_iterations, MoebiusStart::kRotation);
  }
  if (options.start != MoebiusStart::kRotation) {
    if (const auto start = algebraic_start(landmarks)) {
      MoebiusFit fit = levenberg_marquardt(landmarks, *start, options.max_iterations, MoebiusStart::kAlgebraic);
      if (!best || fit.energy < best->energy) best = fit;
    }
  }
  // Asked for the algebraic start alone and it left the disk group: the rotation is all there is.
  if (!best) best = levenberg_marquardt(landmarks, rotation_start(landmarks), options.max_iterations, MoebiusStart::kRotation);
  return *best;
}

MoebiusFit fit_moebius(const DiskLandmarks& landmarks, const MoebiusFitOptions& options) {
  return fit_moebius_checked(check_landmarks(landmarks), options);
}

}  // namespace facemorph
