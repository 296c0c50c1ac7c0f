// compare_blends: the hl+t fields and the positions of a few keyframes blended at frames between
// them, each against that frame (representation_choice.hpp).
#include "codec/encoder/encode/representation_choice.hpp"

#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <limits>
#include <memory>
#include <string>

namespace facemorph {

namespace {

double relative_distance(const std::vector<Face>& faces, const std::vector<Vec3>& blended, const std::vector<Vec3>& frame) {
  TriangleMesh a, b;
  a.positions = blended;
  a.faces = faces;
  b.positions = frame;
  b.faces = faces;
  const SurfaceDistance d = surface_distance(b, a);
  return d.rms / d.diagonal;
}

}  // namespace

BlendComparison compare_blends(const std::shared_ptr<const GridGeometry>& geometry, const std::vector<double>& key_times, SplineKind spline,
                               const std::vector<std::vector<Vec3>>& keys, const std::vector<BlendTrial>& trials, int threads) {
  const auto nodes = static_cast<size_t>(geometry->grid().node_count());
  if (keys.size() != key_times.size())
    throw Error(ErrorCode::kInvalidArgument, "compare_blends: keyframe surfaces and times differ in number");
  std::vector<int32_t> fixed;
  for (const std::vector<Vec3>& key : keys) {
    if (key.empty()) continue;
    if (key.size() != nodes) throw Error(ErrorCode::kInvalidArgument, "compare_blends: a keyframe surface is not on G");
    const std::vector<int32_t> folds = folded_nodes(*geometry, key);
    fixed.insert(fixed.end(), folds.begin(), folds.end());
  }
  std::sort(fixed.begin(), fixed.end());
  fixed.erase(std::unique(fixed.begin(), fixed.end()), fixed.end());
  std::vector<GridFields> fields(keys.size());
  parallel_for(static_cast<int>(keys.size()), threads, [&](int k) {
    const auto index = static_cast<size_t>(k);
    if (!keys[index].empty()) fields[index] = compute_fields(*geometry, keys[index], Representation::kHLT, fixed);
  });
  const KeyframeSpline weights_of(key_times, spline);
  std::vector<double> fields_error(trials.size()), positions_error(trials.size());
  std::vector<char> converged(trials.size(), 1);
  parallel_for(static_cast<int>(trials.size()), threads, [&](int t) {
    const BlendTrial& trial = trials[static_cast<size_t>(t)];
    if (trial.surface.size() != nodes) throw Error(ErrorCode::kInvalidArgument, "compare_blends: a trial surface is not on G");
    const SplineWeights w = weights_of.weights(trial.time);
    std::vector<const GridFields*> blended_keys;
    std::vector<Vec3> positions(nodes, Vec3::Zero());
    for (size_t j = 0; j < w.keys.size(); ++j) {
      const auto k = static_cast<size_t>(w.keys[j]);
      if (keys[k].empty())
        throw Error(ErrorCode::kInvalidArgument,
                    "compare_blends: the trial at " + std::to_string(trial.time) + " needs keyframe " + std::to_string(k));
      blended_keys.push_back(&fields[k]);
      for (size_t v = 0; v < nodes; ++v) positions[v] += w.weights[j] * keys[k][v];
    }
    positions_error[static_cast<size_t>(t)] = relative_distance(geometry->grid().faces, positions, trial.surface);
    Reconstructor reconstructor(geometry);  // one per trial (kBlendTrials at most), on the shared G
    ReconstructOptions options;
    options.throw_on_failure = false;
    // From the blended positions, as the decoder starts a frame from the spline of its keyframes'
    // decoded surfaces: the same fixed point in fewer steps.
    options.start = &positions;
    try {
      const ReconstructResult decoded = reconstructor.reconstruct(combine_fields(blended_keys, w.weights), options);
      converged[static_cast<size_t>(t)] = decoded.converged;
      fields_error[static_cast<size_t>(t)] = relative_distance(geometry->grid().faces, decoded.positions, trial.surface);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::kNumerical) throw;
      converged[static_cast<size_t>(t)] = 0;  // the blend diverged: no surface at all
      fields_error[static_cast<size_t>(t)] = std::numeric_limits<double>::infinity();
    }
  });
  BlendComparison out;
  out.trials = static_cast<int>(trials.size());
  for (size_t t = 0; t < trials.size(); ++t) {
    out.fields_error += fields_error[t] / static_cast<double>(trials.size());
    out.positions_error += positions_error[t] / static_cast<double>(trials.size());
    out.not_converged += converged[t] ? 0 : 1;
  }
  return out;
}

}  // namespace facemorph
