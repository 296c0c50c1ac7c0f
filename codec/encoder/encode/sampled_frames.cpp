// The encoder's frames handed out after sampling, and taken back in: the staged encode's seam
// (staged_encode.hpp, spec/part-file.md). A frame handed out by one encoder and added to another
// leaves the second where map_frames, register_frames and sample_frames would have left it.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/encoder/encode/registration_store.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <numeric>

namespace facemorph {

namespace {

// A sampled frame's registration (add_sampled_frame), through `partition` (the reference's
// geodesic frame's, null without one); kCorrupt naming the frame where the bytes are not one.
DiskRegistration read_sampled_registration(const std::string& name, const std::vector<char>& bytes,
                                           const std::shared_ptr<const PartitionMesh>& partition) {
  // From a part file: bytes the stores never wrote themselves, so read as untrusted.
  try {
    DiskRegistration f = RegistrationStore::deserialize(bytes.data(), bytes.size(), partition);
    RegistrationStore::check(f);
    return f;
  } catch (const Error& e) {
    throw Error(ErrorCode::kCorrupt, name + ": its registration: " + e.what());
  }
}

}  // namespace

SequenceEncoder::SequenceEncoder(const SampledCapture& capture, EncodeOptions options) : options_(std::move(options)) {
  if (capture.frame_count <= 0) throw Error(ErrorCode::kInvalidArgument, "the capture has no frames");
  if (capture.reference < 0 || capture.reference >= capture.frame_count || capture.given_reference < 0 ||
      capture.given_reference >= capture.frame_count) {
    throw Error(ErrorCode::kInvalidArgument, "reference frame " + std::to_string(capture.reference) + " is not a frame of the capture");
  }
  capture_.root = capture.root;
  capture_.fps = capture.fps;
  capture_.units = capture.units;
  capture_.landmark_names = capture.landmark_names;
  first_time_ = capture.first_time;
  last_time_ = capture.last_time;
  given_reference_ = capture.given_reference;
  sampled_reference_ = capture.reference;
  given_rim_ = std::any_of(capture.given_landmark_names.begin(), capture.given_landmark_names.end(),
                           [](const std::string& name) { return name.rfind("rim_", 0) == 0; });
  options_.reference_frame = 0;  // until the reference's frame comes (add_sampled_frame)
  check_encode_options(options_, capture.frame_count);
  const auto count = static_cast<size_t>(capture.frame_count);
  const SpillMode mode = options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory;
  maps_.start(count, mode);
  landmarks_ = make_landmark_store(mode);
  landmarks_->reset(count);
  selection_.start(count, mode);
  report_.reference_frame = capture.reference;
}

std::unique_ptr<SequenceEncoder> SequenceEncoder::of_sampled_frames(const SampledCapture& capture, EncodeOptions options,
                                                                    const std::function<SampledFrame(int)>& frame,
                                                                    const std::function<std::string(int)>& where) {
  std::unique_ptr<SequenceEncoder> encoder(new SequenceEncoder(capture, std::move(options)));
  for (int k = 0; k < capture.frame_count; ++k) {
    SampledFrame f = frame(k);
    try {
      encoder->add_sampled_frame(std::move(f));
    } catch (const Error& e) {
      throw Error(e.code(), where(k) + ": " + e.what());
    }
  }
  encoder->finish_sampled_frames();
  return encoder;
}

void SequenceEncoder::add_sampled_frame(SampledFrame&& f) {
  if (f.index != next_sampled_) {
    throw Error(ErrorCode::kInvalidArgument,
                "frame " + std::to_string(f.index) + " came where frame " + std::to_string(next_sampled_) + " was due");
  }
  if (f.index >= static_cast<int>(maps_.size()))
    throw Error(ErrorCode::kInvalidArgument, "frame " + std::to_string(f.index) + " is past the capture");
  ++next_sampled_;
  if (!capture_.frames.empty() && !(f.time > capture_.frames.back().time)) {
    throw Error(ErrorCode::kInvalidArgument, f.name + ": its time " + std::to_string(f.time) + " s does not follow the frame before it");
  }
  report_.warnings.insert(report_.warnings.end(), f.warnings.begin(), f.warnings.end());
  if (!f.warnings.empty()) warnings_by_frame_[f.index] = f.warnings;
  if (f.mapped) count_found_landmarks(report_, f.summary, given_rim_);
  if (!f.dropped.empty()) {
    if (f.index == sampled_reference_) throw Error(ErrorCode::kInvalidArgument, f.name + ": the reference frame is given as dropped");
    report_.dropped.push_back({f.index, f.name, f.time, f.dropped});
    if (f.mapped) dropped_summaries_[f.index] = std::move(f.summary);
    return;
  }
  if (f.landmarks.size() != capture_.landmark_names.size()) {
    throw Error(ErrorCode::kInvalidArgument, f.name + ": " + std::to_string(f.landmarks.size()) + " landmarks for " +
                                                 std::to_string(capture_.landmark_names.size()) + " names");
  }
  const size_t nodes = selection_.weights().size();
  if (f.selection.local.size() != nodes || f.selection.normal.size() != nodes) {
    throw Error(ErrorCode::kInvalidArgument,
                f.name + ": its selection samples are not the selection grid's " + std::to_string(nodes) + " nodes");
  }
  const size_t i = capture_.frames.size();
  if (f.index == sampled_reference_) {
    const std::vector<char> bytes = f.map_source ? f.map_source() : f.map;
    const MappedFrame mapped = FrameStore::deserialize(bytes.data(), bytes.size());
    // Every stage reads the reference: its map is pinned, its disk reparametrised, and (kFrame)
    // its geodesic frame built again from its disk and landmarks, as register_frames built it.
    options_.reference_frame = static_cast<int>(i);
    maps_.pin(static_cast<int>(i), std::make_shared<const MappedFrame>(mapped));
    set_reference_geometry(registrations_, *maps_.frame(static_cast<int>(i)), capture_.landmark_names, f.landmarks,
                           options_.density_equalising, options_.registration.method, report_);
    registrations_.start(maps_.size(), options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
    for (auto& [k, pending] : pending_registrations_)
      registrations_.put(k, read_sampled_registration(capture_.frames[k].mesh.string(), pending, registrations_.partition()));
    pending_registrations_.clear();
    selection_.outline(i).local = f.selection.local;  // pose_centre reads them after the samples are released
  }
  if (registrations_.started()) {
    registrations_.put(i, read_sampled_registration(f.name, f.registration, registrations_.partition()));
  } else {
    // Before the reference came, a registration through its geodesic frame has no partition yet.
    pending_registrations_.emplace_back(i, std::move(f.registration));
  }
  if (f.map_source) {
    maps_.store().put_source(i, std::move(f.map_source));
  } else {
    maps_.store().put(i, FrameStore::deserialize(f.map.data(), f.map.size()));
  }
  capture_.frames.push_back({f.name, f.time});
  source_index_.push_back(f.index);
  maps_.summaries.push_back(std::move(f.summary));
  maps_.textures.push_back(std::move(f.texture));
  registrations_.without_interior.push_back(f.without_interior_landmarks ? 1 : 0);
  landmarks_->put(i, std::move(f.landmarks));
  SelectionFrame& outline = selection_.outline(i);
  outline.time = f.selection.time;
  outline.pose = f.selection.pose;
  outline.diagonal = f.selection.diagonal;
  selection_.put(i, std::move(f.selection.local), std::move(f.selection.normal));
}

void SequenceEncoder::finish_sampled_frames() {
  if (next_sampled_ != static_cast<int>(maps_.size())) {
    throw Error(ErrorCode::kInvalidArgument,
                "frames " + std::to_string(next_sampled_) + " to " + std::to_string(maps_.size() - 1) + " never came");
  }
  if (!registrations_.started()) throw Error(ErrorCode::kInvalidArgument, "the reference frame never came");
  const size_t kept = capture_.frames.size();
  std::vector<size_t> indices(kept);
  std::iota(indices.begin(), indices.end(), 0);
  landmarks_->keep(indices);
  const size_t before = maps_.size();
  maps_.keep(indices, before);
  registrations_.keep(indices, before);
  selection_.keep_first(kept);
  if (given_reference_ != sampled_reference_) {
    // As drop_frames says it: after every frame's own warnings.
    const auto given =
        std::find_if(report_.dropped.begin(), report_.dropped.end(), [&](const DroppedFrame& d) { return d.index == given_reference_; });
    if (given == report_.dropped.end())
      throw Error(ErrorCode::kInvalidArgument, "the reference frame moved from a frame that was not dropped");
    report_.warnings.push_back(given->name + ": the reference frame was dropped; " +
                               capture_.frames[static_cast<size_t>(options_.reference_frame)].mesh.string() + " is the reference instead");
  }
  const std::vector<char>& without_interior = registrations_.without_interior;
  report_.frames_without_interior_landmarks = static_cast<int>(std::count(without_interior.begin(), without_interior.end(), 1));
  // The representation stays a new encoder's (hl+t, reported as such once plan or adopt_plan adopts
  // one): nothing registered it before these frames, so there is no earlier choice to reset.
  report_.peak_selection_samples_in_memory = 0;
}

void SequenceEncoder::set_source_indices(std::vector<int> indices) {
  if (indices.size() != capture_.frames.size() || !std::is_sorted(indices.begin(), indices.end()) ||
      std::adjacent_find(indices.begin(), indices.end()) != indices.end() || (!indices.empty() && indices.front() < 0)) {
    throw Error(ErrorCode::kInvalidArgument, "set_source_indices: not an increasing index for each frame");
  }
  if (maps_.size() != 0) throw Error(ErrorCode::kInternal, "set_source_indices: the frames are mapped already");
  source_index_ = std::move(indices);
}

void SequenceEncoder::for_each_sampled_frame(const std::function<void(SampledFrame&&)>& take) const {
  if (!selection_.sampled()) throw Error(ErrorCode::kInternal, "for_each_sampled_frame: the frames are not sampled (sample_frames first)");
  // The frames kept (in source_index_) and dropped (report_.dropped), both increasing: merged.
  auto dropped = report_.dropped.begin();
  size_t kept = 0;
  while (kept < capture_.frames.size() || dropped != report_.dropped.end()) {
    SampledFrame f;
    const bool next_dropped = dropped != report_.dropped.end() && (kept == capture_.frames.size() || dropped->index < source_index_[kept]);
    f.index = next_dropped ? dropped->index : source_index_[kept];
    if (const auto w = warnings_by_frame_.find(f.index); w != warnings_by_frame_.end()) f.warnings = w->second;
    if (next_dropped) {
      f.name = dropped->name;
      f.time = dropped->time;
      f.dropped = dropped->reason;
      if (const auto s = dropped_summaries_.find(f.index); s != dropped_summaries_.end()) {
        f.mapped = true;
        f.summary = s->second;
      }
      ++dropped;
      take(std::move(f));
      continue;
    }
    const auto i = static_cast<int>(kept++);
    f.name = capture_.frames[static_cast<size_t>(i)].mesh.string();
    f.time = capture_.frames[static_cast<size_t>(i)].time;
    f.mapped = true;
    f.summary = frame_summary(i);
    f.texture = texture_path(i);
    f.landmarks = landmarks(i);
    f.map = FrameStore::serialize(*frame(i));
    f.registration = RegistrationStore::serialize(*registration(i));
    f.without_interior_landmarks = registrations_.without_interior[static_cast<size_t>(i)] != 0;
    f.selection = *selection_.frame(i);
    take(std::move(f));
  }
}

}  // namespace facemorph
