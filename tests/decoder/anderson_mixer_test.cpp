// The decoder's Anderson mixer (codec/core/reconstruct/anderson_mixer.hpp): its passes, unrolled for
// up to 8 differences and over a run-time count beyond, give the same bits as the plain loops they
// replaced, at every depth, through restarts and a ring that wraps. The decoder's golden files pin
// the iterates, so "the same" means to the bit.
#include "codec/core/reconstruct/anderson_mixer.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace facemorph {
namespace {

// The mixer as it was before its passes were unrolled (one loop over the differences a node, the
// accumulators in arrays): the reference whose sums the mixer must reproduce.
class ReferenceMixer {
 public:
  void restart(int depth, Eigen::Index size) {
    depth_ = std::clamp(depth, 0, kMaxDepth);
    has_previous_ = false;
    count_ = oldest_ = 0;
    previous_residual_ = 0;
    if (depth_ == 0) return;
    gram_.resize(depth_, depth_);
    previous_f_.resize(size);
    previous_g_.resize(size);
    dF_.assign(static_cast<size_t>(depth_), Eigen::VectorXd(size));
    dG_.assign(static_cast<size_t>(depth_), Eigen::VectorXd(size));
  }

  void step(const Eigen::VectorXd& x, Eigen::VectorXd& g) {
    if (depth_ <= 0) return;
    const int slot = count_ < depth_ ? count_ : oldest_;
    const auto size = static_cast<size_t>(x.size());
    double residual2 = 0;
    double cross[kMaxDepth] = {};
    double project[kMaxDepth] = {};
    double* df = dF_[static_cast<size_t>(slot)].data();
    double* dg = dG_[static_cast<size_t>(slot)].data();
    const int others = count_;
    for (size_t e = 0; e < size; ++e) {
      const auto i = static_cast<Eigen::Index>(e);
      const double f = g[i] - x[i];
      residual2 += f * f;
      if (has_previous_) {
        const double d = f - previous_f_[i];
        df[e] = d;
        dg[e] = g[i] - previous_g_[i];
        for (int j = 0; j < others; ++j) {
          if (j == slot) continue;
          cross[j] += d * dF_[static_cast<size_t>(j)][i];
          project[j] += dF_[static_cast<size_t>(j)][i] * f;
        }
        cross[slot] += d * d;
        project[slot] += d * f;
      }
      previous_f_[i] = f;
      previous_g_[i] = g[i];
    }
    const double residual = std::sqrt(residual2);
    const bool restart = has_previous_ && residual > previous_residual_;
    const bool add = has_previous_ && !restart;
    previous_residual_ = residual;
    has_previous_ = true;
    if (restart) {
      count_ = oldest_ = 0;
      return;
    }
    if (!add) return;
    if (count_ < depth_) {
      ++count_;
    } else {
      oldest_ = (oldest_ + 1) % depth_;
    }
    const int m = count_;
    for (int j = 0; j < m; ++j) gram_(slot, j) = gram_(j, slot) = cross[j];
    Eigen::MatrixXd A = gram_.topLeftCorner(m, m);
    Eigen::VectorXd b(m);
    for (int i = 0; i < m; ++i) b[i] = project[i];
    A.diagonal().array() += 1e-12 * A.diagonal().maxCoeff();
    const Eigen::VectorXd gamma = A.ldlt().solve(b);
    if (!gamma.allFinite()) return;
    for (size_t e = 0; e < size; ++e) {
      double sum = 0;
      for (int i = 0; i < m; ++i) sum += gamma[i] * dG_[static_cast<size_t>(i)][static_cast<Eigen::Index>(e)];
      g[static_cast<Eigen::Index>(e)] -= sum;
    }
  }

 private:
  static constexpr int kMaxDepth = AndersonMixer::kMaxDepth;
  int depth_ = 0;
  bool has_previous_ = false;
  int count_ = 0, oldest_ = 0;
  double previous_residual_ = 0;
  Eigen::MatrixXd gram_;
  Eigen::VectorXd previous_f_, previous_g_;
  std::vector<Eigen::VectorXd> dF_, dG_;
};

bool same_bits(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), static_cast<size_t>(a.size()) * sizeof(double)) == 0;
}

TEST(AndersonMixer, GivesThePlainLoopsBitsAtEveryDepth) {
  // A mildly nonlinear contraction, G(S) = A S + b + 0.1 sin S with A diagonal in [0.3, 0.9], its
  // iterates mixed by both mixers from one start: at every step both must hand back the same next
  // iterate. A kick at steps 9 and 23 raises the residual, so the restart is taken too; 40 steps
  // wrap the ring at every depth. Depths 9 and up run the passes over a run-time count (the
  // unrolled ones stop at 8); 17 is clamped to 16.
  const Eigen::Index size = 1001;  // odd: no pass may rely on an even count of nodes
  std::mt19937 random(44);
  std::uniform_real_distribution<double> contraction(0.3, 0.9), offset(-1, 1);
  Eigen::VectorXd a(size), b(size), start(size);
  for (Eigen::Index i = 0; i < size; ++i) a[i] = contraction(random), b[i] = offset(random), start[i] = offset(random);
  AndersonMixer mixer;  // one mixer for every depth: restart() must forget the last one's ring
  for (int depth : {0, 1, 2, 3, 5, 8, 9, 12, 16, 17}) {
    ReferenceMixer reference;
    reference.restart(depth, size);
    mixer.restart(depth, size);
    Eigen::VectorXd x = start;
    int mixed = 0;  // steps where the mixer changed g
    for (int step = 0; step < 40; ++step) {
      Eigen::VectorXd g = (a.array() * x.array() + b.array() + 0.1 * x.array().sin()).matrix();
      if (step == 9 || step == 23) g.array() += 0.5;
      Eigen::VectorXd expected = g, got = g;
      reference.step(x, expected);
      mixer.step(AndersonMixer::Vector(x.data(), size), AndersonMixer::Vector(got.data(), size));
      ASSERT_TRUE(same_bits(expected, got)) << "depth " << depth << ", step " << step << ": max difference "
                                            << (expected - got).cwiseAbs().maxCoeff();
      mixed += !same_bits(got, g);
      x = got;
    }
    // The comparison means something only where the mixer mixed: every depth but 0 does.
    if (depth > 0) {
      EXPECT_GT(mixed, 20) << "depth " << depth;
    }
  }
}

}  // namespace
}  // namespace facemorph
