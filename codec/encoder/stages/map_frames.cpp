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

// Sets those of frame `index`'s landmarks `points` that lie farther from `mesh` than
// `tolerance` of its diagonal to NaN, with a warning each (strict: throws
// kInvalidArgument); says whether it set any.
bool ignore_far_landmarks(const Capture& capture, double tolerance, bool strict, const TriangleMesh& mesh, size_t index,
                          std::vector<Vec3>& points, std::vector<std::string>& warnings) {
  // A capture without landmarks (or a frame without any) needs no closest-point structure.
  if (mesh.positions.empty() || mesh.faces.empty() ||
      std::none_of(points.begin(), points.end(), [](const Vec3& p) { return p.allFinite(); }))
    return false;
  const PointToMesh surface(mesh);
  const double diagonal = bounding_box_diagonal(mesh.positions);
  const std::string& name = capture.frames[index].mesh.string();
  bool ignored = false;
  for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
    Vec3& point = points[l];
    if (!point.allFinite()) continue;
    const double distance = surface.distance(point);
    if (distance <= tolerance * diagonal) continue;
    char share[32];
    std::snprintf(share, sizeof share, "%.3g%%", 100 * distance / diagonal);
    const std::string what = "landmark '" + capture.landmark_names[l] + "' lies " + length_text(distance, capture.units) + " (" + share +
                             " of the frame's diagonal) off its surface, farther than the " + length_text(100 * tolerance, "%") +
                             " allowed";
    if (strict) throw Error(ErrorCode::kInvalidArgument, name + ": " + what);
    warnings.push_back(name + ": " + what + "; ignored");
    point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    ignored = true;
  }
  return ignored;
}

}  // namespace

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

void count_found_landmarks(EncodeReport& report, const FrameSummary& f, bool given_rim) {
  if (f.found) {
    ++report.orientation_found;
    report.weakest_up_evidence = std::min(report.weakest_up_evidence, f.found->up_evidence);
    report.up_from_hint += f.found->up_from_hint;
    report.worst_mirror_error = std::max(report.worst_mirror_error, f.found->mirror_error);
    ++report.orientation_methods[static_cast<size_t>(f.found->method)];
    report.lowest_face_confidence = std::min(report.lowest_face_confidence, f.found->confidence);
  }
  if (!given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers)) report.rim_markers_found = true;
}

namespace {

// Writes the landmarks map_frames found (FaceOrientation, rim markers) into the encoder's frames,
// under nose_tip, nose_bridge and rim_0.., for the registration; counts them in the report.
void adopt_found_landmarks(SequenceEncoder& encoder) {
  const std::vector<FrameSummary>& summaries = encoder.maps().summaries;
  auto name_index = [&](const std::string& name) { return encoder.landmark_name_index(name); };
  const std::vector<std::string>& names = encoder.capture().landmark_names;
  const bool given_rim = std::any_of(names.begin(), names.end(), [](const std::string& name) { return name.rfind("rim_", 0) == 0; });
  // No rim markers given: each normalised frame's rim points at the same disk angles.
  auto takes_rim = [&](const FrameSummary& f) { return !given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers); };
  // The names first, in the order they always came (the pose's, then the rim's): the registration
  // takes the landmarks in the names' order.
  size_t tip = 0, up = 0;
  if (std::any_of(summaries.begin(), summaries.end(), [](const FrameSummary& f) { return f.found.has_value(); })) {
    tip = name_index("nose_tip");
    up = name_index("nose_bridge");
  }
  std::vector<size_t> rim;
  if (std::any_of(summaries.begin(), summaries.end(), takes_rim)) {
    for (int k = 0; k < kFoundRimMarkers; ++k) rim.push_back(name_index("rim_" + std::to_string(k)));
  }
  // Then each frame's points read, set and stored once.
  for (size_t i = 0; i < summaries.size(); ++i) {
    const FrameSummary& f = summaries[i];
    if (!f.found && !takes_rim(f)) continue;
    std::vector<Vec3> points = encoder.landmarks(static_cast<int>(i));
    if (f.found) {
      points[tip] = f.found->nose_tip;
      points[up] = f.found->up;
    }
    if (takes_rim(f)) {
      for (size_t k = 0; k < rim.size(); ++k) points[rim[k]] = f.found_rim[k];
    }
    count_found_landmarks(encoder.report(), f, given_rim);
    encoder.put_landmarks(static_cast<int>(i), std::move(points));
  }
}

}  // namespace

void map_frames(SequenceEncoder& encoder) {
  const auto start = std::chrono::steady_clock::now();
  const EncodeOptions& options = encoder.options();
  const Capture& capture = encoder.capture();
  const int count = encoder.frame_count();
  // Each frame is read, mapped, summarised and put in the store by one thread, then released: the
  // maps in memory at once are one per thread (frame_store.hpp).
  FrameMaps& maps = encoder.maps();
  maps.start(static_cast<size_t>(count), options.spill_frames ? FrameStore::Mode::kSpill : FrameStore::Mode::kMemory);
  maps.summaries.assign(static_cast<size_t>(count), {});
  maps.textures.assign(static_cast<size_t>(count), {});
  FrameStore& store = maps.store();
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<std::vector<std::string>> warnings(static_cast<size_t>(count));
  const std::optional<std::optional<Vec3>> given_hint = encoder.given_vertical_hint();
  std::optional<Vec3> vertical_hint = given_hint.value_or(std::nullopt);
  if (options.find_landmarks && !given_hint) {
    const FrameStore::Hold held = store.hold();  // the frame being prepared
    vertical_hint = find_vertical_hint(
        capture, options.reference_frame, options.largest_component, [&](size_t i) { return encoder.landmarks(static_cast<int>(i)); },
        [&](int done, int total) { encoder.progress("finding the face's up", done, total); });
  }
  if (!options.find_landmarks) vertical_hint.reset();
  parallel_for(
      count, options.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        const std::string name = capture.frames[index].mesh.string();
        const FrameStore::Hold held = store.hold();
        MappedFrame mapped;
        // The frame's landmarks from their store and back: outside the try, as the map's put below
        // (a full disk is no fault of the frame).
        std::vector<Vec3> points = encoder.landmarks(i);
        bool ignored = false;
        try {
          const TriangleMesh mesh = read_mesh(capture.mesh_path(index), {.allow_missing_texture = !options.texture});
          ignored = ignore_far_landmarks(capture, options.landmark_tolerance, options.strict, mesh, index, points, warnings[index]);
          const FrameLandmarks landmarks = frame_landmarks(capture.landmark_names, points);
          if ((!landmarks.centre || !landmarks.up) && !options.find_landmarks) {
            throw Error(ErrorCode::kInvalidArgument,
                        name + ": frame " + std::to_string(encoder.source_index(i)) +
                            " lacks the landmarks nose_tip and nose_bridge (or between_eyes) that fix its disk's pose");
          }
          maps.textures[index] = mesh.texture;
          MapFrameOptions map_options;
          map_options.keep_largest_component = options.largest_component;
          map_options.repair_non_manifold = !options.strict;  // --strict refuses what repairs would change
          map_options.conformal = options.conformal;
          map_options.find_orientation = options.find_landmarks;
          map_options.vertical_hint = vertical_hint;
          mapped = map_frame(mesh, name, landmarks, map_options);
        } catch (const Error& e) {
          if (options.strict) throw;
          failures[index] = frame_failure(e, name);
          return;
        }
        FrameSummary& summary = maps.summaries[index];
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
        if (ignored) encoder.put_landmarks(i, std::move(points));
        store.put(index, std::move(mapped));
      },
      [&](int done, int total) { encoder.progress("mapping", done, total); });
  for (size_t i = 0; i < warnings.size(); ++i) encoder.add_frame_warnings(static_cast<int>(i), std::move(warnings[i]));
  encoder.drop_frames(failures);
  adopt_found_landmarks(encoder);
  encoder.pin_reference();
  EncodeReport& report = encoder.report();
  report.reference_frame = encoder.source_index(encoder.options().reference_frame);
  report.seconds_mapping = seconds_since(start);
}

}  // namespace facemorph
