#include "codec/encoder/encode/segmented_encode.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/options_json.hpp"
#include "codec/encoder/encode/staged_encode.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "format/error.hpp"

#include "codec/encoder/encode/json_fields.hpp"
#include "format/checksum.hpp"
#include "format/file_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace facemorph {

namespace {

constexpr int kMaxSegments = 4096;
// A measure of an hour at 30 fps is about 3 MB (a predicted error a frame); parsed, a JSON text
// takes about 20 times its size.
constexpr uint64_t kMaxMeasureBytes = uint64_t{16} << 20;
constexpr int kMaxMeasureDepth = 4;  // the settings nest three levels
constexpr const char* kMeasureFormat = "facemorph segment measure";
constexpr int kMeasureVersion = 1;

// The intra period of the whole capture's keyframes (of `frames`), as choose_field_coding would
// choose it from them (`precision`): every segment's groups are the whole encode's.
int capture_intra_period(const FieldPrecisionOptions& precision, const std::vector<CaptureFrame>& frames, const KeyframeSelection& chosen) {
  if (precision.intra_period != kAutoIntraPeriod) return precision.intra_period;
  Sequence times;
  for (int k : chosen.keyframes) times.keyframes.emplace_back().time = frames[static_cast<size_t>(k)].time;
  return auto_intra_period(times);
}

// What both stages do first: the parts read, the keyframes, N and representation chosen (or
// taken from a measure), this segment's keyframes found.
struct SegmentStart {
  PartsEncoder parts;
  SequenceEncoder* encoder = nullptr;  // the parts'
  StageSettings settings;              // every stage's, from the segment's options
  KeyframeSelection chosen;
  int intra_period = 0;
  KeyframeSegment keyframes;
  PartHeader header;
};

// `planned`: a measure whose choices of keyframes, N and representation are taken (the assemble
// stage); none: they are made here (the measure stage).
SegmentStart start_segment(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options, SegmentId id,
                           const SegmentMeasure* planned = nullptr) {
  if (!options.predicted_fields) {
    throw Error(ErrorCode::kUnsupported,
                "segments need predicted fields: without them each file takes steps from its own keyframes' range, and files "
                "with other steps do not join");
  }
  if (id.index < 0 || id.index >= id.count || id.count > kMaxSegments)
    throw Error(ErrorCode::kInvalidArgument, "no segment " + std::to_string(id.index) + " of " + std::to_string(id.count));
  SegmentStart s;
  // A segment carries no residual frames (spec/method.md §7.18): its keyframes are the spline's own.
  EncodeOptions segment_options = options;
  segment_options.residual_frames = false;
  s.parts = encoder_of_parts(parts, segment_options, &s.header);
  s.encoder = s.parts.encoder.get();
  s.parts.timing.add_to(s.encoder->report());
  s.settings = stage_settings(s.encoder->options());
  if (planned) {
    s.chosen = planned->plan;
    try {
      s.encoder->adopt_plan(s.chosen, planned->grid, planned->representation, planned->blend);
    } catch (const Error& e) {
      throw Error(e.code(), std::string("the measures are not of these parts: ") + e.what());
    }
  } else {
    s.chosen = s.encoder->plan(s.settings.plan);
  }
  s.intra_period = capture_intra_period(s.settings.precision, s.encoder->capture().frames, s.chosen);
  s.keyframes = segment_keyframes(s.chosen.keyframes.size(), s.intra_period, id);
  return s;
}

void check_steps(const std::vector<double>& steps, const std::string& where) {
  if (steps.size() != kKeyframeArrayCount)
    json_fields::bad(where + " holds " + std::to_string(steps.size()) + " field steps, not " + std::to_string(kKeyframeArrayCount));
  for (double s : steps) {
    if (!(s > 0) || !std::isfinite(s)) json_fields::bad(where + " holds a field step that is not finite and positive");
  }
}

}  // namespace

SegmentId parse_segment(const std::string& text) {
  SegmentId id;
  int consumed = 0;
  const bool digits = !text.empty() && std::all_of(text.begin(), text.end(), [](char c) { return (c >= '0' && c <= '9') || c == '/'; });
  if (!digits || std::sscanf(text.c_str(), "%d/%d%n", &id.index, &id.count, &consumed) != 2 || consumed != static_cast<int>(text.size()) ||
      id.index < 0 || id.index >= id.count || id.count > kMaxSegments) {
    throw Error(ErrorCode::kInvalidArgument, "--segment '" + text + "': S/N with 0 <= S < N <= " + std::to_string(kMaxSegments));
  }
  return id;
}

KeyframeSegment segment_keyframes(size_t keyframes, int intra_period, SegmentId id) {
  if (intra_period < 1) throw Error(ErrorCode::kInvalidArgument, "segments: an intra period below 1");
  const size_t period = static_cast<size_t>(intra_period), groups = (keyframes + period - 1) / period;
  const auto count = static_cast<size_t>(id.count), index = static_cast<size_t>(id.index);
  KeyframeSegment s;
  if (index >= groups) {  // N is a bound: a capture of fewer groups has one segment a group
    s.first = s.end = s.fit_first = s.fit_end = keyframes;
    return s;
  }
  const size_t used = std::min(count, groups);
  s.first = index * groups / used * period;
  s.end = std::min(keyframes, (index + 1) * groups / used * period);
  s.fit_first = s.first > kSegmentFitMargin ? s.first - kSegmentFitMargin : 0;
  s.fit_end = std::min(keyframes, s.end + kSegmentFitMargin);
  return s;
}

SegmentMeasure measure_segment(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options, SegmentId id,
                               EncodeReport* report) {
  SegmentStart s = start_segment(parts, options, id);
  SequenceEncoder& encoder = *s.encoder;
  SegmentMeasure m;
  m.segment = id;
  m.capture_id = s.header.capture_id;
  m.settings = write_options(options, OptionsScope::kSegment);
  m.keyframes = static_cast<int>(s.chosen.keyframes.size());
  m.intra_period = s.intra_period;
  m.grid = encoder.report().grid;
  m.representation = encoder.representation();
  m.first = static_cast<int>(s.keyframes.first);
  m.end = static_cast<int>(s.keyframes.end);
  m.plan = s.chosen;
  m.plan.history.clear();
  m.blend = encoder.report().blend;
  m.target_error = field_precision_options(s.settings, s.chosen).target_error;
  if (m.first == m.end) {  // past the capture's groups: nothing to measure
    if (report) *report = std::move(encoder.report());
    return m;
  }
  s.keyframes.textures = false;  // nothing here is written but the measure
  FieldPrecisionOptions precision = field_precision_options(s.settings, s.chosen);
  precision.intra_period = s.intra_period;
  // Through the driver's fallback: where this segment's keyframes do not reconstruct, its measure
  // is of positions, and says so (the assemble stage takes it to every segment).
  encoder.build_reconstructable(s.settings.build, s.chosen.keyframes, encoder.report().grid, &s.keyframes, [&](StoredSequence& keyframes) {
    const auto start = std::chrono::steady_clock::now();
    encoder.report().field_coding = choose_field_coding(keyframes, precision, &encoder.report().field_precision);
    encoder.report().seconds_precision = seconds_since(start);
  });
  m.representation_fallback = encoder.report().representation_fallback;
  m.folds = encoder.report().keyframe_folds;
  m.steps = encoder.report().field_coding.steps;
  m.inter_dead_zone = encoder.report().field_precision.inter_dead_zone;
  m.keyframe_errors = encoder.report().field_precision.keyframe_errors;
  // Not finish_report: its per-frame lines read every frame's registration back for a file this
  // stage does not write.
  if (report) *report = std::move(encoder.report());
  return m;
}

void write_segment_measure(const std::filesystem::path& path, const SegmentMeasure& m) {
  nlohmann::json doc = {{"format", kMeasureFormat},
                        {"version", kMeasureVersion},
                        {"segment", m.segment.index},
                        {"segments", m.segment.count},
                        {"capture", m.capture_id},
                        {"settings", nlohmann::json::parse(m.settings)},
                        {"keyframes", m.keyframes},
                        {"intra_period", m.intra_period},
                        {"grid", m.grid},
                        {"representation", representation_name(m.representation)},
                        {"first", m.first},
                        {"end", m.end},
                        {"folds", m.folds},
                        {"steps", m.steps},
                        {"target_error", m.target_error},
                        {"inter_dead_zone", m.inter_dead_zone},
                        {"keyframe_errors", m.keyframe_errors},
                        {"plan",
                         {{"keyframes", m.plan.keyframes},
                          {"predicted_error", m.plan.predicted_error},
                          {"budget", m.plan.budget},
                          {"budget_mean_error", m.plan.budget_mean_error},
                          {"budget_worst_error", m.plan.budget_worst_error},
                          {"rate_mean_error", m.plan.rate_mean_error},
                          {"median_interval", m.plan.median_interval},
                          {"sparse", m.plan.sparse},
                          {"blend",
                           {{"trials", m.blend.trials},
                            {"fields_error", m.blend.fields_error},
                            {"positions_error", m.blend.positions_error},
                            {"not_converged", m.blend.not_converged}}}}}};
  // Only where it fell back: every other measure's bytes are as they were.
  if (!m.representation_fallback.empty()) doc["representation_fallback"] = m.representation_fallback;
  format::write_file_atomically(path, doc.dump() + "\n");
}

SegmentMeasure read_segment_measure(const std::filesystem::path& path) {
  const std::string where = path.string();
  const std::vector<uint8_t> bytes = [&] {
    try {
      return format::read_file(path, kMaxMeasureBytes);
    } catch (const Error& e) {
      throw Error(e.code() == ErrorCode::kInvalidArgument ? ErrorCode::kLimit : e.code(), e.what());
    }
  }();
  try {
    using json_fields::bad;
    using json_fields::field;
    using json_fields::integer_field;
    const std::string it = "the measure";
    const nlohmann::json doc = json_fields::parse_object(bytes, kMaxMeasureDepth, it);
    if (field<std::string>(doc, "format", it) != kMeasureFormat) bad("it is not a segment measure");
    if (integer_field(doc, "version", it) != kMeasureVersion)
      throw Error(ErrorCode::kUnsupported, "measure version " + doc["version"].dump() + " (this fmenc reads 1)");
    SegmentMeasure m;
    m.source = where;
    m.segment = {integer_field(doc, "segment", it), integer_field(doc, "segments", it)};
    m.capture_id = field<std::string>(doc, "capture", it);
    if (!doc.contains("settings") || !doc["settings"].is_object()) bad("it lacks its settings");
    m.settings = doc["settings"].dump();
    m.keyframes = integer_field(doc, "keyframes", it);
    m.intra_period = integer_field(doc, "intra_period", it);
    m.grid = integer_field(doc, "grid", it);
    try {
      m.representation = parse_representation(field<std::string>(doc, "representation", it));
    } catch (const Error&) {
      bad("its representation is none of hl, hl+t, xyz");
    }
    m.first = integer_field(doc, "first", it);
    m.end = integer_field(doc, "end", it);
    if (m.segment.index < 0 || m.segment.index >= m.segment.count || m.segment.count > kMaxSegments)
      bad("its segment number is out of range");
    const bool empty = m.first == m.keyframes && m.end == m.keyframes;  // a segment past the capture's groups
    if (m.keyframes < 1 || m.intra_period < 1 ||
        (!empty && (m.first < 0 || m.first >= m.end || m.end > m.keyframes || m.first % m.intra_period != 0))) {
      bad("its keyframes are not whole groups of the capture's");
    }
    if (m.grid < kMinGridSize || m.grid > kMaxGridSize)
      bad("its grid N = " + std::to_string(m.grid) + " is outside " + std::to_string(kMinGridSize) + ".." + std::to_string(kMaxGridSize));
    const auto interior = static_cast<size_t>(disk_grid_shape(m.grid).interior_count);
    const nlohmann::json& folds = doc.contains("folds") ? doc["folds"] : nlohmann::json();
    if (!folds.is_array() || folds.size() > interior) bad("its folds are not a list of at most G's interior nodes");
    for (const nlohmann::json& node : folds) {
      if (!node.is_number_integer() || node.get<int64_t>() < 0 || node.get<int64_t>() >= static_cast<int64_t>(interior))
        bad("a fold is not an interior node of G");
      if (!m.folds.empty() && node.get<int32_t>() <= m.folds.back()) bad("its folds are not ascending");
      m.folds.push_back(node.get<int32_t>());
    }
    m.steps = field<std::vector<double>>(doc, "steps", it);
    if (!empty || !m.steps.empty()) check_steps(m.steps, "it");
    if (empty && !m.folds.empty()) bad("it folds where it has no keyframes");
    m.target_error = field<double>(doc, "target_error", it);
    m.inter_dead_zone = field<double>(doc, "inter_dead_zone", it);
    if (!(m.target_error > 0) || !std::isfinite(m.target_error)) bad("its target error is not finite and positive");
    if (!(m.inter_dead_zone >= 0.5 && m.inter_dead_zone < 1)) bad("its dead zone is outside [0.5, 1)");
    m.keyframe_errors = field<std::vector<double>>(doc, "keyframe_errors", it);
    if (doc.contains("representation_fallback")) {
      m.representation_fallback = field<std::string>(doc, "representation_fallback", it);
      if (m.representation_fallback.empty() || m.representation == Representation::kXYZ)
        bad("it falls back to positions from positions, or says not why");
    }
    if (m.keyframe_errors.size() != static_cast<size_t>(m.end - m.first)) bad("it holds an error for other than each of its keyframes");
    for (double e : m.keyframe_errors) {
      if (!(e >= 0) || !std::isfinite(e)) bad("a keyframe's error is not finite and at least 0");
    }
    const nlohmann::json plan = field<nlohmann::json>(doc, "plan", it);
    if (!plan.is_object()) bad("its plan is not an object");
    const std::string its_plan = "its plan";
    m.plan.keyframes = field<std::vector<int>>(plan, "keyframes", its_plan);
    m.plan.predicted_error = field<std::vector<double>>(plan, "predicted_error", its_plan);
    m.plan.budget = integer_field(plan, "budget", its_plan);
    m.plan.budget_mean_error = field<double>(plan, "budget_mean_error", its_plan);
    m.plan.budget_worst_error = field<double>(plan, "budget_worst_error", its_plan);
    m.plan.rate_mean_error = field<double>(plan, "rate_mean_error", its_plan);
    m.plan.median_interval = field<double>(plan, "median_interval", its_plan);
    m.plan.sparse = field<bool>(plan, "sparse", its_plan);
    const nlohmann::json blend = field<nlohmann::json>(plan, "blend", its_plan);
    if (!blend.is_object()) bad("its plan's blend is not an object");
    m.blend.trials = integer_field(blend, "trials", "its plan's blend");
    m.blend.fields_error = field<double>(blend, "fields_error", "its plan's blend");
    m.blend.positions_error = field<double>(blend, "positions_error", "its plan's blend");
    m.blend.not_converged = integer_field(blend, "not_converged", "its plan's blend");
    // The frames the plan covers are checked against the parts when it is taken (SequenceEncoder::adopt_plan).
    if (m.plan.keyframes.size() != static_cast<size_t>(m.keyframes))
      bad("its plan holds " + std::to_string(m.plan.keyframes.size()) + " keyframes, not " + std::to_string(m.keyframes));
    for (double e : m.plan.predicted_error) {
      if (!(e >= 0) || !std::isfinite(e)) bad("its plan's predicted errors are not finite and at least 0");
    }
    return m;
  } catch (const Error& e) {
    throw Error(e.code(), where + ": " + e.what());
  }
}

std::unique_ptr<StoredSequence> assemble_segment(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options,
                                                 SegmentId id, const std::vector<SegmentMeasure>& measures, SegmentPlacement* placement,
                                                 EncodeReport* report, PartHeader* header) {
  // The measures first (cheap): one encode's N segments, each once.
  std::vector<const SegmentMeasure*> by_index(static_cast<size_t>(id.count), nullptr);
  const std::string settings = write_options(options, OptionsScope::kSegment);
  for (const SegmentMeasure& m : measures) {
    const std::string which = (m.source.empty() ? "" : m.source + ": ") + "the measure of segment " + std::to_string(m.segment.index) +
                              "/" + std::to_string(m.segment.count);
    if (m.segment.count != id.count)
      throw Error(ErrorCode::kInvalidArgument,
                  which + " is of " + std::to_string(m.segment.count) + " segments, not " + std::to_string(id.count));
    if (by_index[static_cast<size_t>(m.segment.index)]) throw Error(ErrorCode::kInvalidArgument, which + " is given twice");
    if (!same_options(m.settings, options, OptionsScope::kSegment))
      throw Error(ErrorCode::kInvalidArgument, which + " was made with other settings: " + m.settings + " (these: " + settings + ")");
    const SegmentMeasure& first = measures.front();
    if (m.capture_id != first.capture_id || m.keyframes != first.keyframes || m.intra_period != first.intra_period ||
        m.grid != first.grid || m.representation != first.representation || m.plan.keyframes != first.plan.keyframes ||
        m.plan.predicted_error != first.plan.predicted_error) {
      throw Error(ErrorCode::kInvalidArgument,
                  which + " is of another encode than the first measure's (capture, keyframes, intra period, grid or representation)");
    }
    // Its keyframes those its number gives (an empty segment past the capture's groups included).
    const KeyframeSegment range = segment_keyframes(static_cast<size_t>(m.keyframes), m.intra_period, m.segment);
    if (m.first != static_cast<int>(range.first) || m.end != static_cast<int>(range.end)) {
      throw Error(ErrorCode::kInvalidArgument, which + " holds keyframes " + std::to_string(m.first) + ":" + std::to_string(m.end) +
                                                   ", not its segment's " + std::to_string(range.first) + ":" + std::to_string(range.end));
    }
    by_index[static_cast<size_t>(m.segment.index)] = &m;
  }
  for (size_t s = 0; s < by_index.size(); ++s) {
    if (!by_index[s])
      throw Error(ErrorCode::kInvalidArgument, "no measure of segment " + std::to_string(s) + "/" + std::to_string(id.count));
  }
  const SegmentMeasure& own = *by_index[static_cast<size_t>(id.index)];
  SegmentStart s = start_segment(parts, options, id, &own);
  SequenceEncoder& encoder = *s.encoder;
  EncodeReport& r = encoder.report();
  // The keyframes, N and representation are the measure's own (adopted), and its range was checked
  // against its number above: what the parts decide besides is the capture and the intra period.
  if (own.capture_id != s.header.capture_id || own.intra_period != s.intra_period) {
    throw Error(ErrorCode::kInvalidArgument,
                own.source + ": the measures are not of these parts: another capture, or another intra period or range of keyframes");
  }
  // Settled across the segments: the fixed nodes, every segment's folds; each step the finest any
  // segment needs (a finer step than a segment's own search chose keeps its keyframes within the target).
  FieldCoding coding;
  coding.intra_period = s.intra_period;
  coding.steps.assign(kKeyframeArrayCount, std::numeric_limits<double>::infinity());
  std::vector<int32_t> fixed;
  uint64_t encode_hash = format::kFnv1aStart;  // over what the segments settle
  const auto mix = [&](const void* data, size_t bytes) { encode_hash = format::fnv1a(encode_hash, data, bytes); };
  mix(own.capture_id.data(), own.capture_id.size());
  mix(settings.data(), settings.size());
  // The plan's predicted errors depend on every frame's geometry, which the capture's fingerprint
  // (names, times, landmarks) does not read.
  mix(own.plan.keyframes.data(), own.plan.keyframes.size() * sizeof(int));
  mix(own.plan.predicted_error.data(), own.plan.predicted_error.size() * sizeof(double));
  // A segment whose keyframes did not reconstruct measured positions: then every segment stores
  // them (one representation a file, and the joined file is one), at those measures' steps.
  const auto fell_back =
      std::find_if(by_index.begin(), by_index.end(), [](const SegmentMeasure* m) { return !m->representation_fallback.empty(); });
  const SegmentMeasure* fallback = fell_back == by_index.end() ? nullptr : *fell_back;
  int used = 0;  // the segments that code keyframes: N, or the capture's groups where fewer
  for (const SegmentMeasure* m : by_index) {
    if (m->first == m->end) continue;
    ++used;
    const bool measured_positions = !m->representation_fallback.empty();
    if (!fallback || measured_positions) {
      for (size_t a = 0; a < coding.steps.size(); ++a) coding.steps[a] = std::min(coding.steps[a], m->steps[a]);
    }
    fixed.insert(fixed.end(), m->folds.begin(), m->folds.end());
    mix(m->steps.data(), m->steps.size() * sizeof(double));
    mix(m->folds.data(), m->folds.size() * sizeof(int32_t));
  }
  std::sort(fixed.begin(), fixed.end());
  fixed.erase(std::unique(fixed.begin(), fixed.end()), fixed.end());
  set_default_pose_steps(coding, s.header.capture.units);
  if (own.first == own.end) {
    if (report) *report = std::move(r);
    return nullptr;
  }
  s.keyframes.fixed_nodes = fixed;
  // The fallback's measure settles this segment's dead zone too where its own measured the fields.
  const SegmentMeasure& zone = fallback && own.representation_fallback.empty() ? *fallback : own;
  if (fallback) encoder.store_as_positions(fallback->representation_fallback);
  std::unique_ptr<StoredSequence> sequence = encoder.build(s.settings.build, s.chosen.keyframes, r.grid, &s.keyframes);
  // Its target is the measure's (own.target_error): the steps below are the measures'.
  FieldPrecisionOptions precision = field_precision_options(s.settings, s.chosen);
  precision.target_error = own.target_error;
  precision.intra_period = s.intra_period;
  precision.inter_dead_zone = zone.inter_dead_zone;
  const auto start = std::chrono::steady_clock::now();
  r.field_precision = {};
  r.field_precision.target_error = own.target_error;
  r.field_precision.inter_dead_zone = zone.inter_dead_zone;
  try {
    r.field_precision.keyframe_errors = apply_field_coding(*sequence, coding, precision);
  } catch (const Error& e) {
    throw Error(e.code(), std::string("coding the keyframes with the steps the measures settled: ") + e.what());
  }
  r.field_coding = coding;
  r.seconds_precision = seconds_since(start);
  if (fallback) warn_stored_as_positions(r);
  const std::vector<int> keyframes(s.chosen.keyframes.begin() + static_cast<long>(s.keyframes.first),
                                   s.chosen.keyframes.begin() + static_cast<long>(s.keyframes.end));
  code_textures(s.settings.texture, texture_frames(encoder), *sequence, keyframes, encoder.report());
  if (placement) {
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(encode_hash));
    *placement = {{id.index, used}, static_cast<int>(s.keyframes.first), static_cast<int>(s.chosen.keyframes.size()), hex};
  }
  if (header) *header = s.header;
  encoder.finish_report(s.chosen, *sequence, report);
  return sequence;
}

}  // namespace facemorph
