// Correspondence between frames by tracking (spec/method.md §7.14): every normalised frame's disk
// drawn as images of its geometry (mean curvature, log conformal factor), and a grid of points of
// the reference's disk followed onto each frame's disk by pyramidal Lucas-Kanade optical flow
// (OpenCV), each point kept only where tracking it back lands where it started. What the encoder
// feeds the registration when a capture gives no interior landmarks.
// Disk coordinates throughout: points of the closed unit disk, dimensionless.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <cstddef>
#include <functional>
#include <vector>

namespace facemorph {

struct TrackingOptions {
  int image_size = 512;      // texels per side of the disk images ([-1, 1]²)
  double spacing = 0.05;     // the reference's points: a square grid this far apart (disk units)...
  double max_radius = 0.85;  // ...within this radius (the rim has its own markers)
  int window = 21;
  double blur = 1.0;  // Gaussian blur of the images before the flow (texels; 0: none)
  // The log conformal factor's contrast against the curvature's (0: the flow sees curvature alone).
  double log_factor_weight = 1.0;
  int pyramid_levels = 3;  // above the full image
  // A point is kept when, tracked back from the frame to the reference, it lands within this of
  // where it started (disk units; 0.01 is 2.6 texels of a 512² image).
  double max_round_trip = 0.01;
  // And when its displacement agrees with the median of its kept neighbours' (within 2.5 spacings)
  // to this (disk units): one point dragged along by a feature that is not its own is dropped.
  double max_neighbour_disagreement = 0.03;
  // And when the frame's window at the tracked point matches the reference's window at most this
  // share of the squared difference the frame shows at the point itself (where the normalised maps
  // alone put it): a point the flow moves without explaining the images better is no evidence.
  double min_gain = 0.7;
  // A point is tracked only where the reference's window holds at least this many of its surface's
  // vertices: over fewer the images show the triangles' interpolation, not the face (a 468-vertex
  // MediaPipe mesh has ~2 per window of a 512² image; scans and fmsynth's faces 20-40).
  int min_window_vertices = 8;
  bool check_round_trip = true;  // false: every point Lucas-Kanade converges on is kept (for tests)
  // A frame registered through tracked points takes a smoothing thin plate (RegistrationOptions::
  // smoothing, in units of the points' mean squared nearest-neighbour spacing) rather than one
  // through every point: each point is off by a tracking error of its own, and a spline that bends
  // through all of them carries those errors into the frame's samples on G (spec/method.md §7.14).
  double registration_smoothing = 10;
};

// A frame's geometry drawn on its disk: texel (x, y) of the size × size images shows the disk point
// w = (2 (x + 0.5) / size - 1, 1 - 2 (y + 0.5) / size), as the disk textures are addressed. Two
// channels, float: the mean curvature H times the frame's bounding-box diagonal, and the log of the
// conformal factor λ over that diagonal (both dimensionless, so frames of any size or unit compare).
// Texels outside the disk repeat the rim's values on their ray.
// Texels of the filled holes (open eyes and mouth) are flagged: their fill is no surface the
// camera saw, and its shape changes as they open, so the flow sees them as one dark level whose
// edge is the lips' and lids' own.
struct DiskFeatures {
  int size = 0;
  std::vector<float> curvature, log_factor;  // size² each, row 0 at the top
  std::vector<uint8_t> hole;                 // 1 for a texel of a hole's fill
  std::vector<uint8_t> vertices;             // the surface's vertices on each texel (at most 255)
};

// Draws `map` (a mapped, normalised frame); `holes` are the fills of its prepared frame
// (PreparedFrame::report.holes, in the vertex numbering map.source_vertex refers to). Throws
// kInvalidArgument for size < 16 or a map whose sizes disagree.
DiskFeatures disk_features(const DiskMap& map, int size, const std::vector<FilledHole>& holes = {});

// Where the reference's points lie on one frame's disk.
struct TrackedPoints {
  std::vector<Vec2> reference, frame;  // the points kept, paired
  std::vector<int> index;              // per point kept: its index among the points tracked
  std::vector<double> round_trip;      // per point kept: the forward-backward error (disk units)
  int tried = 0;                       // points tracked
  int unresolved = 0;                  // points not tracked: too few vertices in their window
  int lost = 0;                        // of them, dropped: Lucas-Kanade failed, left the disk, or round trip too far
  int outliers = 0;                    // of them, dropped by the neighbour check
  int no_gain = 0;                     // of them, dropped as matching no better than the point itself
  // A confidence weight per kept point in (0, 1]: 1 / (1 + (round trip / (max_round_trip / 2))²).
  std::vector<double> confidence() const;
};

// The reference's grid of points (options.spacing, options.max_radius), rows from the top.
std::vector<Vec2> tracking_grid(const TrackingOptions& options = {});

// Tracks `points` (on the reference's disk) onto the frame's disk, starting each from `start`
// (same size as points; empty: from the point itself, the disks being normalised alike) and from the
// point itself, and keeping the better round trip. Throws kInvalidArgument for features of different
// sizes or a bad start.
TrackedPoints track_points(const DiskFeatures& reference, const DiskFeatures& frame, const std::vector<Vec2>& points,
                           const std::vector<Vec2>& start = {}, const TrackingOptions& options = {});

// Every frame's tracked points, frame `reference`'s own being the identity. Frames are tracked in
// time order away from the reference, each directly against the reference (no drift) but starting
// from where the frame before it (nearer the reference) put each point, so a motion that grows over
// many frames is followed. `features(i)` draws frame i (all the same size); frames are drawn in
// chunks on `threads` threads (0: one per core) and dropped once tracked, so memory does not grow
// with the capture. Throws what `features` and track_points throw.
std::vector<TrackedPoints> track_sequence(size_t count, size_t reference, const std::function<DiskFeatures(size_t)>& features,
                                          const TrackingOptions& options = {}, int threads = 0);

// ---- In the encoder ----

// Whether frame `frame` of `capture` needs tracked points: it shares fewer than 3 landmarks with
// frame `reference` other than the pose's (nose_tip, nose_bridge, between_eyes) and the rim markers,
// the ones the encoder finds itself. Given interior landmarks, where there are enough, are used as
// they are.
bool needs_tracked_points(const Capture& capture, size_t reference, size_t frame);
// The same for two frames' points, one per name of `names` (NaN where a frame lacks it).
bool needs_tracked_points(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const std::vector<Vec3>& frame);

// Appends `tracked` to `landmarks` as interior landmarks weighted by their confidence (the given
// ones keep weight 1).
void add_tracked_points(DiskLandmarks& landmarks, const TrackedPoints& tracked);

}  // namespace facemorph
