// A frame path (geodesic_path): the straight disk segment between two points pulled back onto the
// surface (surface_paths.cpp) and corrected toward a surface geodesic (path_correction.cpp),
// method-notes §6 steps 2-4; and the geodesic frame's options checked.
#include "codec/encoder/registration/surface_path.hpp"

#include "codec/encoder/registration/registration_internal.hpp"
#include "format/error.hpp"

#include <cmath>
#include <string>
#include <vector>

namespace facemorph {

void refuse_geodesic_frame_input(const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "geodesic frame: " + what); }

void check_frame_options(const GeodesicFrameOptions& o) {
  if (!(o.graph_boundary_spacing_degrees > 0 && o.graph_boundary_spacing_degrees <= 60))
    refuse_geodesic_frame_input("graph boundary spacing must be in (0, 60] degrees");
  if (!(o.partition_boundary_spacing_degrees > 0 && o.partition_boundary_spacing_degrees <= 30)) {
    refuse_geodesic_frame_input("partition boundary spacing must be in (0, 30] degrees");
  }
  if (!(o.sample_spacing >= 1e-3 && o.sample_spacing <= 1)) refuse_geodesic_frame_input("sample spacing must be in [0.001, 1] disk units");
  if (!(o.angle_tolerance >= 0 && std::isfinite(o.angle_tolerance))) refuse_geodesic_frame_input("angle tolerance must be finite and >= 0");
  if (!(o.length_tolerance >= 0 && std::isfinite(o.length_tolerance)))
    refuse_geodesic_frame_input("length tolerance must be finite and >= 0");
  if (o.max_sweeps < 0 || o.max_sweeps > 100000) refuse_geodesic_frame_input("max sweeps must be in [0, 100000]");
}

// ---- Frame curves ----

namespace {

FramePath curve_of(const SurfacePaths& paths, const std::vector<PathPoint>& points, const Vec2& from, const Vec2& to, bool clipped_from,
                   bool clipped_to) {
  FramePath curve;
  // Back to the disk (notes §6 step 4): an edge point at t is the disk edge's point at t, and between
  // two points sharing a face the map is affine, so the polyline is the curve.
  if (clipped_from) curve.disk.push_back(from);
  for (const PathPoint& p : points) {
    curve.disk.push_back(paths.disk(p));
    curve.surface.push_back(paths.position(p));
  }
  if (clipped_to) curve.disk.push_back(to);
  curve.disk.front() = from;  // the graph points exactly, not their reconstruction
  curve.disk.back() = to;
  return curve;
}

}  // namespace

TracedPath trace_path(const SurfacePaths& paths, const Vec2& from, const Vec2& to, const GeodesicFrameOptions& options) {
  bool clipped_from = false, clipped_to = false;
  const std::vector<PathPoint> straight = paths.pull_back(from, to, clipped_from, clipped_to);
  TracedPath traced;
  traced.straight = curve_of(paths, straight, from, to, clipped_from, clipped_to);
  traced.straight.lengths = {paths.length(straight)};
  traced.straight.angle_error = paths.angle_error(straight);
  if (!options.correct_paths) return traced;
  std::vector<PathPoint> points = straight;
  const Correction c = paths.correct(points, options);
  traced.corrected = curve_of(paths, points, from, to, clipped_from, clipped_to);
  traced.corrected.lengths = c.lengths;
  traced.corrected.sweeps = c.sweeps;
  traced.corrected.angle_error = c.angle_error;
  traced.corrected.vertex_points = c.vertex_points;
  traced.corrected.converged = c.converged;
  traced.correction_valid = paths.connected(points);
  return traced;
}

FramePath geodesic_path(const DiskMap& map, const Vec2& from, const Vec2& to, const GeodesicFrameOptions& options) {
  check_frame_options(options);
  for (const Vec2* p : {&from, &to}) {
    if (!p->allFinite() || p->norm() > 1 + 1e-9) {
      throw Error(ErrorCode::kInvalidArgument, "geodesic frame: path end (" + std::to_string(p->x()) + ", " + std::to_string(p->y()) +
                                                   ") is outside the unit disk or not finite");
    }
  }
  if (from == to) throw Error(ErrorCode::kInvalidArgument, "geodesic frame: the path's two ends coincide");
  const SurfacePaths paths(map);
  TracedPath traced = trace_path(paths, from, to, options);
  if (!options.correct_paths) return traced.straight;
  if (!traced.correction_valid) throw Error(ErrorCode::kNumerical, "geodesic frame: path correction broke the path");
  return traced.corrected;
}

}  // namespace facemorph
