// The encoder's first stage: every frame read, prepared, conformally mapped and normalised (on the
// threads, each map put in the frame store as it is made); frames that fail dropped and named; the
// landmarks found on the frames (nose tip, up, rim markers) adopted under their names.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/landmarks/face_facing.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/landmarks/face_orientation.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {

namespace {

std::string length_text(double value, const std::string& units) {
  char text[64];
  std::snprintf(text, sizeof text, "%.3g %s", value, units.c_str());
  return text;
}

}  // namespace

SequenceEncoder::FrameFailure SequenceEncoder::failure_of(const Error& e, const std::string& name) {
  // Stages name their frame; the report names it once.
  std::string reason = e.what();
  if (reason.rfind(name + ": ", 0) == 0) reason.erase(0, name.size() + 2);
  return {e.code(), reason};
}

bool SequenceEncoder::ignore_far_landmarks(const TriangleMesh& mesh, size_t index, std::vector<Vec3>& points,
                                           std::vector<std::string>& warnings) const {
  // A capture without landmarks (or a frame without any) needs no closest-point structure.
  if (mesh.positions.empty() || mesh.faces.empty() ||
      std::none_of(points.begin(), points.end(), [](const Vec3& p) { return p.allFinite(); }))
    return false;
  const PointToMesh surface(mesh);
  const double diagonal = bounding_box_diagonal(mesh.positions);
  const std::string& name = capture_.frames[index].mesh.string();
  bool ignored = false;
  for (size_t l = 0; l < capture_.landmark_names.size(); ++l) {
    Vec3& point = points[l];
    if (!point.allFinite()) continue;
    const double distance = surface.distance(point);
    if (distance <= options_.landmark_tolerance * diagonal) continue;
    char share[32];
    std::snprintf(share, sizeof share, "%.3g%%", 100 * distance / diagonal);
    const std::string what = "landmark '" + capture_.landmark_names[l] + "' lies " + length_text(distance, capture_.units) + " (" + share +
                             " of the frame's diagonal) off its surface, farther than the " +
                             length_text(100 * options_.landmark_tolerance, "%") + " allowed";
    if (options_.strict) throw Error(ErrorCode::kInvalidArgument, name + ": " + what);
    warnings.push_back(name + ": " + what + "; ignored");
    point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    ignored = true;
  }
  return ignored;
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
    if (summaries_.size() == failures.size() && !summaries_[i].name.empty()) dropped_summaries_[source_index_[i]] = summaries_[i];
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
  compact(summaries_);
  if (store_ && store_->size() == failures.size()) store_->keep(kept);
  if (pinned_index_ >= 0) {
    // The pinned frame keeps its pin under its new index (a dropped one loses it).
    const auto it = std::find(kept.begin(), kept.end(), static_cast<size_t>(pinned_index_));
    pinned_index_ = it == kept.end() ? -1 : static_cast<int>(it - kept.begin());
    if (pinned_index_ < 0) pinned_.reset();
  }
  compact(textures_);
  compact(without_interior_);
  if (registrations_ && registrations_->size() == failures.size()) registrations_->keep(kept);
}

std::optional<Vec3> find_vertical_hint(const Capture& capture, int reference, bool largest_component,
                                       const std::function<std::vector<Vec3>(size_t)>& landmarks,
                                       const std::function<void(int, int)>& progress) {
  // The first frame from the reference on that lacks its pose landmarks and whose own surface says
  // clearly which way is up: its up direction settles the frames whose surfaces do not.
  const size_t count = capture.frames.size();
  for (size_t step = 0; step < count; ++step) {
    const size_t index = (static_cast<size_t>(reference) + step) % count;
    const FrameLandmarks given = frame_landmarks(capture.landmark_names, landmarks(index));
    if (given.centre && given.up) continue;
    try {
      PrepareOptions prepare;
      prepare.keep_largest_component = largest_component;
      const PreparedFrame p =
          prepare_frame(read_mesh(capture.mesh_path(index), {.allow_missing_texture = true}), capture.frames[index].mesh.string(), prepare);
      FaceFindingOptions options;
      options.progress = progress;
      // Read as the frame's own mapping reads it: a whole head's face along its filled holes.
      const Vec3 holes = filled_holes_facing(p);
      return find_face_facing(p.mesh, nullptr, capture.frames[index].mesh.string(), nullptr, holes.norm() > 0 ? &holes : nullptr, options)
          .vertical;
    } catch (const Error&) {
      // This frame does not say; the next may. Its own mapping reports why.
    }
  }
  return std::nullopt;
}

const char* EncodeReport::main_orientation_method() const {
  const auto most = std::max_element(orientation_methods.begin(), orientation_methods.end());
  return face_finding_method_name(static_cast<FaceFindingMethod>(most - orientation_methods.begin()));
}

void SequenceEncoder::count_found_landmarks(const FrameSummary& f, bool given_rim) {
  if (f.found) {
    ++report_.orientation_found;
    report_.weakest_up_evidence = std::min(report_.weakest_up_evidence, f.found->up_evidence);
    report_.up_from_hint += f.found->up_from_hint;
    report_.worst_mirror_error = std::max(report_.worst_mirror_error, f.found->mirror_error);
    ++report_.orientation_methods[static_cast<size_t>(f.found->method)];
    report_.lowest_face_confidence = std::min(report_.lowest_face_confidence, f.found->confidence);
  }
  if (!given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers)) report_.rim_markers_found = true;
}

void SequenceEncoder::adopt_found_landmarks() {
  auto name_index = [&](const std::string& name) {
    int index = capture_.landmark_index(name);
    if (index >= 0) return static_cast<size_t>(index);
    capture_.landmark_names.push_back(name);
    return capture_.landmark_names.size() - 1;
  };
  const bool given_rim = std::any_of(capture_.landmark_names.begin(), capture_.landmark_names.end(),
                                     [](const std::string& name) { return name.rfind("rim_", 0) == 0; });
  // No rim markers given: each normalised frame's rim points at the same disk angles.
  auto takes_rim = [&](const FrameSummary& f) { return !given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers); };
  // The names first, in the order they always came (the pose's, then the rim's): the registration
  // takes the landmarks in the names' order.
  size_t tip = 0, up = 0;
  if (std::any_of(summaries_.begin(), summaries_.end(), [](const FrameSummary& f) { return f.found.has_value(); })) {
    tip = name_index("nose_tip");
    up = name_index("nose_bridge");
  }
  std::vector<size_t> rim;
  if (std::any_of(summaries_.begin(), summaries_.end(), takes_rim)) {
    for (int k = 0; k < kFoundRimMarkers; ++k) rim.push_back(name_index("rim_" + std::to_string(k)));
  }
  // Then each frame's points read, set and stored once.
  for (size_t i = 0; i < summaries_.size(); ++i) {
    const FrameSummary& f = summaries_[i];
    if (!f.found && !takes_rim(f)) continue;
    std::vector<Vec3> points = landmarks(static_cast<int>(i));
    if (f.found) {
      points[tip] = f.found->nose_tip;
      points[up] = f.found->up;
    }
    if (takes_rim(f)) {
      for (size_t k = 0; k < rim.size(); ++k) points[rim[k]] = f.found_rim[k];
    }
    count_found_landmarks(f, given_rim);
    landmarks_->put(i, std::move(points));
  }
}

void SequenceEncoder::map_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  // Each frame is read, mapped, summarised and put in the store by one thread, then released: the
  // maps in memory at once are one per thread (frame_store.hpp).
  store_ = std::make_unique<FrameStore>(options_.spill_frames ? FrameStore::Mode::kSpill : FrameStore::Mode::kMemory);
  store_->reset(static_cast<size_t>(count));
  pinned_index_ = -1;
  pinned_.reset();
  summaries_.assign(static_cast<size_t>(count), {});
  textures_.assign(static_cast<size_t>(count), {});
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<std::vector<std::string>> warnings(static_cast<size_t>(count));
  std::optional<Vec3> vertical_hint = vertical_hint_;
  if (options_.find_landmarks && !vertical_hint_set_) {
    const FrameStore::Hold held = store_->hold();  // the frame being prepared
    vertical_hint = find_vertical_hint(
        capture_, options_.reference_frame, options_.largest_component, [&](size_t i) { return landmarks(static_cast<int>(i)); },
        [&](int done, int total) { progress("finding the face's up", done, total); });
  }
  if (!options_.find_landmarks) vertical_hint.reset();
  parallel_for(
      count, options_.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        const std::string name = capture_.frames[index].mesh.string();
        const FrameStore::Hold held = store_->hold();
        MappedFrame mapped;
        // The frame's landmarks from their store and back: outside the try, as the map's put below
        // (a full disk is no fault of the frame).
        std::vector<Vec3> points = this->landmarks(i);
        bool ignored = false;
        try {
          const TriangleMesh mesh = read_mesh(capture_.mesh_path(index), {.allow_missing_texture = !options_.texture});
          ignored = ignore_far_landmarks(mesh, index, points, warnings[index]);
          const FrameLandmarks landmarks = frame_landmarks(capture_.landmark_names, points);
          if ((!landmarks.centre || !landmarks.up) && !options_.find_landmarks) {
            throw Error(ErrorCode::kInvalidArgument,
                        name + ": frame " + std::to_string(source_index_[index]) +
                            " lacks the landmarks nose_tip and nose_bridge (or between_eyes) that fix its disk's pose");
          }
          textures_[index] = mesh.texture;
          MapFrameOptions map_options;
          map_options.keep_largest_component = options_.largest_component;
          map_options.repair_non_manifold = !options_.strict;  // --strict refuses what repairs would change
          map_options.conformal = options_.conformal;
          map_options.find_orientation = options_.find_landmarks;
          map_options.vertical_hint = vertical_hint;
          mapped = map_frame(mesh, name, landmarks, map_options);
        } catch (const Error& e) {
          if (options_.strict) throw;
          failures[index] = failure_of(e, name);
          return;
        }
        FrameSummary& summary = summaries_[index];
        summary.name = mapped.name;
        summary.vertices = mapped.prepared.mesh.vertex_count();
        summary.holes_filled = static_cast<int>(mapped.prepared.report.holes.size());
        summary.repair = mapped.prepared.report.summary();
        summary.repair_totals = mapped.prepared.report.totals();
        summary.conformal_method = mapped.map.report.method;
        summary.conformal_fallback_reason = mapped.map.report.fallback_reason;
        summary.has_uvs = mapped.map.surface.has_uvs();
        summary.has_colours = mapped.map.surface.has_colours();
        summary.found = mapped.found;
        summary.found_rim = mapped.found_rim;
        // Outside the try: a map the store cannot write ends the encode (it is no fault of the frame).
        if (ignored) landmarks_->put(index, std::move(points));
        store_->put(index, std::move(mapped));
      },
      [&](int done, int total) { progress("mapping", done, total); });
  for (size_t i = 0; i < warnings.size(); ++i) {
    report_.warnings.insert(report_.warnings.end(), warnings[i].begin(), warnings[i].end());
    if (!warnings[i].empty()) warnings_by_frame_[source_index_[i]] = std::move(warnings[i]);
  }
  drop_frames(failures);
  adopt_found_landmarks();
  pin_reference();
  report_.reference_frame = source_index_[static_cast<size_t>(options_.reference_frame)];
  report_.seconds_mapping = seconds_since(start);
}

}  // namespace facemorph
