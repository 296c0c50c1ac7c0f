// The encoder's driver: SequenceEncoder's state (its capture, stores and the frames' maps and
// registrations as every stage reads them back) and the encode run stage by stage — map
// (stages/map_frames.cpp), register (register_frames.cpp), sample and select (sample_frames.cpp),
// plan (choose_grid.cpp, choose_representation.cpp), build and fit (build_keyframes.cpp,
// fit_keyframes.cpp), precision (round_fields.cpp), texture (texture_coding.cpp) — for the
// one-process encode and the staged and segmented encodes alike.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/encoder/encode/representation_rate.hpp"

#include "codec/encoder/encode/density_candidate.hpp"

#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/encode/spill_bytes.hpp"

#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/residual_fit.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "format/error.hpp"

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <cmath>
#include <functional>
#include <future>
#include <limits>
#include <numeric>
#include <optional>

namespace facemorph {

std::unique_ptr<SpilledItems<std::vector<Vec3>>> make_landmark_store(SpillMode mode) {
  return std::make_unique<SpilledItems<std::vector<Vec3>>>(
      mode, "the frames' landmarks", "landmarks of frame",
      [](const std::vector<Vec3>& points) {
        spill::Writer w;
        w.array(points);
        return w.take();
      },
      [](const char* bytes, size_t size) {
        spill::Reader r(bytes, size, "the frames' landmarks: a stored frame");
        std::vector<Vec3> points = r.array<Vec3>();
        if (!r.done()) throw Error(ErrorCode::kInternal, "the frames' landmarks: a stored frame has bytes left over");
        return points;
      });
}

SequenceEncoder::SequenceEncoder(Capture capture, EncodeOptions options) : capture_(std::move(capture)), options_(std::move(options)) {
  const int count = frame_count();
  if (count == 0) throw Error(ErrorCode::kInvalidArgument, "the capture has no frames");
  if (capture_.landmarks.empty())
    capture_.landmarks.resize(capture_.frames.size(), std::vector<Vec3>(capture_.landmark_names.size(), Vec3::Constant(std::nan(""))));
  if (capture_.landmarks.size() != capture_.frames.size()) {
    throw Error(ErrorCode::kInvalidArgument, "the capture has landmarks for " + std::to_string(capture_.landmarks.size()) + " of its " +
                                                 std::to_string(count) + " frames");
  }
  // The landmarks leave the capture for a store: 1.8 kB a frame of ICT's 74, which kept in memory
  // grew with the capture for the whole encode.
  landmarks_ = make_landmark_store(options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
  landmarks_->reset(capture_.landmarks.size());
  for (size_t i = 0; i < capture_.landmarks.size(); ++i) landmarks_->put(i, std::move(capture_.landmarks[i]));
  capture_.landmarks = {};
  source_index_.resize(static_cast<size_t>(count));
  std::iota(source_index_.begin(), source_index_.end(), 0);
  first_time_ = capture_.frames.front().time;
  last_time_ = capture_.frames.back().time;
  given_reference_ = options_.reference_frame;
  check_encode_options(options_, count);
}

std::vector<Vec3> SequenceEncoder::landmarks(int i) const {
  std::vector<Vec3> points = *landmarks_->get(static_cast<size_t>(i));
  // Names adopted after the frame's points were stored (adopt_found_landmarks) it lacks.
  points.resize(capture_.landmark_names.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  return points;
}

void SequenceEncoder::put_landmarks(int i, std::vector<Vec3> points) { landmarks_->put(static_cast<size_t>(i), std::move(points)); }

size_t SequenceEncoder::landmark_name_index(const std::string& name) {
  const int index = capture_.landmark_index(name);
  if (index >= 0) return static_cast<size_t>(index);
  capture_.landmark_names.push_back(name);
  return capture_.landmark_names.size() - 1;
}

void SequenceEncoder::add_frame_warnings(int i, std::vector<std::string> warnings) {
  report_.warnings.insert(report_.warnings.end(), warnings.begin(), warnings.end());
  if (!warnings.empty()) warnings_by_frame_[source_index_[static_cast<size_t>(i)]] = std::move(warnings);
}

FrameFailure frame_failure(const Error& e, const std::string& name) {
  // Stages name their frame; the report names it once.
  std::string reason = e.what();
  if (reason.rfind(name + ": ", 0) == 0) reason.erase(0, name.size() + 2);
  return {e.code(), reason};
}

void SequenceEncoder::drop_frames(const std::vector<FrameFailure>& failures) {
  std::vector<size_t> kept;
  for (size_t i = 0; i < failures.size(); ++i) {
    if (failures[i].code == ErrorCode::kOk) {
      kept.push_back(i);
      continue;
    }
    report_.dropped.push_back({source_index_[i], capture_.frames[i].mesh.string(), capture_.frames[i].time, failures[i].reason});
    // Dropped at registration, the frame was mapped: its summary still counts in what was found.
    const std::vector<FrameSummary>& summaries = maps_.summaries;
    if (summaries.size() == failures.size() && !summaries[i].name.empty()) dropped_summaries_[source_index_[i]] = summaries[i];
  }
  if (kept.size() == failures.size()) return;
  if (kept.empty()) {
    const DroppedFrame& first = report_.dropped.front();
    const auto it = std::find_if(failures.begin(), failures.end(), [](const FrameFailure& f) { return f.code != ErrorCode::kOk; });
    throw Error(it->code, "no frame of the capture could be encoded (" + std::to_string(failures.size()) + " dropped); the first, " +
                              first.name + ": " + first.reason);
  }
  // The reference moves to the nearest frame kept (the earlier of two as near).
  const auto reference = static_cast<size_t>(options_.reference_frame);
  size_t new_reference = 0;
  for (size_t k = 0; k < kept.size(); ++k) {
    const double d = std::abs(capture_.frames[kept[k]].time - capture_.frames[reference].time);
    if (d < std::abs(capture_.frames[kept[new_reference]].time - capture_.frames[reference].time)) new_reference = k;
  }
  if (kept[new_reference] != reference) {
    report_.warnings.push_back(capture_.frames[reference].mesh.string() + ": the reference frame was dropped; " +
                               capture_.frames[kept[new_reference]].mesh.string() + " is the reference instead");
  }
  options_.reference_frame = static_cast<int>(new_reference);
  auto compact = [&](auto& items) {
    if (items.size() != failures.size()) return;
    std::remove_reference_t<decltype(items)> out;
    out.reserve(kept.size());
    for (size_t i : kept) out.push_back(std::move(items[i]));
    items = std::move(out);
  };
  compact(capture_.frames);
  if (landmarks_->size() == failures.size()) landmarks_->keep(kept);
  compact(source_index_);
  maps_.keep(kept, failures.size());
  registrations_.keep(kept, failures.size());
}

void SequenceEncoder::adopt_representation(Representation representation, const BlendComparison& blend) {
  auto_representation_ = representation;
  report_.blend = blend;
  report_.representation = options_.representation.value_or(representation);
}

Sequence encode_capture(const Capture& capture, const EncodeOptions& options, EncodeReport* report) {
  return encode_capture_stored(capture, options, report)->to_sequence();
}

std::unique_ptr<StoredSequence> encode_capture_stored(Capture capture, const EncodeOptions& options, EncodeReport* report_out) {
  SequenceEncoder encoder(std::move(capture), options);
  map_frames(encoder);
  register_frames(encoder);
  sample_frames(encoder);
  return encoder.encode_sampled(report_out);
}

namespace {

void report_selection(EncodeReport& report, const KeyframeSelection& chosen) {
  report.keyframes = chosen.keyframes;
  report.selection_history = chosen.history;
  report.keyframe_budget = chosen.budget;
  report.sparse = chosen.sparse;
  report.median_frame_interval = chosen.median_interval;
  report.budget_mean_error = chosen.budget_mean_error;
  report.budget_worst_error = chosen.budget_worst_error;
  report.budget_worst_p99 = chosen.budget_worst_p99;
}

// Frees the selection's samples of every frame (its local and normal vectors on the 65² grid),
// which the later steps do not read, keeping what they do: each frame's time, pose and diagonal,
// the reference's local vectors (pose_centre) and the fit's noise estimate at `keyframes`; the
// store's figures into the report. build may then be given those keyframes only.
void release_samples(SelectionSamples& selection, const std::vector<int>& keyframes, EncodeReport& report) {
  if (const auto figures = selection.release(keyframes)) {
    report.peak_selection_samples_in_memory = std::max(report.peak_selection_samples_in_memory, figures->peak_held);
    report.selection_spilled_bytes = figures->spilled_bytes;
  }
#ifdef __GLIBC__
  // The samples were thousands of 78 KB blocks across the threads' heaps: handed back to the system
  // here, so that the keyframe steps' arrays take their place rather than add to them.
  malloc_trim(0);
#endif
}

}  // namespace

PlanFrames plan_frames(const SequenceEncoder& encoder) {
  return {encoder.capture().frames, encoder.selection(), encoder.maps(), encoder.frame_sampler()};
}

void adopt_chosen_representation(SequenceEncoder& encoder, const PlanSettings& settings, const KeyframeSelection& chosen, int grid) {
  const RepresentationDecision decision = choose_representation(settings, plan_frames(encoder), chosen, grid, encoder.report());
  encoder.adopt_representation(decision.representation, decision.blend);
}

void adopt_chosen_representation(SequenceEncoder& encoder, const KeyframeSelection& chosen, int grid) {
  adopt_chosen_representation(encoder, plan_settings(encoder.options()), chosen, grid);
}

std::unique_ptr<StoredSequence> SequenceEncoder::encode_sampled(EncodeReport* report_out) {
  const StageSettings settings = stage_settings(options_);
  const KeyframeSelection chosen = plan(settings.plan);
  std::unique_ptr<StoredSequence> sequence = code(settings, chosen, report_.grid);
  finish_report(chosen, *sequence, report_out);
  return sequence;
}

KeyframeSelection SequenceEncoder::plan(const PlanSettings& settings) {
  const auto start = std::chrono::steady_clock::now();
  const PlanFrames frames{capture_.frames, selection_, maps_, FrameSampler(maps_, registrations_)};
  const KeyframeSelection chosen = select_keyframes(settings, frames.selection);
  report_selection(report_, chosen);
  report_.grid = choose_grid(settings, frames, report_, &chosen);
  const RepresentationDecision decision = choose_representation(settings, frames, chosen, report_.grid, report_);
  adopt_representation(decision.representation, decision.blend);
  release_samples(selection_, chosen.keyframes, report_);
  report_.seconds_planning = seconds_since(start);
  return chosen;
}

void SequenceEncoder::adopt_plan(const KeyframeSelection& chosen, int grid, Representation representation, const BlendComparison& blend) {
  const std::vector<int>& keys = chosen.keyframes;
  const int frames = frame_count();
  const bool increasing = std::adjacent_find(keys.begin(), keys.end(), std::greater_equal<int>()) == keys.end();
  if (keys.empty() || keys.front() != 0 || keys.back() != frames - 1 || !increasing ||
      chosen.predicted_error.size() != static_cast<size_t>(frames)) {
    throw Error(ErrorCode::kInvalidArgument,
                "the keyframes planned are not a selection of this encode's " + std::to_string(frames) + " frames");
  }
  report_selection(report_, chosen);
  report_.grid = grid;
  adopt_representation(representation, blend);
  release_samples(selection_, keys, report_);
}

std::unique_ptr<StoredSequence> SequenceEncoder::build(const BuildSettings& settings, const std::vector<int>& keyframes, int grid,
                                                       const KeyframeSegment* segment, KeyframeSurfaces* kept,
                                                       const StoredSequence* textures_from) {
  const Representation representation = options_.representation.value_or(auto_representation_);
  const Vec3 pose_centre = selection_.centre(options_.reference_frame);  // the face's centroid in the face frame
  const BuildFrames frames{capture_, selection_, maps_, registrations_, representation, first_time_, last_time_, pose_centre};
  return build_keyframes(settings, frames, keyframes, grid, segment, report_, kept, textures_from);
}

Sequence build_sequence(SequenceEncoder& encoder, const std::vector<int>& keyframes, int grid) {
  return encoder.build(build_settings(encoder.options()), keyframes, grid)->to_sequence();
}

void SequenceEncoder::finish_report(const KeyframeSelection& chosen, const StoredSequence& sequence, EncodeReport* report_out) {
  for (size_t i = 0; i < capture_.frames.size(); ++i) {
    const FrameSummary& frame = maps_.summaries[i];
    const std::shared_ptr<const DiskRegistration> f = registrations_.registration(static_cast<int>(i));
    const DiskRegistration& registration = *f;
    EncodedFrameReport r;
    r.name = frame.name;
    r.time = capture_.frames[i].time;
    r.vertices = frame.vertices;
    r.holes_filled = frame.holes_filled;
    r.repair = frame.repair;
    r.repair_totals = frame.repair_totals;
    r.keyframe = std::binary_search(chosen.keyframes.begin(), chosen.keyframes.end(), static_cast<int>(i));
    r.fallback = registration.fallback;
    r.fallback_reason = registration.fallback_reason;
    r.conformal_fallback_reason = frame.conformal_fallback_reason;
    r.conformal_method = frame.conformal_method;
    r.energy_moebius = registration.energy_moebius;
    r.energy = registration.energy;
    r.predicted_error = chosen.predicted_error[i];
    if (i < chosen.predicted_p99.size()) r.predicted_p99 = chosen.predicted_p99[i];
    r.diagonal = selection_.frames()[i].diagonal;
    report_.registration_fallbacks += r.fallback != RegistrationFallback::kNone;
    report_.frames.push_back(std::move(r));
  }
  report_.peak_frames_in_memory = maps_.store().peak_held();
  report_.spilled_bytes = maps_.store().spilled_bytes();
  report_.peak_keyframes_in_memory = std::max(report_.peak_keyframes_in_memory, report_.field_precision.peak_keyframes_in_memory);
  report_.keyframes_spilled_bytes += report_.field_precision.spilled_bytes;
  report_.keyframes_spilled_bytes += sequence.spilled_bytes();
  if (report_out) *report_out = std::move(report_);
}

void SequenceEncoder::store_as_positions(const std::string& why) {
  adopt_representation(Representation::kXYZ, report_.blend);
  report_.representation_fallback = why;
}

void warn_stored_as_positions(EncodeReport& report) {
  report.warnings.push_back("every keyframe stored as positions (xyz): the fields' reconstruction did not converge (" +
                            report.representation_fallback + ")");
}

std::unique_ptr<StoredSequence> SequenceEncoder::build_reconstructable(const BuildSettings& settings, const std::vector<int>& keyframes,
                                                                       int grid, const KeyframeSegment* segment,
                                                                       const std::function<void(StoredSequence&)>& measure_fields,
                                                                       KeyframeSurfaces* kept) {
  std::unique_ptr<StoredSequence> sequence = build(settings, keyframes, grid, segment, kept);
  try {
    measure_fields(*sequence);
  } catch (const Error& e) {
    // A keyframe whose fields do not reconstruct (hl+t's iteration did not converge): a capture
    // never fails for it. The file's representation is one for all keyframes (the format holds no
    // mix), so every keyframe is stored as positions, which decode without iterating, and the
    // summary and fminfo (the settings' warnings) say which keyframe and why. Asked for hl+t, the
    // encode still fails: the positions were not asked for.
    if (e.code() != ErrorCode::kNotConverged || options_.representation || auto_representation_ == Representation::kXYZ) throw;
    store_as_positions(e.what());
    sequence = build(settings, keyframes, grid, segment, kept);
    measure_fields(*sequence);
    warn_stored_as_positions(report_);
  }
  return sequence;
}

namespace {

// A candidate's geometry bytes (geometry_bytes): those the field precision measured of the same
// rounded keyframes where `just_rounded` (round_fields ran on `sequence` last and its auto dead zone
// compared files), else laid out here. The same number either way (FieldPrecision's
// AutoDeadZoneKeepsTheSmallestOfItsCandidates): one layout fewer a candidate, 1.4% of ict24's encode.
uint64_t candidate_bytes(const StoredSequence& sequence, const EncodeReport& report, bool just_rounded) {
  if (just_rounded && report.field_precision.geometry_bytes > 0) return report.field_precision.geometry_bytes;
  return geometry_bytes(sequence, report.field_coding);
}

}  // namespace

std::unique_ptr<StoredSequence> SequenceEncoder::choose_by_bytes(const StageSettings& settings, const KeyframeSelection& chosen, int grid,
                                                                 std::unique_ptr<StoredSequence> fields,
                                                                 const std::optional<std::vector<TriangleMesh>>& captured,
                                                                 CandidateBuilds& builds) {
  report_.representation_rate = {};
  if (!choosing_by_bytes(settings) || !captured) return fields;
  const std::vector<int> trials = rate_trial_frames(chosen.keyframes);
  const auto start = std::chrono::steady_clock::now();
  const HeldOutError fields_error = held_out_error(capture_, *fields, trials, *captured, settings.threads);
  RepresentationRate rate;
  rate.measured = true;
  // Frames between keyframes are never keyframes: trials among the keyframes are the keyframes themselves.
  rate.on_keyframes = std::includes(chosen.keyframes.begin(), chosen.keyframes.end(), trials.begin(), trials.end());
  // The bound the selection holds the frames to (--max-error, else the error bound), read as the
  // grid and the field rounding read it: a budget given (fmenc --keyframes) sets the bound to 0, and
  // the default 0.5% stands, or an explicit --keyframes 10% would keep no coarser N where the default
  // does (spec/method.md §7.14).
  rate.tolerance = unpredicted_error_bound(settings.plan.selection);
  // The worst trial p99 any candidate may reach, whatever the first's: the frame patches' bound,
  // under which a frame is given no patch (0 with the patches off: no candidate worse than the first;
  // admitted_worst_region).
  rate.worst_bound = settings.patch_bound;
  rate.candidates.push_back({Representation::kHLT, grid, false, candidate_bytes(*fields, report_, settings.predicted_fields), fields_error.rms,
                             static_cast<int>(trials.size()), 1, fields_error.worst_p99});
  // The others on the same keyframes, each rounded to the same target: xyz at this N, then N's
  // winner at the coarser N the worst region alone allows (--grid auto only). The best so far is kept with
  // its report (its stages' figures are the file's).
  struct Kept {
    std::unique_ptr<StoredSequence> sequence;
    EncodeReport report;
  };
  Kept best{std::move(fields), report_};
  const EncodeReport planned = report_;
  // The fields at the coarser N as a decoder rebuilds them (the grid stage measures them from where
  // its RMS terms are done, most often finer): measured there once, only where the fields are the
  // coarser N's candidate, and read by the rounding's worst-region bound (round_fields.cpp).
  const int coarser = settings.plan.grid > 0 ? 0 : worst_region_grid(report_.grid_floor_p99s, report_.grid_worst_target, grid);
  std::optional<EncodeReport::DecodedFloor> coarser_fields;
  for (const EncodeReport::DecodedFloor& d : planned.grid_decoded_floors) {
    if (coarser > 0 && d.n == coarser) coarser_fields = d;
  }
  bool measure = false;
  const auto coarser_fields_p99 = [&] {
    if (!coarser_fields) {
      coarser_fields = decoded_fields_floor(settings.plan, plan_frames(*this), coarser);
      measure = true;
    }
    return coarser_fields->p99;
  };
  const auto try_candidate = [&](Representation representation, int n, double step_scale = 1) {
    const std::shared_ptr<const GridGeometry> held = shared_grid_geometry(n);  // one G for its floors, build, rounding and decoders
    report_ = planned;
    adopt_representation(representation, planned.blend);
    if (measure && representation == Representation::kHLT)
      report_.grid_decoded_floors.insert(report_.grid_decoded_floors.begin(), *coarser_fields);
    FieldPrecisionOptions precision = keyframe_precision(settings, chosen, n);
    precision.target_error *= step_scale;
    RateCandidate candidate;
    candidate.representation = representation;
    candidate.grid = n;
    candidate.coarser = n != grid || step_scale != 1;
    candidate.step_scale = step_scale;
    if (std::unique_ptr<StoredSequence> sequence = measure_candidate(settings, chosen, builds, precision, candidate, *captured, rate))
      best = {std::move(sequence), report_};
  };
  try_candidate(Representation::kXYZ, grid);
  // Then the coarser N the worst region alone allows (--grid auto only), in N's winner alone.
  for (const auto& [representation, n] : coarser_candidates(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes, coarser, coarser_fields_p99,
                                                                  report_.grid_worst_target))
    try_candidate(representation, n);
  // Then the kept one with its fields rounded to a coarser target (coarser_step_candidate): bytes the
  // rounding spends under the spline's error between keyframes buy little of the held-out error.
  // Rounded where the fields are (settings.predicted_fields), so the rounding's worst-region bound holds for it too.
  // Not on the keyframes alone: nothing is predicted there, and the rounding's target is the error the
  // user's tolerance set (buys_only_error_below_the_target), not a share of a prediction's.
  if (settings.predicted_fields && !rate.on_keyframes) {
    const RateCandidate again = coarser_step_candidate(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes);
    try_candidate(again.representation, again.grid, kCoarserStepScale);
  }
  rate.chosen = cheapest_at_equal_error(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes);
  rate.seconds = seconds_since(start);
  report_ = std::move(best.report);
  // The report says what was measured whichever is kept (coarser N first, as the grid stage's order).
  auto& decoded = report_.grid_decoded_floors;
  if (measure && (decoded.empty() || decoded.front().n != coarser)) decoded.insert(decoded.begin(), *coarser_fields);
  adopt_representation(rate.candidates[rate.chosen].representation, planned.blend);
  report_.representation_rate = std::move(rate);
  report_.seconds_representation += report_.representation_rate.seconds;
  return std::move(best.sequence);
}

std::unique_ptr<StoredSequence> SequenceEncoder::measure_candidate(const StageSettings& settings, const KeyframeSelection& chosen,
                                                                   CandidateBuilds& builds, const FieldPrecisionOptions& precision,
                                                                   RateCandidate candidate, const std::vector<TriangleMesh>& captured,
                                                                   RepresentationRate& rate, const std::function<void()>& after_rounding) {
  const int n = candidate.grid;
  std::unique_ptr<StoredSequence> sequence;
  try {
    sequence = builds.get(candidate.representation, n,
                          [&](KeyframeSurfaces* surfaces) {
                            return build(settings.build, chosen.keyframes, n, nullptr, surfaces, builds.any_kept());
                          },
                          report_);
    if (settings.predicted_fields) report_.field_coding = round_fields(precision, *sequence, report_);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kNotConverged) throw;
    return nullptr;  // fields that do not reconstruct at this N: not a candidate
  }
  if (after_rounding) after_rounding();
  const std::vector<int> trials = rate_trial_frames(chosen.keyframes);
  const HeldOutError error = held_out_error(capture_, *sequence, trials, captured, settings.threads);
  candidate.bytes = candidate_bytes(*sequence, report_, settings.predicted_fields);
  candidate.held_rms = error.rms;
  candidate.frames = static_cast<int>(trials.size());
  candidate.worst_p99 = error.worst_p99;
  if (!add_candidate(rate, candidate)) return nullptr;
  report_.grid = n;
  return sequence;
}

FieldPrecisionOptions SequenceEncoder::keyframe_precision(const StageSettings& settings, const KeyframeSelection& chosen, int grid) {
  FieldPrecisionOptions precision = field_precision_options(settings, chosen);
  if (settings.plan.grid > 0 || !settings.predicted_fields) return precision;  // not bounded (round_fields.cpp): nothing measured
  const std::pair<int, std::vector<int>> key(grid, chosen.keyframes);
  auto floors = keyframe_floors_.find(key);
  if (floors == keyframe_floors_.end()) floors = keyframe_floors_.emplace(key, keyframe_floor_p99s(plan_frames(*this), chosen.keyframes, grid, settings.threads)).first;
  precision.keyframe_floors = floors->second;
  return precision;
}

bool SequenceEncoder::choosing_by_bytes(const StageSettings& settings) const {
  return !settings.plan.representation && auto_representation_ == Representation::kHLT;
}

std::unique_ptr<StoredSequence> SequenceEncoder::code(const StageSettings& settings, const KeyframeSelection& chosen, int grid) {
  // One G at N for every stage below that makes one (shared_grid_geometry: each stage's own was
  // let go before the next asked, 1.3% of ict24's encode).
  const std::shared_ptr<const GridGeometry> held = shared_grid_geometry(grid);
  const FieldPrecisionOptions precision = keyframe_precision(settings, chosen, grid);
  // The keyframes built here are the choice by bytes' first candidate: kept unrounded with their
  // surfaces for its others at this N (candidate_builds.hpp), where it will run.
  std::unique_ptr<StoredSequence> sequence;
  // The trial frames' captured meshes, read once for both disks' candidates.
  std::optional<std::vector<TriangleMesh>> captured;
  // The density-equalised candidate's disk depends on the reference frame's map alone: made on a
  // thread of its own while the conformal disk's candidates are built and measured, where that
  // candidate may be tried (one serial stretch of 0.3 s fewer on every capture measured; unused, and
  // waited for, where the choice by bytes ends up not measuring). Not with --threads 1.
  std::future<DiskReparametrisation> equalised_disk;
  if (settings.threads != 1 && choosing_by_bytes(settings) && density_candidate_possible(options_, report_))
    equalised_disk = std::async(std::launch::async, [reference = maps_.frame(options_.reference_frame)] { return candidate_disk(reference->map); });
  {
    CandidateBuilds builds(settings.build.spill_keyframes ? SpillMode::kSpill : SpillMode::kMemory, settings.threads);
    KeyframeSurfaces surfaces;
    sequence = build_reconstructable(
        settings.build, chosen.keyframes, grid, nullptr,
        [&](StoredSequence& keyframes) {
          if (choosing_by_bytes(settings)) builds.keep(keyframes, surfaces, report_);
          if (settings.predicted_fields) report_.field_coding = round_fields(precision, keyframes, report_);
        },
        &surfaces);
    if (choosing_by_bytes(settings)) captured = trial_meshes(capture_, rate_trial_frames(chosen.keyframes), settings.threads);
    sequence = choose_by_bytes(settings, chosen, grid, std::move(sequence), captured, builds);
  }  // the conformal disk's builds let go before D's are made
  sequence = choose_density_equalised(settings, chosen, std::move(sequence), captured, &equalised_disk);
  // Residual frames fitted to the keyframes as the file holds them (residual_fit.hpp), where the
  // selection took fewer keyframes for them (residuals_pay): elsewhere they are bytes added.
  if (settings.residual_frames && residuals_pay(chosen)) {
    const RegisteredFrames frames = registered_frames(capture_.frames, selection_, FrameSampler(maps_, registrations_));
    sequence->set_residuals(fit_decoded_residuals(frames, *sequence, chosen.keyframes, SelectionOptions().residual_step,
                                                  &report_.residual_fit, settings.threads));
    report_.residual_fit.keyframes_saved = chosen.spline_keyframes - static_cast<int>(chosen.keyframes.size());
  }
  // Frame patches fitted to the decoded frames, residuals included (patch_fit.hpp).
  if (settings.patch_bound > 0)
    sequence->set_patches(
        fit_frame_patches(capture_, *sequence, chosen.keyframes, settings.patch_bound, &report_.patch_fit, settings.threads));
  // The density-equalised candidate's comparison coded the kept disk's textures already (its qualities
  // read the keyframes' textures and spline, which residuals and patches leave as they are).
  if (!report_.density_candidate.textures_coded)
    code_textures(settings.texture, TextureFrameSource{capture_.frames, maps_, FrameSampler(maps_, registrations_)}, *sequence,
                  chosen.keyframes, report_);
  return sequence;
}

TextureFrameSource texture_frames(const SequenceEncoder& encoder) {
  return {encoder.capture().frames, encoder.maps(), encoder.frame_sampler()};
}

RegisteredFrames registered_frames(const std::vector<CaptureFrame>& frames, const SelectionSamples& selection, FrameSampler sampler) {
  RegisteredFrames registered;
  for (const CaptureFrame& f : frames) registered.times.push_back(f.time);
  for (const SelectionFrame& f : selection.frames()) registered.diagonals.push_back(f.diagonal);
  registered.surface = [sampler = std::move(sampler)](int i, std::span<const Vec2> nodes) { return sampler.sample_surface(i, nodes); };
  return registered;
}

RegisteredFrames registered_frames(const SequenceEncoder& encoder) {
  return registered_frames(encoder.capture().frames, encoder.selection(), encoder.frame_sampler());
}

}  // namespace facemorph
