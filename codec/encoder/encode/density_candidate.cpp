// The density-equalised disk as a candidate of the choice by bytes at equal error
// (density_candidate.hpp, spec/method.md §7.11, §7.14).
#include "codec/encoder/encode/density_candidate.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/encode/plan_keyframes.hpp"
#include "codec/encoder/encode/representation_rate.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <future>
#include <map>
#include <optional>

namespace facemorph {

bool density_candidate_possible(const EncodeOptions& options, const EncodeReport& report) {
  return !options.representation && options.grid == 0 && options.density_equalising.strength == 0 &&
         options.density_equalising.radial == kAutoRadial && report.radial_equalising == 0;
}

bool density_candidate_open(const EncodeOptions& options, const EncodeReport& report) {
  return density_candidate_possible(options, report) && report.representation_rate.measured;
}

DiskReparametrisation candidate_disk(const DiskMap& reference) {
  DensityEqualisingOptions equalising;
  equalising.strength = kCandidateDensityStrength;
  equalising.radial = 0;
  return DiskReparametrisation(reference, equalising);
}

int coarsest_within(std::vector<int> ns, int below, double worst_target, const std::function<double(int)>& floor_p99,
                    std::vector<std::pair<int, double>>* measured) {
  std::sort(ns.begin(), ns.end(), std::greater<int>());
  int coarsest = 0;
  for (const int n : ns) {
    if (n >= below) continue;
    const double p99 = floor_p99(n);
    if (measured) measured->emplace(measured->begin(), n, p99);
    if (!(p99 <= worst_target)) break;
    coarsest = n;
  }
  return coarsest;
}

int rung_between(const std::vector<std::pair<int, double>>& measured, int coarser, int finer, double worst_target) {
  if (coarser <= 0) return 0;
  const double middle = std::sqrt(double(coarser) * double(finer));
  int between = 0;
  for (const auto& [n, p99] : measured) {
    if (n <= coarser || n >= finer || !(p99 <= worst_target)) continue;
    if (between == 0 || std::abs(n - middle) < std::abs(between - middle)) between = n;
  }
  return between;
}

std::optional<RateCandidate> best_density_equalised(const RepresentationRate& rate) {
  std::vector<RateCandidate> on_d = {rate.candidates.front()};
  for (const RateCandidate& c : rate.candidates) {
    if (c.density_equalising > 0) on_d.push_back(c);
  }
  const size_t best = cheapest_at_equal_error(on_d, rate.tolerance, rate.worst_bound, rate.on_keyframes);
  return best > 0 ? std::optional<RateCandidate>(on_d[best]) : std::nullopt;
}

int rung_to_try_between(const RepresentationRate& rate, const std::vector<std::pair<int, double>>& measured, int coarser, int kept,
                        double worst_target) {
  const std::optional<RateCandidate> d = best_density_equalised(rate);
  if (!d || d->grid != kept) return 0;
  return rung_between(measured, coarser, kept, worst_target);
}

bool equalised_file_kept(uint64_t conformal_geometry, uint64_t conformal_texture, uint64_t equalised_geometry, uint64_t equalised_texture) {
  return equalised_geometry + equalised_texture <= conformal_geometry + conformal_texture;
}

namespace {

// The bytes the textures add to the file fmenc writes (its default texture coding), once the
// texture stage has run on `stored` (its qualities in `report`). Its texture groups' AV1 sequences
// are kept with it: the kept disk's file takes them as coded here.
uint64_t texture_file_bytes(const TextureSettings& settings, const StoredSequence& stored, const EncodeReport& report) {
  SequenceFileMetadata metadata;
  metadata.field_coding = report.field_coding;
  metadata.keyframe_texture_qualities = report.texture_qualities;
  metadata.texture_codec = settings.codec;
  return sequence_file_size(stored, metadata, &stored.coded_texture_groups()) - geometry_bytes(stored, report.field_coding);
}

}  // namespace

std::unique_ptr<StoredSequence> SequenceEncoder::choose_density_equalised(const StageSettings& settings, const KeyframeSelection& chosen,
                                                                          std::unique_ptr<StoredSequence> kept,
                                                                          const std::optional<std::vector<TriangleMesh>>& captured,
                                                                          std::future<DiskReparametrisation>* made_ahead) {
  report_.density_candidate = {};
  if (!density_candidate_open(options_, report_) || !captured) return kept;
  const auto start = std::chrono::steady_clock::now();
  RepresentationRate rate = report_.representation_rate;
  const EncodeReport before = report_;
  const int planned_n = rate.candidates.front().grid;
  const int kept_n = rate.candidates[rate.chosen].grid;

  // D as set_reference_geometry builds it for --density-equalising S, swapped in after the
  // registrations (they map the frames' conformal disks; D maps the reference's onto itself).
  const std::shared_ptr<const MappedFrame> reference = maps_.frame(options_.reference_frame);
  DiskReparametrisation conformal = registrations_.reparametrisation();
  DiskReparametrisation equalised = made_ahead && made_ahead->valid() ? made_ahead->get() : candidate_disk(reference->map);
  const DensityEqualisingReport equalised_report = equalised.report();
  registrations_.set_reparametrisation(std::move(equalised));

  // The resampled floor through D (the reference against G's surface sampled from it, as --grid
  // auto measures it on the conformal disk): the rounding's worst-region bound reads it at each N.
  EncodeReport::DensityCandidate candidate;
  candidate.strength = kCandidateDensityStrength;
  const FrameSampler sampler(maps_, registrations_);
  const auto floor_p99 = [&](int n) {
    for (const auto& [m, p99] : candidate.floor_p99s) {
      if (m == n) return p99;
    }
    const DiskGrid grid = make_disk_grid(n);
    // One N after another (coarsest_within reads each before the next): each on every thread.
    const SurfaceDistance d = surface_distance(
        reference->map.surface, grid_mesh(grid, sampler.sample_surface(*reference, options_.reference_frame, grid.nodes, settings.threads)),
        settings.threads);
    return d.p99 / d.diagonal;
  };
  std::vector<int> ns;
  for (const auto& [n, p99] : before.grid_floor_p99s) ns.push_back(n);
  const int coarser = coarsest_within(ns, kept_n, before.grid_worst_target, floor_p99, &candidate.floor_p99s);
  candidate.floor_p99s.emplace_back(kept_n, floor_p99(kept_n));

  struct Kept {
    std::unique_ptr<StoredSequence> sequence;
    EncodeReport report;
  };
  // The conformal candidate choose_by_bytes kept, and D's best once one wins.
  std::unique_ptr<StoredSequence> conformal_kept = std::move(kept);
  Kept best{nullptr, before};
  const FieldPrecisionOptions precision = field_precision_options(settings, chosen);
  // D's builds, once an N (candidate_builds.hpp): its best is tried again at the coarser step.
  CandidateBuilds builds(settings.build.spill_keyframes ? SpillMode::kSpill : SpillMode::kMemory, settings.threads);
  // Each keyframe's own floor through D, once an N (D's best is tried again at its N, at the coarser step).
  std::map<int, std::vector<double>> keyframe_floors;
  const auto floors_at = [&](int n) -> const std::vector<double>& {
    auto at = keyframe_floors.find(n);
    if (at == keyframe_floors.end()) at = keyframe_floors.emplace(n, keyframe_floor_p99s(plan_frames(*this), chosen.keyframes, n, settings.threads)).first;
    return at->second;
  };
  const auto try_candidate = [&](int n, double step_scale) {
    const std::shared_ptr<const GridGeometry> held = shared_grid_geometry(n);  // one G for its floors, build, rounding and decoders
    report_ = before;
    adopt_representation(Representation::kXYZ, before.blend);
    // The rounding's worst region bounded by D's floor at n (positions decode as sampled), the
    // plan's conformal floors restored for the report once rounded.
    report_.grid_floor_p99s = {{n, floor_p99(n)}};
    report_.grid_decoded_floors.clear();
    FieldPrecisionOptions scaled = precision;
    scaled.target_error *= step_scale;
    // Each keyframe's own floor through D (keyframe_precision's are the conformal disk's, kept by N).
    if (settings.plan.grid == 0 && settings.predicted_fields) scaled.keyframe_floors = floors_at(n);
    RateCandidate tried;
    tried.representation = Representation::kXYZ;
    tried.grid = n;
    tried.coarser = n != planned_n || step_scale != 1;
    tried.step_scale = step_scale;
    tried.density_equalising = kCandidateDensityStrength;
    const auto restore_floors = [&] {
      report_.grid_floor_p99s = before.grid_floor_p99s;
      report_.grid_decoded_floors = before.grid_decoded_floors;
    };
    if (std::unique_ptr<StoredSequence> sequence =
            measure_candidate(settings, chosen, builds, scaled, tried, *captured, rate, restore_floors))
      best = {std::move(sequence), report_};
  };
  try_candidate(kept_n, 1);
  // The coarsest N within the worst region's share, and where it lost to D at the kept N on bytes x
  // RMS² (its RMS grew more than its bytes fell) the rung between the two, which a measured floor
  // alone cannot place on that trade (ict60 before the rungs: D at 193 lost to 257; one encode more,
  // not one a rung).
  if (coarser != 0) {
    try_candidate(coarser, 1);
    const int between = rung_to_try_between(rate, candidate.floor_p99s, coarser, kept_n, before.grid_worst_target);
    if (between != 0) try_candidate(between, 1);
  }
  // D's best once more at the coarser field step, as choose_by_bytes tries the conformal disk's
  // (coarser_step_candidate), where a prediction's error is what the step is measured against: the
  // conformal disk's best has had its step tried, so D's is compared at the same step too (ict24: D at
  // N = 193 lost to the conformal disk's coarser step at 257 only for the step it had not tried).
  const std::optional<RateCandidate> d_best = best_density_equalised(rate);
  if (settings.predicted_fields && !rate.on_keyframes && d_best) try_candidate(d_best->grid, kCoarserStepScale);
  rate.chosen = cheapest_at_equal_error(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes);
  candidate.kept = rate.candidates[rate.chosen].density_equalising > 0;
  std::unique_ptr<StoredSequence> sequence = std::move(conformal_kept);
  report_ = before;
  if (candidate.kept && best.sequence->size() > 0 && !best.sequence->texture(0)->empty()) {
    // D won on geometry; the texture on each disk, as the texture stage codes it, decides (D's costs
    // more bytes at the same per-pixel PSNR: spec/method.md §7.11). Each disk's texture is sampled
    // through its own reparametrisation.
    // D's file is laid out (its AV1 sequences coded, one thread a group) on a thread of its own while
    // the conformal disk's texture stage runs: the same bytes, measured on Medusa 1.4 s of wall saved
    // (spec/method.md §3.3, *The encode's serial stretches*). One thread (--threads 1): in turn.
    const TextureFrameSource d_textures{capture_.frames, maps_, FrameSampler(maps_, registrations_)};
    candidate.equalised_geometry_bytes = rate.candidates[rate.chosen].bytes;
    std::vector<QualityCurve> d_curves;
    code_textures(settings.texture, d_textures, *best.sequence, chosen.keyframes, best.report, {}, &d_curves);
    const auto d_texture_bytes = [&] { return texture_file_bytes(settings.texture, *best.sequence, best.report); };
    std::future<uint64_t> d_bytes;
    if (settings.threads != 1) {
      d_bytes = std::async(std::launch::async, d_texture_bytes);
    } else {
      candidate.equalised_texture_bytes = d_texture_bytes();
    }
    DiskReparametrisation d_map = registrations_.reparametrisation();
    registrations_.set_reparametrisation(std::move(conformal));
    const TextureFrameSource conformal_textures{capture_.frames, maps_, FrameSampler(maps_, registrations_)};
    candidate.conformal_geometry_bytes = rate.candidates[before.representation_rate.chosen].bytes;
    // Each keyframe's quality search starts where its errors on D meet its target here: the same skin.
    code_textures(settings.texture, conformal_textures, *sequence, chosen.keyframes, report_, d_curves);
    candidate.conformal_texture_bytes = texture_file_bytes(settings.texture, *sequence, report_);
    if (d_bytes.valid()) candidate.equalised_texture_bytes = d_bytes.get();
    candidate.textures_coded = true;
    candidate.kept = equalised_file_kept(candidate.conformal_geometry_bytes, candidate.conformal_texture_bytes,
                                         candidate.equalised_geometry_bytes, candidate.equalised_texture_bytes);
    if (candidate.kept) {
      registrations_.set_reparametrisation(std::move(d_map));
    } else {
      rate.chosen = before.representation_rate.chosen;  // the registrations are on the conformal disk already
    }
  }
  if (candidate.kept) {
    sequence = std::move(best.sequence);
    report_ = std::move(best.report);
    const double half = report_.density_equalising.half_area_radius_before;
    report_.density_equalising = equalised_report;
    report_.density_equalising.half_area_radius_before = half;
  } else if (!candidate.textures_coded) {
    registrations_.set_reparametrisation(std::move(conformal));
  }
  adopt_representation(rate.candidates[rate.chosen].representation, before.blend);
  const double seconds = seconds_since(start);
  rate.seconds += seconds;
  report_.representation_rate = std::move(rate);
  report_.seconds_representation = before.seconds_representation + seconds;
  report_.density_candidate = std::move(candidate);
  return sequence;
}

}  // namespace facemorph
