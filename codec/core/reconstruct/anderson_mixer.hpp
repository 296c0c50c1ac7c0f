// Anderson acceleration of the decoder's fixed-point iteration (Reconstructor): a mixer of its
// iterates with a bounded history, kept between frames.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace facemorph {

// Anderson acceleration (Walker & Ni 2011, "type II") of the fixed-point iteration S -> G(S): the
// next iterate combines the last few G values so as to minimise the linear model of the residual
// G(S) - S. The plain iteration contracts by about 0.45 per step on faces; this one far faster.
// Safeguarded by a restart: when the residual |G(S) - S| grows, the history (a linear model of a
// map that is far from linear there) is dropped and the plain step taken. Unguarded, it wandered
// and never converged on smooth analytic bumps that the plain iteration solves in 10-40 steps
// (tests/decoder/reconstruct_test.cpp); guarded, real faces take the same steps as before.
// The history is a ring of preallocated vectors and its Gram matrix is kept, so a step costs a few
// passes over the surface (one new row of dot products), not one per pair of past steps: it was
// an eighth of a decoder step at N = 257. The decoder keeps one mixer and restarts it each frame:
// its ~10 surface-sized vectors, allocated afresh, were a page fault per 4 kB every frame.
class AndersonMixer {
 public:
  using Vector = Eigen::Map<Eigen::VectorXd>;
  static constexpr int kMaxDepth = 16;

  // Forgets the history; `depth` past steps (clamped to [0, kMaxDepth]) of `size` unknowns from
  // now on (memory kept).
  void restart(int depth, Eigen::Index size);

  // Replaces `g`, the image of the current iterate `x`, by the next iterate. Two passes over the
  // surface: one forms the residual, the newest differences and every dot product the least squares
  // needs; one applies the combination.
  void step(const Vector& x, Vector g);

 private:
  int depth_ = 0;
  bool has_previous_ = false;
  int count_ = 0;   // differences held
  int oldest_ = 0;  // once the ring is full, the slot overwritten next
  double previous_residual_ = 0;
  Eigen::MatrixXd gram_;  // dF_i · dF_j
  // The last f = G(S) - S and G(S), and the ring of their differences from one step to the next.
  Eigen::VectorXd previous_f_, previous_g_;
  std::vector<Eigen::VectorXd> dF_, dG_;
};

}  // namespace facemorph
