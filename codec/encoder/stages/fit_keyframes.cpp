// The keyframe fit (--keyframe-fit): the keyframes' values whose spline best matches every frame
// of the capture, a banded least-squares solve per node of G, each keyframe's move bounded by its
// frame's noise (spec/method.md §7.5).
#include "codec/encoder/stages/fit_keyframes.hpp"

#include "codec/encoder/keyframes/banded_cholesky.hpp"

#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/core/util/parallel.hpp"
#include "format/error.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <vector>

namespace facemorph {

void fit_keyframes(const KeyframeFitInput& input, const GridGeometry& geometry, SurfaceStore& local) {
  const std::vector<int>& keyframes = input.keyframes;
  const std::vector<Vec2>& nodes = geometry.grid().nodes;
  // Per node of G, the keyframe values P_k minimising
  //   Σ_j |Σ_k c_k(t_j) P_k − X_j|² + μ Σ_k |P_k − X_k|²
  // over the frames j within the keyframes' span, X_j frame j's registered surface in the face frame
  // of the pose the decoder blends at t_j (at a keyframe, its own pose). The weights c_k(t_j) are
  // shared by every node, so this is one keys × keys normal matrix (banded, positive definite: each
  // keyframe's own frame has weight 1 + μ) and a right-hand side per node coordinate.
  const auto keys = static_cast<Eigen::Index>(keyframes.size());
  const auto count = static_cast<Eigen::Index>(input.times.size());
  if (keys < 2 || keys >= count || local.size() != keyframes.size()) return;
  const double mu = input.weight;
  std::vector<double> times;
  for (int k : keyframes) times.push_back(input.times[static_cast<size_t>(k)]);
  const std::vector<RigidPose>& poses = input.poses;
  const KeyframeSpline spline(times, input.spline);
  const std::vector<Vec3> rotations = unwrap_rotations(poses);
  const Vec3& centre = input.pose_centre;
  const auto n = static_cast<Eigen::Index>(3 * nodes.size());
  auto flat = [n](std::vector<Vec3>& v) { return Eigen::Map<Eigen::VectorXd>(v.data()->data(), n); };
  auto flat_const = [n](const std::vector<Vec3>& v) { return Eigen::Map<const Eigen::VectorXd>(v.data()->data(), n); };
  std::vector<int> held;
  for (int j = keyframes.front() + 1; j < keyframes.back(); ++j) {
    if (!std::binary_search(keyframes.begin(), keyframes.end(), j)) held.push_back(j);
  }
  // The normal matrix from the weights alone: every keyframe's own frame (weight 1 + μ) and each
  // held frame's few keyframes. It couples keyframes a frame's weights reach together, a band of a
  // few; `last_use[k]`: the last held frame whose weights reach keyframe k (−1: none).
  std::vector<SplineWeights> weights(held.size());
  int band = 0;
  for (size_t h = 0; h < held.size(); ++h) {
    weights[h] = spline.weights(input.times[static_cast<size_t>(held[h])]);
    for (int32_t a : weights[h].keys) {
      for (int32_t b : weights[h].keys) band = std::max(band, std::abs(a - b));
    }
  }
  SymmetricBand normal(static_cast<int>(keys), band);
  std::vector<long> last_use(static_cast<size_t>(keys), -1);
  for (Eigen::Index k = 0; k < keys; ++k) normal.at(static_cast<int>(k), static_cast<int>(k)) += 1 + mu;
  for (size_t h = 0; h < held.size(); ++h) {
    const SplineWeights& w = weights[h];
    for (size_t a = 0; a < w.keys.size(); ++a) {
      last_use[static_cast<size_t>(w.keys[a])] = static_cast<long>(h);
      // Every ordered pair, each entry once (the band holds A(i, j) and A(j, i) as one number); a
      // key may appear twice in one frame's weights.
      for (size_t b = 0; b < w.keys.size(); ++b) {
        if (w.keys[a] >= w.keys[b]) normal.at(w.keys[a], w.keys[b]) += w.weights[a] * w.weights[b];
      }
    }
  }
  const BandedCholesky factor(normal);
  // The right-hand side, column k = Σ_j c_k(t_j) X_j + (1 + μ) X_k, made as the held frames are
  // sampled in time order (32 at a time, on the threads), and solved as it comes: once no later
  // frame reaches column k, forward substitution turns it into y_k = (column k − Σ L(k, i) y_i) /
  // L(k, k) over the `band` y's before it, and y_k goes to the store. Memory holds the columns
  // begun and not finished and the last `band` y's, a few surfaces whatever the keyframes' count
  // (a whole right-hand side was 1.25 MB a keyframe at N = 257).
  SurfaceStore forward(local.mode());
  forward.reset(keyframes.size());
  std::map<Eigen::Index, Eigen::VectorXd> open;    // columns begun
  std::deque<Eigen::VectorXd> recent;              // y_{k − band} .. y_{k − 1}
  Eigen::Index next = 0;                           // the next column to finish
  const auto finish_columns = [&](long through) {  // every held frame up to `through` added
    for (; next < keys && last_use[static_cast<size_t>(next)] <= through; ++next) {
      Eigen::VectorXd y = open.count(next) ? std::move(open[next]) : Eigen::VectorXd::Zero(n);
      open.erase(next);
      y += (1 + mu) * flat_const(*local.get(static_cast<size_t>(next)));
      factor.forward(static_cast<int>(next), y, recent);
      std::vector<Vec3> stored(nodes.size());
      flat(stored) = y;
      forward.put(static_cast<size_t>(next), std::move(stored));
      recent.push_back(std::move(y));
      if (static_cast<int>(recent.size()) > band) recent.pop_front();
    }
  };
  finish_columns(-1);
  const int chunk = 32;
  std::vector<std::vector<Vec3>> samples(chunk);
  for (size_t begin = 0; begin < held.size(); begin += chunk) {
    const int size = static_cast<int>(std::min(held.size() - begin, static_cast<size_t>(chunk)));
    parallel_for(size, input.threads, [&](int c) {
      const size_t h = begin + static_cast<size_t>(c);
      const RigidPose to_face = blend_poses(poses, rotations, weights[h], centre).inverse();
      std::vector<Vec3> positions = input.surface(held[h], nodes);
      for (Vec3& p : positions) p = to_face.apply(p);
      samples[static_cast<size_t>(c)] = std::move(positions);
    });
    for (int c = 0; c < size; ++c) {
      const SplineWeights& w = weights[begin + static_cast<size_t>(c)];
      const auto x = flat(samples[static_cast<size_t>(c)]);
      for (size_t a = 0; a < w.keys.size(); ++a) {
        // last_use keeps a column open until its last frame is in; a frame reaching one already
        // solved would be lost from it.
        if (w.keys[a] < next) throw Error(ErrorCode::kInternal, "keyframe fit: a frame reaches a keyframe already solved");
        Eigen::VectorXd& column = open[w.keys[a]];
        if (column.size() == 0) column = Eigen::VectorXd::Zero(n);
        column += w.weights[a] * x;
      }
    }
    finish_columns(static_cast<long>(begin) + size - 1);
  }
  finish_columns(static_cast<long>(held.size()));
  // Back substitution from the last keyframe: P_k = (y_k − Σ L(i, k) P_i) / L(k, k) over the
  // `band` keyframes after it, each fitted surface then bounded against the keyframe's own frame.
  const Eigen::VectorXd& mass = geometry.mass();
  std::deque<Eigen::VectorXd> after;  // P_{k + 1} .. P_{k + band}
  for (Eigen::Index k = keys - 1; k >= 0; --k) {
    Eigen::VectorXd fitted = flat_const(*forward.get(static_cast<size_t>(k)));
    factor.backward(static_cast<int>(k), fitted, after);
    std::vector<Vec3> own = *local.get(static_cast<size_t>(k));  // a copy to move: the stored one is read-only
    double moved = 0, total = 0;
    for (Eigen::Index v = 0; v < mass.size(); ++v) {
      moved += mass[v] * (fitted.segment<3>(3 * v) - own[static_cast<size_t>(v)]).squaredNorm();
      total += mass[v];
    }
    moved = std::sqrt(moved / total);
    const double noise = input.noise(keyframes[static_cast<size_t>(k)]);
    // A move beyond κ times the frame's own noise would fit the spline's systematic error between
    // keyframes rather than the capture's noise: shrink it back to that (a clean capture's keyframes
    // stay its frames). Fewer than 5 frames give no estimate of the noise, so nothing bounds the
    // move: the keyframe stays its frame.
    const double scale = std::isfinite(noise) ? std::min(1.0, input.noise_factor * noise / std::max(moved, 1e-300)) : 0.0;
    flat(own) += scale * (fitted - flat(own));
    local.put(static_cast<size_t>(k), std::move(own));
    after.push_front(std::move(fitted));
    if (static_cast<int>(after.size()) > band) after.pop_back();
  }
}

}  // namespace facemorph
