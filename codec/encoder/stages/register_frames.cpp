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

std::vector<TrackedPoints> SequenceEncoder::track_frames() {
  const auto start = std::chrono::steady_clock::now();
  const auto count = static_cast<size_t>(frame_count());
  const auto reference = static_cast<size_t>(options_.reference_frame);
  report_.tracked_frames = 0;
  std::vector<TrackedPoints> tracked;
  // Which frames share too few interior landmarks with the reference, the reference's read once.
  const std::vector<Vec3> reference_points = landmarks(static_cast<int>(reference));
  std::vector<char> needs(count, 0);
  for (size_t i = 0; i < count; ++i)
    needs[i] = i != reference && needs_tracked_points(capture_.landmark_names, reference_points, landmarks(static_cast<int>(i)));
  const bool needed = std::find(needs.begin(), needs.end(), 1) != needs.end();
  if (!options_.track_landmarks || !needed) return tracked;
  const int size = options_.tracking.image_size;
  // Each frame's map read back from the store while its images are drawn (frame() is thread-safe).
  tracked = track_sequence(
      count, reference, [&](size_t i) { return disk_features(this->frame(static_cast<int>(i))->map, size); }, options_.tracking,
      options_.threads);
  std::vector<double> round_trips;
  double kept = 0;
  report_.tracked_points_fewest = std::numeric_limits<int>::max();
  for (size_t i = 0; i < count; ++i) {
    if (!needs[i]) continue;
    ++report_.tracked_frames;
    kept += static_cast<double>(tracked[i].reference.size());
    report_.tracked_points_fewest = std::min(report_.tracked_points_fewest, static_cast<int>(tracked[i].reference.size()));
    round_trips.insert(round_trips.end(), tracked[i].round_trip.begin(), tracked[i].round_trip.end());
  }
  report_.tracking_grid_points = tracked[reference].tried;
  report_.tracked_points_mean = report_.tracked_frames > 0 ? kept / report_.tracked_frames : 0.0;
  if (report_.tracked_frames == 0) report_.tracked_points_fewest = 0;
  std::sort(round_trips.begin(), round_trips.end());
  if (!round_trips.empty()) {
    report_.tracked_round_trip_median = round_trips[round_trips.size() / 2];
    report_.tracked_round_trip_p90 = round_trips[round_trips.size() * 9 / 10];
  }
  report_.seconds_tracking = seconds_since(start);
  return tracked;
}

void SequenceEncoder::register_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  const auto reference = static_cast<size_t>(options_.reference_frame);
  const std::shared_ptr<const MappedFrame> reference_frame = pin_reference();
  set_reference_geometry(*reference_frame, landmarks(static_cast<int>(reference)));
  registrations_ = std::make_unique<RegistrationStore>(options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
  registrations_->reset(static_cast<size_t>(count), geodesic_frame_ ? geodesic_frame_->partition : nullptr);
  const std::vector<TrackedPoints> tracked = track_frames();
  const std::vector<Vec3> reference_points = landmarks(static_cast<int>(reference));
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<char>& without_interior = without_interior_;
  without_interior.assign(static_cast<size_t>(count), 0);
  parallel_for(
      count, options_.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        // What the stores give back and take is no fault of the frame (a full disk): outside the try,
        // so that it ends the encode instead of dropping frames.
        const std::shared_ptr<const MappedFrame> frame = this->frame(i);
        const std::vector<Vec3> frame_points = this->landmarks(i);
        const bool needs = needs_tracked_points(capture_.landmark_names, reference_points, frame_points);
        const std::string& name = frame->name;
        DiskRegistration registered;
        try {
          // The frame's landmarks on the two disks, made here and dropped once registered (kept, they
          // were 2 kB a frame for the whole encode).
          DiskLandmarks landmarks =
              facemorph::disk_landmarks(capture_.landmark_names, reference_points, reference_frame->map, frame_points, frame->map);
          const bool took_tracked = !tracked.empty() && needs && !tracked[index].reference.empty();
          if (took_tracked) add_tracked_points(landmarks, tracked[index]);
          without_interior[index] = !took_tracked && index != reference && needs;
          if (landmarks.reference.size() < 3) {
            throw Error(ErrorCode::kInvalidArgument, name + ": frame " + std::to_string(source_index_[index]) + " shares only " +
                                                         std::to_string(landmarks.reference.size()) +
                                                         " landmarks with the reference frame (3 needed)");
          }
          try {
            // A frame registered through tracked points: a smoothing thin plate, not one through every point.
            RegistrationOptions registration = options_.registration;
            if (took_tracked) registration.smoothing = std::max(registration.smoothing, options_.tracking.registration_smoothing);
            registered = register_disks(landmarks, registration, geodesic_frame_.get());
          } catch (const Error& e) {
            throw Error(e.code(), name + ": registration: " + e.what());
          }
        } catch (const Error& e) {
          // The reference cannot be dropped here: every other frame is already registered to it.
          if (options_.strict || index == reference) throw;
          failures[index] = failure_of(e, name);
          return;
        }
        registrations_->put(index, std::move(registered));
      },
      [&](int done, int total) { progress("registering", done, total); });
  // Over the frames kept (a frame dropped here is registered neither way).
  report_.frames_without_interior_landmarks = 0;
  for (size_t i = 0; i < without_interior.size(); ++i)
    report_.frames_without_interior_landmarks += failures[i].code == ErrorCode::kOk && without_interior[i];
  auto_representation_ = Representation::kHLT;  // until choose_representation measures otherwise
  report_.representation = representation();
  drop_frames(failures);
  std::sort(report_.dropped.begin(), report_.dropped.end(), [](const DroppedFrame& a, const DroppedFrame& b) { return a.index < b.index; });
  report_.seconds_registration = seconds_since(start);
}

void SequenceEncoder::set_reference_geometry(const MappedFrame& reference, const std::vector<Vec3>& points) {
  const DensityEqualisingOptions& equalising = options_.density_equalising;
  const double half = half_area_radius(reference.map);
  double radial = equalising.radial == kAutoRadial ? (half < kCrowdedHalfAreaRadius ? 1.0 : 0.0) : equalising.radial;
  if (equalising.strength > 0) radial = 0;  // the flow, as asked
  reparametrisation_ = radial > 0 ? DiskReparametrisation::radial(reference.map, radial) : DiskReparametrisation(reference.map, equalising);
  report_.density_equalising = reparametrisation_.report();
  report_.density_equalising.half_area_radius_before = half;
  report_.radial_equalising = radial;
  geodesic_frame_.reset();
  if (options_.registration.method == RegistrationMethod::kFrame) {
    // The reference's frame, once: its landmarks on its own disk are the graph's points, and every
    // frame's Φ maps that frame's partition (paper §5). Frames lacking a landmark simply leave f̄
    // unconstrained there.
    const DiskLandmarks own = facemorph::disk_landmarks(capture_.landmark_names, points, reference.map, points, reference.map);
    try {
      geodesic_frame_ = std::make_shared<const GeodesicFrame>(make_geodesic_frame(reference.map, own.reference, own.on_rim));
    } catch (const Error& e) {
      throw Error(e.code(), reference.name + ": the reference frame's geodesic frame: " + e.what());
    }
  }
}

DiskLandmarks SequenceEncoder::frame_disk_landmarks(int i) const {
  const int reference = options_.reference_frame;
  return facemorph::disk_landmarks(capture_.landmark_names, landmarks(reference), frame(reference)->map, landmarks(i), frame(i)->map);
}

}  // namespace facemorph
