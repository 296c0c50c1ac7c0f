// Landmark correspondence by optical flow on the disk images (landmark_tracking.hpp): fmsynth's
// faces, whose every material point is known at every time, tracked from a reference frame.
#include "codec/encoder/landmarks/landmark_tracking.hpp"
#include "codec/core/container/file_metadata.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace facemorph {
namespace {

struct Truth {
  std::vector<MappedFrame> frames;
  std::vector<std::vector<Vec2>> landmarks;  // per frame, the interior landmarks' disk points
};

Vec2 on_disk(const MappedFrame& f, const Vec3& p) { return disk_point(f.map, PointToMesh(f.map.surface).closest(p)); }

// Frames of a synthetic face at `times`, each mapped and normalised by its own nose landmarks, with
// where its interior landmarks lie on its disk.
Truth synthetic_frames(Expression expression, uint64_t seed, const std::vector<double>& times, int vertices) {
  const SyntheticFace face(expression, seed);
  Truth t;
  for (double time : times) {
    const TriangleMesh mesh = face.truth_mesh(time, vertices);
    FrameLandmarks given;
    std::vector<Vec3> interior;
    for (const NamedPoint& p : face.landmarks()) {
      const Vec3 x = face.position(p.material, time);
      if (p.name == "nose_tip")
        given.centre = x;
      else if (p.name == "nose_bridge")
        given.up = x;
      else if (p.name.rfind("rim_", 0) == 0)
        given.rim_markers.push_back(x);
      else if (p.name != "between_eyes")
        interior.push_back(x);
    }
    t.frames.push_back(map_frame(mesh, "synth", given));
    std::vector<Vec2> points;
    for (const Vec3& x : interior) points.push_back(on_disk(t.frames.back(), x));
    t.landmarks.push_back(points);
  }
  return t;
}

struct Accuracy {
  double tracked = 0, untracked = 0;  // RMS disk distance to the truth: tracked, and left where the reference has it
  int kept = 0, tried = 0;
};

Accuracy measure(const Truth& t, size_t frame, const TrackingOptions& options) {
  const DiskFeatures reference = disk_features(t.frames[0].map, options.image_size);
  const DiskFeatures other = disk_features(t.frames[frame].map, options.image_size);
  const TrackedPoints tracked = track_points(reference, other, t.landmarks[0], {}, options);
  Accuracy a;
  a.tried = tracked.tried;
  a.kept = static_cast<int>(tracked.index.size());
  for (size_t k = 0; k < tracked.index.size(); ++k) {
    const auto l = static_cast<size_t>(tracked.index[k]);
    a.tracked += (tracked.frame[k] - t.landmarks[frame][l]).squaredNorm();
    a.untracked += (t.landmarks[0][l] - t.landmarks[frame][l]).squaredNorm();
  }
  a.tracked = std::sqrt(a.tracked / std::max(a.kept, 1));
  a.untracked = std::sqrt(a.untracked / std::max(a.kept, 1));
  return a;
}

// A talking face's landmarks (eyes, brows, lips, mouth corners) from the neutral frame onto frames
// with the mouth open: the tracked points land far nearer the truth than the normalised maps put
// them, and most are kept.
TEST(LandmarkTracking, FollowsASyntheticFacesLandmarks) {
  const Truth t = synthetic_frames(Expression::kTalk, 4, {0.0, 0.4, 0.9}, 6000);
  for (size_t i = 1; i < t.frames.size(); ++i) {
    const Accuracy a = measure(t, i, {});
    std::printf("frame %zu: %d of %d kept; RMS %.4f tracked, %.4f untracked (disk units)\n", i, a.kept, a.tried, a.tracked, a.untracked);
    EXPECT_GE(a.kept, a.tried * 2 / 3);
    EXPECT_LT(a.tracked, 0.7 * a.untracked);
    EXPECT_LT(a.tracked, 0.008);
  }
}

// A frame whose disk is the reference's turned by 60°: no window matches where the flow can reach,
// so the round-trip, neighbour and gain checks drop nearly every point; without them a fifth of
// the grid, all wrong, would be kept.
TEST(LandmarkTracking, DropsPointsItCannotFollow) {
  const Truth t = synthetic_frames(Expression::kTalk, 4, {0.0}, 6000);
  MappedFrame turned = t.frames[0];
  const double c = std::cos(1.047), s = std::sin(1.047);
  for (Vec2& w : turned.map.disk) w = Vec2(c * w.x() - s * w.y(), s * w.x() + c * w.y());
  TrackingOptions options;
  const DiskFeatures reference = disk_features(t.frames[0].map, options.image_size), other = disk_features(turned.map, options.image_size);
  const std::vector<Vec2> grid = tracking_grid(options);
  const TrackedPoints checked = track_points(reference, other, grid, {}, options);
  options.check_round_trip = false;
  const TrackedPoints unchecked = track_points(reference, other, grid, {}, options);
  std::printf("%zu of %d kept with the checks, %zu without\n", checked.index.size(), checked.tried, unchecked.index.size());
  EXPECT_LT(checked.index.size(), grid.size() / 20);
  EXPECT_GT(unchecked.index.size(), grid.size() / 6);
}

}  // namespace
}  // namespace facemorph
