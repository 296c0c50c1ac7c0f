// Residual frames fitted to what the decoder shows (spec/method.md §7.18).
#include "codec/encoder/encode/residual_fit.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/encoder/encode/decoder_team.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/keyframes/blend_correction.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "format/error.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>

namespace facemorph {

namespace {

// A frame between keyframes as G samples it: its registered surface's normals and area weights at
// G's interior nodes, and its bbox diagonal.
struct CapturedOnGrid {
  std::vector<Vec3> positions;  // every node of G, capture frame
  std::vector<Vec3> normals;    // interior nodes
  std::vector<double> weights;  // interior nodes: lumped disk mass × λ², the surface area about each
  double total_weight = 0;
  double diagonal = 1;
};

CapturedOnGrid captured_on_grid(const RegisteredFrames& frames, const GridGeometry& geometry, int frame) {
  CapturedOnGrid c;
  c.positions = frames.surface(frame, geometry.grid().nodes);
  std::vector<Vec3> tu, tv;
  geometry.frames(c.positions, tu, tv, c.normals);
  const std::vector<double> lambda2 = geometry.conformal_factor_squared(c.positions);
  c.weights.resize(lambda2.size());
  for (size_t v = 0; v < lambda2.size(); ++v) {
    c.weights[v] = geometry.mass()[static_cast<Eigen::Index>(v)] * lambda2[v];
    c.total_weight += c.weights[v];
  }
  c.diagonal = frames.diagonals[static_cast<size_t>(frame)];
  return c;
}

// The decoded surface's offsets from the captured one along its normals, at the interior nodes.
std::vector<double> normal_offsets(const std::vector<Vec3>& decoded, const CapturedOnGrid& c) {
  std::vector<double> o(c.normals.size());
  for (size_t v = 0; v < o.size(); ++v) o[v] = (decoded[v] - c.positions[v]).dot(c.normals[v]);
  return o;
}

double relative_rms(double weighted_squares, const CapturedOnGrid& c) {
  return std::sqrt(weighted_squares / std::max(c.total_weight, 1e-300)) / c.diagonal;
}

double relative_rms(const std::vector<double>& offsets, const CapturedOnGrid& c) {
  double sum = 0;
  for (size_t v = 0; v < offsets.size(); ++v) sum += c.weights[v] * offsets[v] * offsets[v];
  return relative_rms(sum, c);
}

DecodeOptions shape_only() {
  DecodeOptions o;
  o.texture = false;
  o.cut_holes = false;
  o.continue_correction = false;  // each frame a function of t alone, as measured
  return o;
}

}  // namespace

std::vector<ResidualFrame> fit_decoded_residuals(const RegisteredFrames& frames, StoredSequence& stored, const std::vector<int>& keyframes,
                                                 double step, ResidualFitReport* report_out, int threads) {
  const auto start = std::chrono::steady_clock::now();
  ResidualFitReport report;
  stored.set_residuals({});
  const std::vector<double>& key_times = stored.outline().times;
  if (key_times.size() != keyframes.size())
    throw Error(ErrorCode::kInvalidArgument, "fit_decoded_residuals: the keyframes are not the stored sequence's");
  // Frames strictly between the first and last keyframe, not keyframes themselves: interval i of each.
  std::vector<int> held, interval;
  for (int j = keyframes.front() + 1; j < keyframes.back(); ++j) {
    const int i = residual_interval(key_times, frames.times[static_cast<size_t>(j)]);
    if (i < 0) continue;
    held.push_back(j);
    interval.push_back(i);
  }
  if (held.empty() || keyframes.size() < 2) {
    if (report_out) *report_out = report;
    return {};
  }
  const std::shared_ptr<const KeyframeSource> source(std::shared_ptr<void>(), &stored);  // not owned
  DecoderTeam plain(source, threads, held.size());
  const GridGeometry& geometry = plain.first().geometry();
  const DecodeOptions options = shape_only();
  // The keyframes' decoded surfaces in their face frames: what the decoder blends.
  std::vector<std::vector<Vec3>> local(keyframes.size());
  plain.for_each(keyframes.size(), [&](SequenceDecoder& decoder, size_t k) {
    const DecodedFrame f = decoder.decode(key_times[k], options);
    const RigidPose to_face = f.pose.inverse();
    local[k].reserve(f.grid_positions.size());
    for (const Vec3& p : f.grid_positions) local[k].push_back(to_face.apply(p));
  });
  // Pass 1: each frame decoded with the spline alone, its correction fitted.
  std::vector<ResidualFrame> candidates(held.size());
  std::vector<double> before(held.size(), 0.0);
  std::vector<char> fitted(held.size(), 0), tried(held.size(), 0);
  plain.for_each(held.size(), [&](SequenceDecoder& decoder, size_t h) {
    const int j = held[h];
    const double t = frames.times[static_cast<size_t>(j)];
    const DecodedFrame decoded = decoder.decode(t, options);
    const CapturedOnGrid captured = captured_on_grid(frames, geometry, j);
    const std::vector<double> offsets = normal_offsets(decoded.grid_positions, captured);
    before[h] = relative_rms(offsets, captured);
    const KeyWindow window = residual_window(interval[h], static_cast<int>(keyframes.size()));
    std::vector<double> delta(static_cast<size_t>(window.count), 0.0);
    if (before[h] > kResidualFloor && window.count >= 2) {
      std::vector<std::vector<double>> columns(static_cast<size_t>(window.count), std::vector<double>(offsets.size()));
      for (int m = 0; m < window.count; ++m) {
        const std::vector<Vec3>& key = local[static_cast<size_t>(window.first + m)];
        for (size_t v = 0; v < offsets.size(); ++v)
          columns[static_cast<size_t>(m)][v] = (decoded.pose.rotation * key[v]).dot(captured.normals[v]);
      }
      const double predicted = relative_rms(fit_blend_correction(offsets, columns, captured.weights, step, delta), captured);
      tried[h] = 1;
      if (!(predicted <= (1 - kDecodedResidualMinGain) * before[h])) std::fill(delta.begin(), delta.end(), 0.0);
      fitted[h] = std::any_of(delta.begin(), delta.end(), [](double d) { return d != 0; });
    }
    candidates[h] = {t, std::move(delta)};
  });
  report.frames_fitted = static_cast<int>(std::count(tried.begin(), tried.end(), 1));
  // Pass 2: the frames decoded with their corrections, at the times the file holds.
  const double first_time = stored.shape().first_time, fps = stored.shape().fps;
  std::vector<ResidualFrame> on_file;
  std::vector<size_t> node_of(held.size(), SIZE_MAX);  // frame h's residual in `on_file`
  {
    std::vector<ResidualFrame> moved = residuals_on_file_times(candidates, key_times, first_time, fps);
    size_t r = 0;
    for (size_t h = 0; h < held.size() && r < moved.size(); ++h) {
      if (std::abs(moved[r].time - candidates[h].time) * fps * kResidualTimeSteps <= 0.5 + 1e-9) node_of[h] = r++;
    }
    on_file = std::move(moved);
  }
  std::vector<double> after = before;
  if (std::any_of(fitted.begin(), fitted.end(), [](char c) { return c != 0; })) {
    stored.set_residuals(on_file);
    DecoderTeam corrected(source, threads, held.size());
    std::vector<double> decoded_error(held.size(), 0.0);
    corrected.for_each(held.size(), [&](SequenceDecoder& decoder, size_t h) {
      if (!fitted[h]) return;
      const int j = held[h];
      const DecodedFrame decoded = decoder.decode(frames.times[static_cast<size_t>(j)], options);
      const CapturedOnGrid captured = captured_on_grid(frames, geometry, j);
      decoded_error[h] = relative_rms(normal_offsets(decoded.grid_positions, captured), captured);
    });
    for (size_t h = 0; h < held.size(); ++h) {
      if (!fitted[h]) continue;
      if (decoded_error[h] <= (1 - kDecodedResidualMinGain) * before[h]) {
        after[h] = decoded_error[h];
        ++report.frames_improved;
      } else {
        ++report.frames_worse;
        fitted[h] = 0;
      }
    }
    stored.set_residuals({});
  }
  // Corrections decoded worse set to 0; an interval keeps its residuals only where one is kept.
  std::vector<char> interval_kept(keyframes.size(), 0);
  for (size_t h = 0; h < held.size(); ++h) interval_kept[static_cast<size_t>(interval[h])] |= fitted[h];
  std::vector<ResidualFrame> out;
  for (size_t h = 0; h < held.size(); ++h) {
    if (node_of[h] == SIZE_MAX || !interval_kept[static_cast<size_t>(interval[h])]) continue;
    ResidualFrame f = on_file[node_of[h]];
    if (!fitted[h]) std::fill(f.delta.begin(), f.delta.end(), 0.0);
    out.push_back(std::move(f));
  }
  report.residuals = static_cast<int>(out.size());
  for (size_t h = 0; h < held.size(); ++h) {
    report.mean_before += before[h] / static_cast<double>(held.size());
    report.mean_after += after[h] / static_cast<double>(held.size());
    report.worst_before = std::max(report.worst_before, before[h]);
    report.worst_after = std::max(report.worst_after, after[h]);
  }
  report.seconds = seconds_since(start);
  if (report_out) *report_out = report;
  return out;
}

}  // namespace facemorph
