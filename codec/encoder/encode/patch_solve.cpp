// The least squares of a frame patch's lattice displacements (patch_solve.hpp).
#include "codec/encoder/encode/patch_solve.hpp"

#include <Eigen/Sparse>

#include <algorithm>
#include <cmath>
#include <utility>

namespace facemorph {

std::pair<int, double> patch_cell_of(double x, int lattice) {
  const double f = (x + 1) / 2 * (lattice - 1);
  const int i = std::clamp(static_cast<int>(std::floor(f)), 0, lattice - 2);
  return {i, f - i};
}

std::vector<Vec3> solve_patch_normal(std::vector<Eigen::Triplet<double>> entries, const Eigen::MatrixXd& rhs, const std::vector<int>& index,
                                     int lattice, int unknowns, double smoothing, size_t rows) {
  const double mu = smoothing * static_cast<double>(rows) / unknowns + 1e-9;
  for (int b = 0; b < lattice; ++b) {
    for (int a = 0; a < lattice; ++a) {
      const int p = index[static_cast<size_t>(b * lattice + a)];
      for (const int other : {a + 1 < lattice ? b * lattice + a + 1 : -1, b + 1 < lattice ? (b + 1) * lattice + a : -1}) {
        if (other < 0) continue;
        const int q = index[static_cast<size_t>(other)];
        if (p < 0 && q < 0) continue;
        if (p >= 0) entries.emplace_back(p, p, mu);
        if (q >= 0) entries.emplace_back(q, q, mu);
        if (p >= 0 && q >= 0) {
          entries.emplace_back(p, q, -mu);
          entries.emplace_back(q, p, -mu);
        }
      }
    }
  }
  Eigen::SparseMatrix<double> normal(unknowns, unknowns);
  normal.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  const Eigen::MatrixXd x = solver.solve(rhs);
  std::vector<Vec3> out(static_cast<size_t>(unknowns));
  for (int p = 0; p < unknowns; ++p) out[static_cast<size_t>(p)] = x.row(p).transpose();
  return out;
}

PatchNormalSums::PatchNormalSums(const std::vector<OffsetSample>& samples, int lattice, const std::vector<int>* only)
    : lattice_(lattice) {
  const size_t nodes = static_cast<size_t>(lattice) * static_cast<size_t>(lattice);
  pair_.assign(nodes, {});
  shared_.assign(nodes, {});
  rhs_.assign(nodes, Vec3::Zero());
  cell_samples_.assign(static_cast<size_t>(lattice - 1) * static_cast<size_t>(lattice - 1), 0);
  for (const OffsetSample& s : samples) {
    const auto [i, a] = patch_cell_of(s.w.x(), lattice);
    const auto [j, b] = patch_cell_of(s.w.y(), lattice);
    const int corner[4] = {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1};
    const int dx[4] = {0, 1, 0, 1}, dy[4] = {0, 0, 1, 1};
    if (only) {
      bool touches = false;
      for (int c = 0; c < 4; ++c) touches |= (*only)[static_cast<size_t>(corner[c])] >= 0;
      if (!touches) continue;
    }
    const double weight[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
    ++cell_samples_[static_cast<size_t>(j * (lattice - 1) + i)];
    for (int c = 0; c < 4; ++c) {
      const size_t p = static_cast<size_t>(corner[c]);
      rhs_[p] += weight[c] * s.offset;
      for (int e = 0; e < 4; ++e) {
        // As a triplet list summed by setFromTriplets: the first term as it is, the next added to it.
        const int k = slot(dx[e] - dx[c], dy[e] - dy[c]);
        const double term = weight[c] * weight[e];
        double& entry = pair_[p][static_cast<size_t>(k)];
        entry = shared_[p][static_cast<size_t>(k)] ? entry + term : term;
        shared_[p][static_cast<size_t>(k)] = 1;
      }
    }
  }
}

std::vector<Vec3> PatchNormalSums::solve(const std::vector<int>& index, int unknowns, double smoothing) const {
  const int lattice = lattice_;
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(unknowns, 3);
  size_t rows = 0;  // the samples touching a moving node
  for (int j = 0; j + 1 < lattice; ++j)
    for (int i = 0; i + 1 < lattice; ++i) {
      const int corner[4] = {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1};
      bool touches = false;
      for (int c = 0; c < 4; ++c) touches |= index[static_cast<size_t>(corner[c])] >= 0;
      if (touches) rows += static_cast<size_t>(cell_samples_[static_cast<size_t>(j * (lattice - 1) + i)]);
    }
  for (int y = 0; y < lattice; ++y)
    for (int x = 0; x < lattice; ++x) {
      const size_t n = static_cast<size_t>(y * lattice + x);
      const int p = index[n];
      if (p < 0) continue;
      rhs.row(p) = rhs_[n].transpose();
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int k = slot(dx, dy);
          if (!shared_[n][static_cast<size_t>(k)] || x + dx < 0 || x + dx >= lattice || y + dy < 0 || y + dy >= lattice) continue;
          const int q = index[static_cast<size_t>((y + dy) * lattice + x + dx)];
          if (q >= 0) entries.emplace_back(p, q, pair_[n][static_cast<size_t>(k)]);
        }
    }
  return solve_patch_normal(std::move(entries), rhs, index, lattice, unknowns, smoothing, rows);
}

}  // namespace facemorph
