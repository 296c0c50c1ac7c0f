// The correction of a blend of keyframes that best cancels a frame's offsets (blend_correction.hpp).
#include "codec/encoder/keyframes/blend_correction.hpp"

#include "format/error.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace facemorph {

double fit_blend_correction(std::span<const double> offsets, const std::vector<std::vector<double>>& columns,
                            std::span<const double> weights, double step, std::vector<double>& delta) {
  const int n = static_cast<int>(columns.size());
  delta.clear();
  if (n < 2) return std::numeric_limits<double>::infinity();
  const size_t nodes = offsets.size();
  for (const auto& a : columns) {
    if (a.size() != nodes) throw Error(ErrorCode::kInvalidArgument, "fit_blend_correction: a column of another size than the offsets");
  }
  if (weights.size() != nodes) throw Error(ErrorCode::kInvalidArgument, "fit_blend_correction: weights of another size than the offsets");
  const int free = n - 1;
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(free, free);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(free);
  Eigen::VectorXd b(free);
  for (size_t v = 0; v < nodes; ++v) {
    for (int m = 0; m < free; ++m) b[m] = columns[static_cast<size_t>(m)][v] - columns[static_cast<size_t>(free)][v];
    normal.noalias() += weights[v] * b * b.transpose();
    rhs.noalias() -= weights[v] * offsets[v] * b;
  }
  normal.diagonal().array() += 1e-9 * std::max(normal.trace() / free, 1e-300);
  const Eigen::VectorXd x = normal.ldlt().solve(rhs);
  const double bound = 1.0;
  delta.assign(static_cast<size_t>(n), 0.0);
  int64_t total = 0;
  for (int m = 0; m < free; ++m) {
    const double value = std::isfinite(x[m]) ? std::clamp(x[m], -bound, bound) : 0.0;
    const int64_t code = std::llround(value / step);
    total += code;
    delta[static_cast<size_t>(m)] = static_cast<double>(code) * step;
  }
  delta[static_cast<size_t>(free)] = static_cast<double>(-total) * step;
  double sum = 0;
  for (size_t v = 0; v < nodes; ++v) {
    double offset = offsets[v];
    for (int m = 0; m < n; ++m) offset += delta[static_cast<size_t>(m)] * columns[static_cast<size_t>(m)][v];
    sum += weights[v] * offset * offset;
  }
  return sum;
}

}  // namespace facemorph
