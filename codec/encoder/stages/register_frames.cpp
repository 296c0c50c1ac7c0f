// The encoder's second stage: every frame's landmarks on its disk paired with the reference's
// (tracked points added where it shares too few), and the frame registered to the reference's disk
// through them; the reference's reparametrised disk and geodesic frame made first, once.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/util/parallel.hpp"
#include "codec/encoder/landmarks/landmark_tracking.hpp"
#include "codec/encoder/registration/registration.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace facemorph {

DiskLandmarks disk_landmarks(const Capture& capture, size_t reference, const DiskMap& reference_map, size_t frame,
                             const DiskMap& frame_map) {
  return disk_landmarks(capture.landmark_names, capture.landmarks[reference], reference_map, capture.landmarks[frame], frame_map);
}

DiskLandmarks disk_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const DiskMap& reference_map,
                             const std::vector<Vec3>& frame, const DiskMap& frame_map) {
  DiskLandmarks landmarks;
  const PointToMesh on_reference(reference_map.surface), on_frame(frame_map.surface);
  for (size_t l = 0; l < names.size(); ++l) {
    const Vec3 &p = reference[l], &q = frame[l];
    if (!p.allFinite() || !q.allFinite()) continue;
    Vec2 wp = disk_point(reference_map, on_reference.closest(p)), wq = disk_point(frame_map, on_frame.closest(q));
    const bool rim = names[l].rfind("rim_", 0) == 0;
    if (rim) {
      // A marker on the rim interpolates along a boundary chord: put it on the circle.
      wp.normalize();
      wq.normalize();
    }
    landmarks.reference.push_back(wp);
    landmarks.frame.push_back(wq);
    landmarks.on_rim.push_back(rim ? 1 : 0);
  }
  return landmarks;
}

namespace {

// The reference's grid tracked onto every frame (options().tracking) when some frame needs tracked
// points (needs_tracked_points), with the report's tracking counts; empty otherwise.
std::vector<TrackedPoints> track_frames(const SequenceEncoder& encoder, EncodeReport& report) {
  const auto start = std::chrono::steady_clock::now();
  const EncodeOptions& options = encoder.options();
  const auto count = static_cast<size_t>(encoder.frame_count());
  const auto reference = static_cast<size_t>(options.reference_frame);
  report.tracked_frames = 0;
  std::vector<TrackedPoints> tracked;
  // Which frames share too few interior landmarks with the reference, the reference's read once.
  const std::vector<Vec3> reference_points = encoder.landmarks(static_cast<int>(reference));
  const std::vector<std::string>& names = encoder.capture().landmark_names;
  std::vector<char> needs(count, 0);
  for (size_t i = 0; i < count; ++i)
    needs[i] = i != reference && needs_tracked_points(names, reference_points, encoder.landmarks(static_cast<int>(i)));
  const bool needed = std::find(needs.begin(), needs.end(), 1) != needs.end();
  if (!options.track_landmarks || !needed) return tracked;
  const int size = options.tracking.image_size;
  // Each frame's map read back from the store while its images are drawn (frame() is thread-safe).
  tracked = track_sequence(
      count, reference, [&](size_t i) { return disk_features(encoder.frame(static_cast<int>(i))->map, size); }, options.tracking,
      options.threads);
  std::vector<double> round_trips;
  double kept = 0;
  report.tracked_points_fewest = std::numeric_limits<int>::max();
  for (size_t i = 0; i < count; ++i) {
    if (!needs[i]) continue;
    ++report.tracked_frames;
    kept += static_cast<double>(tracked[i].reference.size());
    report.tracked_points_fewest = std::min(report.tracked_points_fewest, static_cast<int>(tracked[i].reference.size()));
    round_trips.insert(round_trips.end(), tracked[i].round_trip.begin(), tracked[i].round_trip.end());
  }
  report.tracking_grid_points = tracked[reference].tried;
  report.tracked_points_mean = report.tracked_frames > 0 ? kept / report.tracked_frames : 0.0;
  if (report.tracked_frames == 0) report.tracked_points_fewest = 0;
  std::sort(round_trips.begin(), round_trips.end());
  if (!round_trips.empty()) {
    report.tracked_round_trip_median = round_trips[round_trips.size() / 2];
    report.tracked_round_trip_p90 = round_trips[round_trips.size() * 9 / 10];
  }
  report.seconds_tracking = seconds_since(start);
  return tracked;
}

}  // namespace

void register_frames(SequenceEncoder& encoder) {
  const auto start = std::chrono::steady_clock::now();
  const EncodeOptions& options = encoder.options();
  const std::vector<std::string>& names = encoder.capture().landmark_names;
  EncodeReport& report = encoder.report();
  const int count = encoder.frame_count();
  const auto reference = static_cast<size_t>(options.reference_frame);
  const std::shared_ptr<const MappedFrame> reference_frame = encoder.pin_reference();
  FrameRegistrations& registrations = encoder.registrations();
  set_reference_geometry(registrations, *reference_frame, names, encoder.landmarks(static_cast<int>(reference)), options.density_equalising,
                         options.registration.method, report);
  registrations.start(static_cast<size_t>(count), options.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
  const std::vector<TrackedPoints> tracked = track_frames(encoder, report);
  const std::vector<Vec3> reference_points = encoder.landmarks(static_cast<int>(reference));
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<char>& without_interior = registrations.without_interior;
  without_interior.assign(static_cast<size_t>(count), 0);
  parallel_for(
      count, options.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        // What the stores give back and take is no fault of the frame (a full disk): outside the try,
        // so that it ends the encode instead of dropping frames.
        const std::shared_ptr<const MappedFrame> frame = encoder.frame(i);
        const std::vector<Vec3> frame_points = encoder.landmarks(i);
        const bool needs = needs_tracked_points(names, reference_points, frame_points);
        const std::string& name = frame->name;
        DiskRegistration registered;
        try {
          // The frame's landmarks on the two disks, made here and dropped once registered (kept, they
          // were 2 kB a frame for the whole encode).
          DiskLandmarks landmarks = disk_landmarks(names, reference_points, reference_frame->map, frame_points, frame->map);
          const bool took_tracked = !tracked.empty() && needs && !tracked[index].reference.empty();
          if (took_tracked) add_tracked_points(landmarks, tracked[index]);
          without_interior[index] = !took_tracked && index != reference && needs;
          if (landmarks.reference.size() < 3) {
            throw Error(ErrorCode::kInvalidArgument, name + ": frame " + std::to_string(encoder.source_index(i)) + " shares only " +
                                                         std::to_string(landmarks.reference.size()) +
                                                         " landmarks with the reference frame (3 needed)");
          }
          try {
            // A frame registered through tracked points: a smoothing thin plate, not one through every point.
            RegistrationOptions registration = options.registration;
            if (took_tracked) registration.smoothing = std::max(registration.smoothing, options.tracking.registration_smoothing);
            registered = register_disks(landmarks, registration, registrations.geodesic_frame());
          } catch (const Error& e) {
            throw Error(e.code(), name + ": registration: " + e.what());
          }
        } catch (const Error& e) {
          // The reference cannot be dropped here: every other frame is already registered to it.
          if (options.strict || index == reference) throw;
          failures[index] = frame_failure(e, name);
          return;
        }
        registrations.put(index, std::move(registered));
      },
      [&](int done, int total) { encoder.progress("registering", done, total); });
  // Over the frames kept (a frame dropped here is registered neither way).
  report.frames_without_interior_landmarks = 0;
  for (size_t i = 0; i < without_interior.size(); ++i)
    report.frames_without_interior_landmarks += failures[i].code == ErrorCode::kOk && without_interior[i];
  encoder.reset_representation();
  encoder.drop_frames(failures);
  std::sort(report.dropped.begin(), report.dropped.end(), [](const DroppedFrame& a, const DroppedFrame& b) { return a.index < b.index; });
  report.seconds_registration = seconds_since(start);
}

void set_reference_geometry(FrameRegistrations& registrations, const MappedFrame& reference, const std::vector<std::string>& names,
                            const std::vector<Vec3>& points, const DensityEqualisingOptions& equalising, RegistrationMethod method,
                            EncodeReport& report) {
  const double half = half_area_radius(reference.map);
  double radial = equalising.radial == kAutoRadial ? (half < kCrowdedHalfAreaRadius ? 1.0 : 0.0) : equalising.radial;
  if (equalising.strength > 0) radial = 0;  // the flow, as asked
  DiskReparametrisation reparametrisation =
      radial > 0 ? DiskReparametrisation::radial(reference.map, radial) : DiskReparametrisation(reference.map, equalising);
  report.density_equalising = reparametrisation.report();
  report.density_equalising.half_area_radius_before = half;
  report.radial_equalising = radial;
  std::shared_ptr<const GeodesicFrame> geodesic_frame;
  if (method == RegistrationMethod::kFrame) {
    // The reference's frame, once: its landmarks on its own disk are the graph's points, and every
    // frame's Φ maps that frame's partition (paper §5). Frames lacking a landmark simply leave f̄
    // unconstrained there.
    const DiskLandmarks own = disk_landmarks(names, points, reference.map, points, reference.map);
    try {
      geodesic_frame = std::make_shared<const GeodesicFrame>(make_geodesic_frame(reference.map, own.reference, own.on_rim));
    } catch (const Error& e) {
      throw Error(e.code(), reference.name + ": the reference frame's geodesic frame: " + e.what());
    }
  }
  registrations.set_reference(std::move(reparametrisation), std::move(geodesic_frame));
}

DiskLandmarks SequenceEncoder::frame_disk_landmarks(int i) const {
  const int reference = options_.reference_frame;
  return disk_landmarks(capture_.landmark_names, landmarks(reference), frame(reference)->map, landmarks(i), frame(i)->map);
}

}  // namespace facemorph
