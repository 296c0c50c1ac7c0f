// The patch's least squares from sums gathered once a lattice (codec/encoder/encode/patch_solve.hpp,
// spec/method.md §7.19): every solve must give, to the bit, what summing the samples into the normal
// matrix at that solve gives (the files stay byte for byte the same), whichever nodes move, and a
// constant offset is met by a constant displacement.
#include "codec/encoder/encode/patch_solve.hpp"

#include <Eigen/Sparse>
#include <gtest/gtest.h>

#include <random>
#include <utility>

namespace facemorph {
namespace {

// The solve as fit_at_threshold did it before the sums (main e6841c8): each sample's terms as a
// triplet list, summed by setFromTriplets, the smoothing's after them.
std::vector<Vec3> solve_from_samples(const std::vector<OffsetSample>& samples, const std::vector<int>& index, int unknowns, int lattice,
                                     double smoothing) {
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(unknowns, 3);
  size_t rows = 0;
  for (const OffsetSample& s : samples) {
    const auto [i, a] = patch_cell_of(s.w.x(), lattice);
    const auto [j, b] = patch_cell_of(s.w.y(), lattice);
    const int corner[4] = {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1};
    const double weight[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
    bool touches = false;
    for (int c = 0; c < 4; ++c) touches |= index[static_cast<size_t>(corner[c])] >= 0;
    if (!touches) continue;
    ++rows;
    for (int c = 0; c < 4; ++c) {
      const int p = index[static_cast<size_t>(corner[c])];
      if (p < 0) continue;
      rhs.row(p) += weight[c] * s.offset.transpose();
      for (int e = 0; e < 4; ++e) {
        const int q = index[static_cast<size_t>(corner[e])];
        if (q >= 0) entries.emplace_back(p, q, weight[c] * weight[e]);
      }
    }
  }
  // The smoothing and the solve are the code under test's (solve_patch_normal): what differs is how
  // the samples' terms are summed.
  return solve_patch_normal(std::move(entries), rhs, index, lattice, unknowns, smoothing, rows);
}

// Samples over the unit disk with a bump of offsets (as a frame's worst region), some exactly on
// lattice lines (a weight exactly 0: the entry still exists) and at the disk's edge.
std::vector<OffsetSample> bump_samples(int count, unsigned seed, int lattice) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1), n(-1e-3, 1e-3);
  std::vector<OffsetSample> samples;
  while (static_cast<int>(samples.size()) < count) {
    Vec2 w(u(rng), u(rng));
    if (w.squaredNorm() > 1) continue;
    if (samples.size() % 17 == 0) w.x() = -1 + 2.0 * static_cast<double>(samples.size() % (lattice - 1)) / (lattice - 1);
    const double bump = std::exp(-12 * (w - Vec2(0.3, -0.2)).squaredNorm());
    samples.push_back({w, Vec3(0.01 * bump + n(rng), n(rng), -0.02 * bump + n(rng))});
  }
  samples.push_back({Vec2(1, 0), Vec3(1e-3, 0, 0)});
  return samples;
}

// The moving nodes of a threshold, as fit_at_threshold chooses them: the corners of the cells
// holding a sample whose offset passes it.
std::vector<int> moving_nodes(const std::vector<OffsetSample>& samples, int lattice, double threshold, int& unknowns) {
  std::vector<int> index(static_cast<size_t>(lattice * lattice), -1);
  for (const OffsetSample& s : samples) {
    if (s.offset.norm() <= threshold) continue;
    const int i = patch_cell_of(s.w.x(), lattice).first, j = patch_cell_of(s.w.y(), lattice).first;
    for (const int node : {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1})
      index[static_cast<size_t>(node)] = 0;
  }
  unknowns = 0;
  for (int& p : index)
    if (p >= 0) p = unknowns++;
  return index;
}

// One set of sums serves every threshold's solve (the patch search's seven), and a set gathered for
// one index alone (the second round's) serves that index: each the triplet solve to the bit. Sums
// gathered from other samples (a stale set) or summed in another order fail here.
TEST(PatchSolve, SumsGatheredOnceSolveEveryThresholdToTheBit) {
  for (const int lattice : {17, 33}) {
    const std::vector<OffsetSample> samples = bump_samples(6000, 3 + static_cast<unsigned>(lattice), lattice);
    const PatchNormalSums sums(samples, lattice);
    int solved = 0;
    for (const double threshold : {0.009, 0.007, 0.005, 0.003, 0.0015}) {
      int unknowns = 0;
      const std::vector<int> index = moving_nodes(samples, lattice, threshold, unknowns);
      if (unknowns == 0) continue;
      const std::vector<Vec3> want = solve_from_samples(samples, index, unknowns, lattice, 0.1);
      const std::vector<Vec3> got = sums.solve(index, unknowns, 0.1);
      const std::vector<Vec3> only = PatchNormalSums(samples, lattice, &index).solve(index, unknowns, 0.1);
      ASSERT_EQ(got.size(), want.size());
      for (size_t p = 0; p < want.size(); ++p) {
        EXPECT_EQ(got[p], want[p]) << "lattice " << lattice << ", threshold " << threshold << ", unknown " << p;
        EXPECT_EQ(only[p], want[p]) << "lattice " << lattice << ", threshold " << threshold << ", unknown " << p;
      }
      ++solved;
    }
    EXPECT_GE(solved, 4);
    // Sums of other samples (the patched surface's second round) are not this solve's.
    int unknowns = 0;
    const std::vector<int> index = moving_nodes(samples, lattice, 0.005, unknowns);
    const std::vector<OffsetSample> other = bump_samples(6000, 99, lattice);
    EXPECT_NE(PatchNormalSums(other, lattice).solve(index, unknowns, 0.1), solve_from_samples(samples, index, unknowns, lattice, 0.1));
  }
}

// Every sample offset by the same vector, every node moving, little smoothing: the displacement is
// that vector at every node (the bilinear weights sum to 1).
TEST(PatchSolve, AConstantOffsetIsAConstantDisplacement) {
  std::vector<OffsetSample> samples = bump_samples(4000, 5, 17);
  for (OffsetSample& s : samples) s.offset = Vec3(0.01, -0.02, 0.005);
  std::vector<int> index(17 * 17);
  for (size_t n = 0; n < index.size(); ++n) index[n] = static_cast<int>(n);
  // Nodes outside the disk hold no sample; the smoothing carries the value to them.
  const std::vector<Vec3> d = PatchNormalSums(samples, 17).solve(index, 17 * 17, 1e-6);
  for (const Vec3& v : d) EXPECT_LT((v - Vec3(0.01, -0.02, 0.005)).norm(), 1e-7);
}

}  // namespace
}  // namespace facemorph
