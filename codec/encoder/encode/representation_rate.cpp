// The representation and N chosen by bytes at equal error: the measures and the rule
// (representation_rate.hpp, spec/method.md §7.14).
#include "codec/encoder/encode/representation_rate.hpp"

#include "format/error.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/decoder_team.hpp"
#include "codec/encoder/encode/geometry_trial_source.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>

namespace facemorph {

double rate_cost(const RateCandidate& candidate, double tolerance) {
  if (candidate.frames <= 0 || !(candidate.held_rms > 0) || candidate.bytes == 0) return std::numeric_limits<double>::infinity();
  const double error = std::max(candidate.held_rms, kUnboughtErrorShare * tolerance);
  return static_cast<double>(candidate.bytes) * std::pow(error, kRateErrorExponent);
}

Representation cheaper_at_equal_error(const RateCandidate& fields, const RateCandidate& positions) {
  return rate_cost(positions) < rate_cost(fields) ? Representation::kXYZ : Representation::kHLT;
}

bool admitted_worst_region(const RateCandidate& candidate, const RateCandidate& first, double worst_bound) {
  const double rise = worst_bound > 0 ? kWorstRegionRise : 1;
  return candidate.worst_p99 <= worst_bound || candidate.worst_p99 <= first.worst_p99 * rise;
}

bool buys_only_error_below_the_target(const RateCandidate& candidate, const RateCandidate& first, bool on_keyframes) {
  return on_keyframes && candidate.bytes > first.bytes;
}

bool coarser_within_tolerance(const std::vector<RateCandidate>& candidates, size_t i, double tolerance) {
  const RateCandidate& candidate = candidates.at(i);
  if (!candidate.coarser || candidate.held_rms <= tolerance) return true;
  double lowest_at_n = std::numeric_limits<double>::infinity();
  for (size_t j = 0; j < i; ++j) {
    if (!candidates[j].coarser) lowest_at_n = std::min(lowest_at_n, candidates[j].held_rms);
  }
  return candidate.held_rms <= lowest_at_n;
}

size_t cheapest_at_equal_error(const std::vector<RateCandidate>& candidates, double tolerance, double worst_bound, bool on_keyframes) {
  size_t best = 0;
  for (size_t i = 1; i < candidates.size(); ++i) {
    const RateCandidate& c = candidates[i];
    if (!coarser_within_tolerance(candidates, i, tolerance)) continue;
    if (!admitted_worst_region(c, candidates.front(), worst_bound)) continue;
    if (buys_only_error_below_the_target(c, candidates.front(), on_keyframes)) continue;
    if (rate_cost(c, tolerance) < rate_cost(candidates[best], tolerance)) best = i;
  }
  return best;
}

bool add_candidate(RepresentationRate& rate, const RateCandidate& candidate) {
  rate.candidates.push_back(candidate);
  return cheapest_at_equal_error(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes) == rate.candidates.size() - 1;
}

RateCandidate coarser_step_candidate(const std::vector<RateCandidate>& candidates, double tolerance, double worst_bound, bool on_keyframes) {
  RateCandidate again = candidates.at(cheapest_at_equal_error(candidates, tolerance, worst_bound, on_keyframes));
  again.coarser = true;
  again.step_scale = kCoarserStepScale;
  again.bytes = 0;
  again.held_rms = 0;
  again.frames = 0;
  again.worst_p99 = 0;
  return again;
}

int worst_region_grid(const std::vector<std::pair<int, double>>& floor_p99s, double worst_target, int grid) {
  int coarsest = 0;
  for (const auto& [n, p99] : floor_p99s) {
    if (n < grid && p99 <= worst_target && (coarsest == 0 || n < coarsest)) coarsest = n;
  }
  return coarsest;
}

std::vector<int> rate_trial_frames(const std::vector<int>& keyframes) {
  std::vector<int> between;
  for (size_t k = 0; k + 1 < keyframes.size(); ++k)
    for (int i = keyframes[k] + 1; i < keyframes[k + 1]; ++i) between.push_back(i);
  // No frame between keyframes (one frame, or every frame a keyframe): the keyframes themselves,
  // each decoded against its captured frame (fmbench's keyframe RMS), so that such a capture is
  // chosen for by the same rule rather than left hl+t (spec/method.md §7.14).
  const std::vector<int>& frames = between.empty() ? keyframes : between;
  if (frames.size() <= static_cast<size_t>(kRateTrials)) return frames;
  std::vector<int> spread;
  for (int t = 0; t < kRateTrials; ++t)
    spread.push_back(frames[static_cast<size_t>(t) * (frames.size() - 1) / static_cast<size_t>(kRateTrials - 1)]);
  return spread;
}

namespace {

// The stored keyframes as they are (textures left out): what the two representations store differently.
class GeometryOnly final : public GeometryTrialSource {
 public:
  explicit GeometryOnly(const StoredSequence& stored) : GeometryTrialSource(stored.outline(), "the representation's bytes"), stored_(stored) {}
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override { return stored_.keyframe(k); }

 private:
  const StoredSequence& stored_;
};

}  // namespace

uint64_t geometry_bytes(const StoredSequence& stored, const FieldCoding& coding) {
  SequenceFileMetadata metadata;
  metadata.field_coding = coding;
  return sequence_file_size(GeometryOnly(stored), metadata);
}

std::optional<std::vector<TriangleMesh>> trial_meshes(const Capture& capture, const std::vector<int>& frames, int threads) {
  if (frames.empty()) return std::nullopt;
  for (const int i : frames) {
    std::error_code ec;
    if (static_cast<size_t>(i) >= capture.frames.size() || !std::filesystem::is_regular_file(capture.mesh_path(static_cast<size_t>(i)), ec))
      return std::nullopt;
  }
  std::vector<TriangleMesh> meshes(frames.size());
  parallel_for(static_cast<int>(frames.size()), threads, [&](int j) {
    meshes[static_cast<size_t>(j)] = read_mesh(capture.mesh_path(static_cast<size_t>(frames[static_cast<size_t>(j)])), {.allow_missing_texture = true});
  });
  return meshes;
}

HeldOutError held_out_error(const Capture& capture, const StoredSequence& stored, const std::vector<int>& frames,
                            const std::vector<TriangleMesh>& captured, int threads) {
  if (frames.empty() || captured.size() != frames.size())
    throw Error(ErrorCode::kInvalidArgument, "held_out_error: one captured mesh for each trial frame");
  const std::shared_ptr<const KeyframeSource> source(std::shared_ptr<void>(), &stored);  // not owned
  DecoderTeam team(source, threads, frames.size());
  const DiskGrid& grid = team.first().geometry().grid();
  const DecodeOptions options = shown_decode();
  std::vector<double> rms(frames.size(), 0), p99(frames.size(), 0);
  team.for_each(frames.size(), [&](SequenceDecoder& decoder, size_t j) {
    const DecodedFrame decoded = decoder.decode(capture.frames[static_cast<size_t>(frames[j])].time, options);
    const SurfaceDistance d = surface_distance(captured[j], shown_mesh(grid, decoded.grid_positions, decoded.hole_level));
    rms[j] = d.diagonal > 0 ? d.rms / d.diagonal : 0;
    p99[j] = d.diagonal > 0 ? d.p99 / d.diagonal : 0;
  });
  HeldOutError error;
  for (const double r : rms) error.rms += r;
  error.rms /= static_cast<double>(rms.size());
  error.worst_p99 = *std::max_element(p99.begin(), p99.end());
  return error;
}

std::vector<std::pair<Representation, int>> coarser_candidates(const std::vector<RateCandidate>& at_grid, double tolerance,
                                                               double worst_bound, bool on_keyframes, int coarser,
                                                               const std::function<double()>& coarser_fields_p99, double worst_target) {
  if (coarser <= 0 || at_grid.empty()) return {};
  const Representation winner = at_grid[cheapest_at_equal_error(at_grid, tolerance, worst_bound, on_keyframes)].representation;
  if (winner == Representation::kHLT && !(coarser_fields_p99() <= worst_target)) return {{Representation::kXYZ, coarser}};
  return {{winner, coarser}};
}

}  // namespace facemorph
