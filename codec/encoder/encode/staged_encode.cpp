// The staged encode: the sample stage (one part) and the assemble stage (spec/part-file.md).
#include "codec/encoder/encode/staged_encode.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/encoder/encode/options_json.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>

namespace facemorph {

namespace {

std::vector<Vec3> frame_points(const Capture& capture, size_t i) {
  if (i < capture.landmarks.size()) return capture.landmarks[i];
  return std::vector<Vec3>(capture.landmark_names.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
}

// `capture` with only the frames `indices` (increasing), their landmarks with them.
Capture sub_capture(const Capture& capture, const std::vector<int>& indices) {
  Capture sub;
  sub.root = capture.root;
  sub.description = capture.description;
  sub.fps = capture.fps;
  sub.units = capture.units;
  sub.landmark_names = capture.landmark_names;
  sub.generator = capture.generator;
  for (int i : indices) {
    sub.frames.push_back(capture.frames[static_cast<size_t>(i)]);
    sub.landmarks.push_back(frame_points(capture, static_cast<size_t>(i)));
  }
  return sub;
}

// Whether frame k alone maps (what map_frames would keep of it). Strict, its failure is thrown, as
// the one-process encode throws it.
bool maps(const Capture& capture, const EncodeOptions& options, const std::optional<Vec3>& hint, int k) {
  EncodeOptions one = options;
  one.reference_frame = 0;
  one.progress = nullptr;
  one.threads = 1;
  try {
    SequenceEncoder encoder(sub_capture(capture, {k}), one);
    encoder.set_vertical_hint(hint);
    map_frames(encoder);  // with no frame left, throws the frame's failure
    return true;
  } catch (const Error&) {
    if (options.strict) throw;
    return false;
  }
}

// The frame every frame registers to, as drop_frames settles it: the one given, or where that one
// cannot be mapped the nearest in time that can (the earlier of two as near).
int settle_reference(const Capture& capture, const EncodeOptions& options, const std::optional<Vec3>& hint) {
  const int count = static_cast<int>(capture.frames.size());
  const double given = capture.frames[static_cast<size_t>(options.reference_frame)].time;
  std::vector<int> order(static_cast<size_t>(count));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return std::abs(capture.frames[static_cast<size_t>(a)].time - given) < std::abs(capture.frames[static_cast<size_t>(b)].time - given);
  });
  // The given frame first (its distance is 0), where several frames share its time too.
  std::stable_partition(order.begin(), order.end(), [&](int k) { return k == options.reference_frame; });
  for (int k : order) {
    if (maps(capture, options, hint, k)) return k;
  }
  throw Error(ErrorCode::kInvalidArgument, "no frame of the capture could be mapped to register the others to");
}

// The names every part's landmarks are put under: the capture's own, then those the frames' found
// landmarks add, in the order map_frames adds them (the pose's, then the rim's).
std::vector<std::string> assembled_names(const std::vector<PartHeader>& headers) {
  std::vector<std::string> names = headers.front().capture.given_landmark_names;
  std::vector<std::string> found = {"nose_tip", "nose_bridge"};
  for (int k = 0; k < kFoundRimMarkers; ++k) found.push_back("rim_" + std::to_string(k));
  for (const std::string& name : found) {
    const bool in_a_part = std::any_of(headers.begin(), headers.end(), [&](const PartHeader& h) {
      return std::find(h.capture.landmark_names.begin(), h.capture.landmark_names.end(), name) != h.capture.landmark_names.end();
    });
    if (in_a_part && std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
  }
  return names;
}

}  // namespace

std::vector<FrameRange> part_ranges(int frames, int per_part) {
  if (frames < 1 || per_part < 1) throw Error(ErrorCode::kInvalidArgument, "a capture splits into parts of at least one frame");
  std::vector<FrameRange> ranges;
  for (int first = 0; first < frames; first += std::min(per_part, frames - first))
    ranges.push_back({first, std::min(frames, first + per_part)});
  return ranges;
}

PartHeader encode_part(const Capture& capture, const EncodeOptions& options, FrameRange range, const std::filesystem::path& path) {
  const int count = static_cast<int>(capture.frames.size());
  if (count == 0) throw Error(ErrorCode::kInvalidArgument, "the capture has no frames");
  if (range.first < 0 || range.end > count || range.first >= range.end) {
    throw Error(ErrorCode::kInvalidArgument, "frames " + std::to_string(range.first) + ":" + std::to_string(range.end) +
                                                 " are not a range of the capture's " + std::to_string(count) + " frames");
  }
  if (options.reference_frame < 0 || options.reference_frame >= count) {
    throw Error(ErrorCode::kInvalidArgument,
                "reference frame " + std::to_string(options.reference_frame) + " is not a frame of the capture");
  }
  if (options.track_landmarks) {
    throw Error(ErrorCode::kUnsupported,
                "--track-landmarks tracks from frame to frame across the whole capture, which a part does not hold: encode in one process");
  }
  if (!capture.landmarks.empty() && capture.landmarks.size() != capture.frames.size()) {
    throw Error(ErrorCode::kInvalidArgument, "the capture has landmarks for " + std::to_string(capture.landmarks.size()) + " of its " +
                                                 std::to_string(count) + " frames");
  }
  // What map_frames settles from the whole capture: the up hint, then the reference.
  std::optional<Vec3> hint;
  if (options.find_landmarks) {
    hint =
        find_vertical_hint(capture, options.reference_frame, options.largest_component, [&](size_t i) { return frame_points(capture, i); });
  }
  const int reference = settle_reference(capture, options, hint);
  std::vector<int> indices(static_cast<size_t>(range.size()));
  std::iota(indices.begin(), indices.end(), range.first);
  if (!range.contains(reference)) indices.insert(std::lower_bound(indices.begin(), indices.end(), reference), reference);
  EncodeOptions part_options = options;
  part_options.reference_frame = static_cast<int>(std::find(indices.begin(), indices.end(), reference) - indices.begin());
  SequenceEncoder encoder(sub_capture(capture, indices), part_options);
  encoder.set_source_indices(indices);
  encoder.set_vertical_hint(hint);
  map_frames(encoder);
  register_frames(encoder);
  sample_frames(encoder);

  PartHeader header;
  header.capture_id = capture_fingerprint(capture);
  SampledCapture& c = header.capture;
  c.root = std::filesystem::absolute(capture.root);
  c.fps = capture.fps;
  c.units = capture.units;
  c.first_time = capture.frames.front().time;
  c.last_time = capture.frames.back().time;
  c.frame_count = count;
  c.landmark_names = encoder.capture().landmark_names;
  c.given_landmark_names = capture.landmark_names;
  c.given_reference = options.reference_frame;
  c.reference = reference;
  header.range = range;
  header.settings = write_options(options, OptionsScope::kSample);
  header.encoder = std::string("facemorph ") + FACEMORPH_VERSION;
  header.seconds_mapping = encoder.report().seconds_mapping;
  header.seconds_registration = encoder.report().seconds_registration;
  header.seconds_selection = encoder.report().seconds_selection;
  PartWriter writer(path, header);
  encoder.for_each_sampled_frame([&](SampledFrame&& f) {
    if (!range.contains(f.index)) return;  // the reference, registered to here, is its own part's
    if (!f.texture.empty()) f.texture = std::filesystem::absolute(f.texture);
    writer.add(f);
  });
  writer.finish();
  return header;
}

void check_part_settings(const PartReader& part, const EncodeOptions& options) {
  check_part_settings(part, write_options(options, OptionsScope::kSample));
}

void check_part_settings(const PartReader& part, const std::string& sample_settings) {
  const PartHeader& h = part.header();
  if (same_options(h.settings, sample_settings)) return;
  throw Error(ErrorCode::kInvalidArgument, part.source() + " (frames " + std::to_string(h.range.first) + ":" + std::to_string(h.range.end) +
                                               ") was sampled with other settings than these: " + h.settings + " (these: " + sample_settings +
                                               ")");
}

PartsEncoder::PartsEncoder() = default;
PartsEncoder::PartsEncoder(PartsEncoder&&) noexcept = default;
PartsEncoder& PartsEncoder::operator=(PartsEncoder&&) noexcept = default;
PartsEncoder::~PartsEncoder() = default;

PartsEncoder encoder_of_parts(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options, PartHeader* header_out) {
  if (parts.empty()) throw Error(ErrorCode::kInvalidArgument, "no parts to assemble");
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::unique_ptr<PartReader>> readers;
  for (const std::filesystem::path& part : parts) readers.push_back(std::make_unique<PartReader>(part));
  std::stable_sort(readers.begin(), readers.end(),
                   [](const auto& a, const auto& b) { return a->header().range.first < b->header().range.first; });
  // One capture, one setting, every frame once.
  const PartHeader& first = readers.front()->header();
  std::vector<PartHeader> headers;
  const std::string sample_settings = write_options(options, OptionsScope::kSample);
  int next = 0;
  for (const auto& reader : readers) {
    const PartHeader& h = reader->header();
    const SampledCapture &a = first.capture, &b = h.capture;
    if (h.capture_id != first.capture_id || b.root != a.root || b.frame_count != a.frame_count || b.fps != a.fps || b.units != a.units ||
        b.first_time != a.first_time || b.last_time != a.last_time || b.given_landmark_names != a.given_landmark_names) {
      throw Error(ErrorCode::kInvalidArgument, "the parts come from different captures: " + readers.front()->source() + " (" +
                                                   a.root.string() + ") and " + reader->source() + " (" + b.root.string() + ")");
    }
    check_part_settings(*reader, sample_settings);
    if (b.reference != a.reference || b.given_reference != a.given_reference) {
      throw Error(ErrorCode::kInvalidArgument, "the parts register to different reference frames (" + std::to_string(a.reference) +
                                                   " and " + std::to_string(b.reference) + ")");
    }
    if (h.range.first > next) {
      throw Error(ErrorCode::kInvalidArgument, "frames " + std::to_string(next) + ":" + std::to_string(h.range.first) + " are in no part");
    }
    if (h.range.first < next) {
      throw Error(ErrorCode::kInvalidArgument, "frames " + std::to_string(h.range.first) + ":" +
                                                   std::to_string(std::min(next, h.range.end)) + " are in two parts (" + reader->source() +
                                                   " and the part before it)");
    }
    next = h.range.end;
    headers.push_back(h);
  }
  if (next != first.capture.frame_count) {
    throw Error(ErrorCode::kInvalidArgument,
                "frames " + std::to_string(next) + ":" + std::to_string(first.capture.frame_count) + " are in no part");
  }
  SampledCapture capture = first.capture;
  capture.landmark_names = assembled_names(headers);
  PartsTiming timing;
  timing.parts = static_cast<int>(readers.size());
  std::vector<size_t> part_of;              // per frame of the capture, the part that holds it
  std::vector<std::vector<int>> positions;  // per part, its landmark names' places among the assembled names
  for (size_t p = 0; p < readers.size(); ++p) {
    const PartHeader& h = readers[p]->header();
    timing.seconds_mapping += h.seconds_mapping;
    timing.seconds_registration += h.seconds_registration;
    timing.seconds_selection += h.seconds_selection;
    part_of.insert(part_of.end(), static_cast<size_t>(h.range.size()), p);
    // Each frame's landmarks under the assembled names (a part adds only the names its frames found).
    std::vector<int>& position = positions.emplace_back();
    for (const std::string& n : h.capture.landmark_names) {
      const auto it = std::find(capture.landmark_names.begin(), capture.landmark_names.end(), n);
      if (it == capture.landmark_names.end())
        throw Error(ErrorCode::kCorrupt, readers[p]->source() + ": landmark '" + n + "' is neither the capture's nor one found");
      position.push_back(static_cast<int>(it - capture.landmark_names.begin()));
    }
  }
  const auto frame = [&](int i) {
    const size_t p = part_of[static_cast<size_t>(i)];
    const auto k = static_cast<size_t>(i - readers[p]->header().range.first);
    SampledFrame f = readers[p]->frame(k);
    if (f.dropped.empty()) {
      std::vector<Vec3> points(capture.landmark_names.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
      for (size_t l = 0; l < positions[p].size(); ++l) points[static_cast<size_t>(positions[p][l])] = f.landmarks[l];
      f.landmarks = std::move(points);
      // The map stays in its part (checked as read just now) and is read from there when a
      // step needs it: the maps are most of a part's bytes, not to be copied again.
      f.map = {};
      f.map_source = readers[p]->map_source(k);
    }
    if (options.progress) options.progress("assembling", i + 1, capture.frame_count);
    return f;
  };
  const auto where = [&](int i) { return readers[part_of[static_cast<size_t>(i)]]->source() + ": frame " + std::to_string(i); };
  PartsEncoder made;
  made.encoder = SequenceEncoder::of_sampled_frames(capture, options, frame, where);
  timing.seconds_reading = seconds_since(start);
  made.timing = timing;
  if (header_out) *header_out = first;
  made.parts = std::move(readers);
  return made;
}

void PartsTiming::add_to(EncodeReport& report) const {
  report.parts = parts;
  report.seconds_mapping = seconds_mapping;
  report.seconds_registration = seconds_registration;
  report.seconds_selection = seconds_selection;
  report.seconds_reading_parts = seconds_reading;
}

std::unique_ptr<StoredSequence> assemble_parts(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options,
                                               EncodeReport* report, PartHeader* header) {
  const PartsEncoder made = encoder_of_parts(parts, options, header);
  std::unique_ptr<StoredSequence> sequence = made.encoder->encode_sampled(report);
  if (report) made.timing.add_to(*report);  // the encode reads none of them
  return sequence;
}

}  // namespace facemorph
