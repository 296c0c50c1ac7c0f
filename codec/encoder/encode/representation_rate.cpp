// The representation and N chosen by bytes at equal error: the measures and the rule
// (representation_rate.hpp, spec/method.md §7.14).
#include "codec/encoder/encode/representation_rate.hpp"

#include "format/error.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/decoder_team.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>

namespace facemorph {

double rate_cost(const RateCandidate& candidate) {
  if (candidate.frames <= 0 || !(candidate.held_rms > 0) || candidate.bytes == 0) return std::numeric_limits<double>::infinity();
  return static_cast<double>(candidate.bytes) * std::pow(candidate.held_rms, kRateErrorExponent);
}

Representation cheaper_at_equal_error(const RateCandidate& fields, const RateCandidate& positions) {
  return rate_cost(positions) < rate_cost(fields) ? Representation::kXYZ : Representation::kHLT;
}

size_t cheapest_at_equal_error(const std::vector<RateCandidate>& candidates, double tolerance) {
  size_t best = 0;
  for (size_t i = 1; i < candidates.size(); ++i) {
    const RateCandidate& c = candidates[i];
    if (c.coarser && !(c.held_rms <= tolerance)) continue;
    if (rate_cost(c) < rate_cost(candidates[best])) best = i;
  }
  return best;
}

int worst_region_grid(const std::vector<std::pair<int, double>>& floor_p99s, double worst_target, int grid) {
  int coarsest = 0;
  for (const auto& [n, p99] : floor_p99s) {
    if (n < grid && p99 <= worst_target && (coarsest == 0 || n < coarsest)) coarsest = n;
  }
  return coarsest;
}

std::vector<std::pair<Representation, int>> rate_candidates(int grid, int coarser, double coarser_fields_p99, double worst_target) {
  std::vector<std::pair<Representation, int>> others{{Representation::kXYZ, grid}};
  if (coarser <= 0) return others;
  if (coarser_fields_p99 <= worst_target) others.emplace_back(Representation::kHLT, coarser);
  others.emplace_back(Representation::kXYZ, coarser);
  return others;
}

std::vector<int> rate_trial_frames(const std::vector<int>& keyframes) {
  std::vector<int> between;
  for (size_t k = 0; k + 1 < keyframes.size(); ++k)
    for (int i = keyframes[k] + 1; i < keyframes[k + 1]; ++i) between.push_back(i);
  if (between.size() <= static_cast<size_t>(kRateTrials)) return between;
  std::vector<int> spread;
  for (int t = 0; t < kRateTrials; ++t)
    spread.push_back(between[static_cast<size_t>(t) * (between.size() - 1) / static_cast<size_t>(kRateTrials - 1)]);
  return spread;
}

namespace {

// The stored keyframes without their textures: what the two representations store differently.
class GeometryOnly final : public KeyframeSource {
 public:
  explicit GeometryOnly(const StoredSequence& stored) : stored_(stored), outline_(stored.outline()) { outline_.texture_size = 0; }
  const SequenceOutline& outline() const override { return outline_; }
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override { return stored_.keyframe(k); }
  std::shared_ptr<const Image> texture(size_t) const override {
    throw Error(ErrorCode::kInternal, "the representation's bytes: the geometry has no textures");
  }
  size_t surfaces_kept() const override { return 1; }
  uint64_t bytes_held() const override { return 0; }

 private:
  const StoredSequence& stored_;
  SequenceOutline outline_;
};

DecodeOptions measured_decode() {
  DecodeOptions o;
  o.texture = false;
  o.ignore_sane_range = true;
  o.continue_correction = false;  // each frame a function of t alone
  o.reconstruct.throw_on_failure = false;
  return o;
}

}  // namespace

uint64_t geometry_bytes(const StoredSequence& stored, const FieldCoding& coding) {
  SequenceFileMetadata metadata;
  metadata.field_coding = coding;
  return sequence_file_size(GeometryOnly(stored), metadata);
}

std::optional<double> held_out_rms(const Capture& capture, const StoredSequence& stored, const std::vector<int>& frames, int threads) {
  if (frames.empty()) return std::nullopt;
  for (const int i : frames) {
    std::error_code ec;
    if (static_cast<size_t>(i) >= capture.frames.size() || !std::filesystem::is_regular_file(capture.mesh_path(static_cast<size_t>(i)), ec))
      return std::nullopt;
  }
  const std::shared_ptr<const KeyframeSource> source(std::shared_ptr<void>(), &stored);  // not owned
  DecoderTeam team(source, threads, frames.size());
  const DiskGrid& grid = team.first().geometry().grid();
  const DecodeOptions options = measured_decode();
  std::vector<double> rms(frames.size(), 0);
  team.for_each(frames.size(), [&](SequenceDecoder& decoder, size_t j) {
    const auto i = static_cast<size_t>(frames[j]);
    const DecodedFrame decoded = decoder.decode(capture.frames[i].time, options);
    const TriangleMesh captured = read_mesh(capture.mesh_path(i), {.allow_missing_texture = true});
    const SurfaceDistance d = surface_distance(captured, shown_mesh(grid, decoded.grid_positions, decoded.hole_level));
    rms[j] = d.diagonal > 0 ? d.rms / d.diagonal : 0;
  });
  double sum = 0;
  for (const double r : rms) sum += r;
  return sum / static_cast<double>(rms.size());
}

}  // namespace facemorph
