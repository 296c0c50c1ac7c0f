// Anderson acceleration's mixer (anderson_mixer.hpp).
#include "codec/core/reconstruct/anderson_mixer.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <type_traits>
#include <utility>
#include <vector>

namespace facemorph {

namespace {

// The mixer's two passes over the surface, with the number of differences they run over a
// compile-time constant where it is small (kUnrolledTerms or fewer): the dot products' accumulators
// then live in registers, not in an array the loop stores to on every node, and the combination
// vectorises across nodes. Every sum adds its terms in the same order as the loops over a run-time
// count (Terms = kAnyTerms) do, so the iterates are the same bits either way: the decoder's golden
// files pin them. Over a run-time count the mixer was a tenth of the encoder's CPU on ICT at 2k
// vertices; unrolled, a warm decode at N = 128 takes 4.3 ms a frame where it took 5.6
// (`fmbench reconstruct --speed`).
constexpr int kAnyTerms = -1;
constexpr int kUnrolledTerms = 8;

// Calls `body` with std::integral_constant<int, terms> where terms <= kUnrolledTerms, with
// kAnyTerms otherwise.
template <int Terms = 0, class Body>
decltype(auto) dispatch_on_terms(int terms, Body&& body) {
  if constexpr (Terms > kUnrolledTerms) {
    return body(std::integral_constant<int, kAnyTerms>{});
  } else {
    if (terms == Terms) return body(std::integral_constant<int, Terms>{});
    return dispatch_on_terms<Terms + 1>(terms, std::forward<Body>(body));
  }
}

// What the first pass reads and writes: the iterate x and its image g; the newest differences of
// the residual f = g - x and of g (into the slot's df, dg); the previous f and g (overwritten by
// this step's); the differences dF_j the dot products run over (dF[slot] is df, written first).
struct FirstPass {
  const double* x;
  const double* g;
  double* df;
  double* dg;
  double* previous_f;
  double* previous_g;
  const double* dF[AndersonMixer::kMaxDepth];
  size_t size;
};

// |f|², and, over `terms` differences j (Terms where known at compile time), cross[j] += df·dF_j
// and project[j] += dF_j·f, each summed node by node in order. terms = 0: no previous f yet, so no
// differences are written either.
template <int Terms>
double first_pass(const FirstPass& p, int terms, double* cross, double* project) {
  const int count = Terms == kAnyTerms ? terms : Terms;
  double residual2 = 0;
  double c[AndersonMixer::kMaxDepth] = {}, q[AndersonMixer::kMaxDepth] = {};
  for (size_t e = 0; e < p.size; ++e) {
    const double ge = p.g[e];
    const double f = ge - p.x[e];
    residual2 += f * f;
    if (count > 0) {
      const double d = f - p.previous_f[e];
      p.df[e] = d;
      p.dg[e] = ge - p.previous_g[e];
      for (int j = 0; j < count; ++j) {
        const double dj = p.dF[j][e];  // d itself for j = slot: read back where it was just written
        c[j] += d * dj;
        q[j] += dj * f;
      }
    }
    p.previous_f[e] = f;
    p.previous_g[e] = ge;
  }
  for (int j = 0; j < count; ++j) cross[j] = c[j], project[j] = q[j];
  return residual2;
}

// g -= Σ_i γ_i dG_i over `terms` differences (Terms where known at compile time), the sum over i in
// order from 0 at every node.
template <int Terms>
void combine(double* __restrict g, size_t size, const std::vector<Eigen::VectorXd>& dG, const double* gamma, int terms) {
  const int count = Terms == kAnyTerms ? terms : Terms;
  const double* rows[AndersonMixer::kMaxDepth];
  double weights[AndersonMixer::kMaxDepth];
  for (int i = 0; i < count; ++i) rows[i] = dG[static_cast<size_t>(i)].data(), weights[i] = gamma[i];
  for (size_t e = 0; e < size; ++e) {
    double sum = 0;
    for (int i = 0; i < count; ++i) sum += weights[i] * rows[i][e];
    g[e] -= sum;
  }
}

}  // namespace

void AndersonMixer::restart(int depth, Eigen::Index size) {
  depth_ = std::clamp(depth, 0, kMaxDepth);
  has_previous_ = false;
  count_ = oldest_ = 0;
  previous_residual_ = 0;
  if (depth_ == 0) return;
  gram_.resize(depth_, depth_);
  previous_f_.resize(size);
  previous_g_.resize(size);
  if (dF_.size() < static_cast<size_t>(depth_)) {
    dF_.resize(static_cast<size_t>(depth_));
    dG_.resize(static_cast<size_t>(depth_));
  }
  for (int j = 0; j < depth_; ++j) {
    dF_[static_cast<size_t>(j)].resize(size);
    dG_[static_cast<size_t>(j)].resize(size);
  }
}

void AndersonMixer::step(const Vector& x, Vector g) {
  if (depth_ <= 0) return;
  // The slot the newest difference goes to: the next free one, or the oldest once the ring is full.
  const int slot = count_ < depth_ ? count_ : oldest_;
  // The differences the dot products run over: those that stay and the newest, once there is a
  // previous residual to difference against.
  const int terms = has_previous_ ? std::max(count_, slot + 1) : 0;
  FirstPass pass{
      x.data(),           g.data(), dF_[static_cast<size_t>(slot)].data(), dG_[static_cast<size_t>(slot)].data(), previous_f_.data(),
      previous_g_.data(), {},       static_cast<size_t>(x.size())};
  for (int j = 0; j < terms; ++j) pass.dF[j] = dF_[static_cast<size_t>(j)].data();
  double cross[kMaxDepth] = {};    // dF_slot · dF_j (the Gram matrix's new row)
  double project[kMaxDepth] = {};  // dF_j · f, the newest f
  const double residual =
      std::sqrt(dispatch_on_terms(terms, [&](auto count) { return first_pass<decltype(count)::value>(pass, terms, cross, project); }));
  const bool restart = has_previous_ && residual > previous_residual_;
  const bool add = has_previous_ && !restart;
  previous_residual_ = residual;
  has_previous_ = true;
  if (restart) {
    count_ = 0;
    oldest_ = 0;
    return;  // the plain step
  }
  if (!add) return;
  if (count_ < depth_) {
    ++count_;
  } else {
    oldest_ = (oldest_ + 1) % depth_;
  }
  const int m = count_;
  for (int j = 0; j < m; ++j) gram_(slot, j) = gram_(j, slot) = cross[j];
  // Least squares min |f - ΔF γ| through the m x m normal equations (m is small).
  Eigen::MatrixXd A = gram_.topLeftCorner(m, m);
  Eigen::VectorXd b(m);
  for (int i = 0; i < m; ++i) b[i] = project[i];
  A.diagonal().array() += 1e-12 * A.diagonal().maxCoeff();
  const Eigen::VectorXd gamma = A.ldlt().solve(b);
  if (!gamma.allFinite()) return;
  dispatch_on_terms(m, [&](auto count) { combine<decltype(count)::value>(g.data(), pass.size, dG_, gamma.data(), m); });
}

}  // namespace facemorph
