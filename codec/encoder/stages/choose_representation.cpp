// What the keyframes store when the options leave it open, first step: xyz where the fields blended
// between keyframes come out farther from the frames than the blended positions, else hl+t until
// SequenceEncoder::choose_by_bytes has measured both candidates' bytes at equal error
// (spec/method.md §7.14).
#include "codec/encoder/encode/plan_keyframes.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/representation_choice.hpp"

#include <memory>
#include <vector>

namespace facemorph {

std::vector<size_t> blend_trial_pairs(const std::vector<int>& keyframes) {
  std::vector<size_t> pairs;
  for (size_t k = 0; k + 1 < keyframes.size(); ++k) {
    if (keyframes[k + 1] - keyframes[k] >= 2) pairs.push_back(k);
  }
  if (pairs.size() <= static_cast<size_t>(kBlendTrials)) return pairs;
  std::vector<size_t> spread;
  for (int t = 0; t < kBlendTrials; ++t)
    spread.push_back(pairs[static_cast<size_t>(t) * (pairs.size() - 1) / static_cast<size_t>(kBlendTrials - 1)]);
  return spread;
}

Representation representation_for(const BlendComparison& blend) {
  return blend.trials > 0 && blend.fields_error > kFieldsBlendMargin * blend.positions_error ? Representation::kXYZ : Representation::kHLT;
}

RepresentationDecision choose_representation(const PlanSettings& settings, const PlanFrames& plan, const KeyframeSelection& chosen,
                                             int grid, EncodeReport& report) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<CaptureFrame>& frames = plan.frames;
  Representation choice = Representation::kHLT;
  BlendComparison blend;
  const std::vector<int>& keyframes = chosen.keyframes;
  const bool unmatched = 2 * report.frames_without_interior_landmarks > static_cast<int>(frames.size()) - 1;
  // On a radially reparametrised disk (a whole head) hl+t's fixed-point iteration diverges: the
  // tangential part of Δ_h S, large where the map stretches the disk unevenly, turns with the frame
  // it is carried in (measured on fmsynth --head at radial strengths 0.25 to 1: no keyframe converged).
  // Positions decode without iterating, and the container holds them (spec/method.md §7.11).
  if (!settings.representation && report.radial_equalising > 0) {
    choice = Representation::kXYZ;
  } else if (!settings.representation && unmatched && keyframes.size() >= 2) {
    // The frame midway between each pair of keyframes with frames between them (blend_trial_pairs).
    const std::vector<size_t> pairs = blend_trial_pairs(keyframes);
    std::vector<double> times;
    for (int k : keyframes) times.push_back(frames[static_cast<size_t>(k)].time);
    const KeyframeSpline spline(times, settings.selection.spline);
    std::vector<int> midway, needed_keys;
    std::vector<char> needed(keyframes.size(), 0);
    for (size_t k : pairs) {
      midway.push_back((keyframes[k] + keyframes[k + 1]) / 2);
      for (int32_t key : spline.weights(frames[static_cast<size_t>(midway.back())].time).keys) needed[static_cast<size_t>(key)] = 1;
    }
    for (size_t k = 0; k < keyframes.size(); ++k) {
      if (needed[k]) needed_keys.push_back(static_cast<int>(k));
    }
    if (!pairs.empty()) {
      const auto geometry = shared_grid_geometry(grid);
      // A frame's registered surface on G in the face frame (as build_keyframes samples a keyframe).
      auto local_surface = [&](int i) {
        std::vector<Vec3> surface = plan.sampler.sample_surface(i, geometry->grid().nodes);
        const RigidPose to_face = plan.selection.frames()[static_cast<size_t>(i)].pose.inverse();
        for (Vec3& p : surface) p = to_face.apply(p);
        return surface;
      };
      std::vector<std::vector<Vec3>> keys(keyframes.size());
      std::vector<BlendTrial> trials(pairs.size());
      parallel_for(static_cast<int>(needed_keys.size() + pairs.size()), settings.threads, [&](int j) {
        const auto index = static_cast<size_t>(j);
        if (index < needed_keys.size()) {
          const auto k = static_cast<size_t>(needed_keys[index]);
          keys[k] = local_surface(keyframes[k]);
        } else {
          const size_t t = index - needed_keys.size();
          trials[t].time = frames[static_cast<size_t>(midway[t])].time;
          trials[t].surface = local_surface(midway[t]);
        }
      });
      blend = compare_blends(geometry, times, settings.selection.spline, keys, trials, settings.threads);
      choice = representation_for(blend);
    }
  }
  report.seconds_representation = seconds_since(start);
  return {choice, blend};
}

}  // namespace facemorph
