// Paths on a disk map's surface: a straight disk segment pulled back onto the surface, and its
// correction toward a geodesic (Martínez, Velho, Carvalho 2005; method-notes §6 steps 2-4).
#pragma once

#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

namespace facemorph {

// A point of a path: at a mesh vertex, inside a mesh edge, or (the two ends only) inside a face.
struct PathPoint {
  enum Kind : uint8_t { kVertex, kEdge, kFace };
  Kind kind = kVertex;
  int a = -1, b = -1;  // kVertex: vertex a; kEdge: the point (1 - t) x_a + t x_b; kFace: face a
  double t = 0;
  Vec3 bary = Vec3::Zero();  // kFace: barycentric coordinates in face a
};

// What a correction did (FramePath's fields of the same names).
struct Correction {
  std::vector<double> lengths;
  int sweeps = 0;
  double angle_error = 0;
  int vertex_points = 0;
  bool converged = false;
};

// The surface's connectivity as the walk and the correction use it: the face on each side of every
// edge and the fan of faces round every vertex, counter-clockwise. Read-only once built, so one
// instance serves parallel paths. `map` must outlive it.
class SurfacePaths {
 public:
  explicit SurfacePaths(const DiskMap& map);

  // The straight disk segment from `from` to `to` (points of the closed disk) pulled back: a crossing
  // of each disk edge it passes, at the edge's own parameter, between its ends. An end outside the
  // triangulation (between the rim and the circle) is replaced by the point where the segment enters
  // it; `clipped_from` / `clipped_to` say so. Throws kNumerical when the segment misses the
  // triangulation or the walk does not reach its end (a folded map).
  std::vector<PathPoint> pull_back(const Vec2& from, const Vec2& to, bool& clipped_from, bool& clipped_to) const;

  // Sweeps of path correction until the options' tolerances are met; the ends stay.
  Correction correct(std::vector<PathPoint>& path, const GeodesicFrameOptions& options) const;

  Vec3 position(const PathPoint& p) const;
  Vec2 disk(const PathPoint& p) const;
  double length(std::span<const PathPoint> path) const;       // 3D, capture units
  double angle_error(std::span<const PathPoint> path) const;  // the largest error of its interior points (radians)
  // Whether consecutive points all share a face: the invariant every step keeps.
  bool connected(std::span<const PathPoint> path) const;

 private:
  // The ordered faces round vertex v.
  std::span<const int> fan(int v) const;
  int face_of(int a, int b) const;           // the face holding the directed edge a -> b, or -1
  int across(int a, int b, int face) const;  // the other face of edge {a, b}, or -1
  bool touches(const PathPoint& p, int face) const;
  int shared_face(const PathPoint& p, const PathPoint& q) const;  // a face both touch, or -1
  bool same(const PathPoint& p, const PathPoint& q) const;
  PathPoint at(const SurfacePoint& s) const;  // tiny barycentrics snapped to an edge or a vertex

  struct Unfolded;
  struct Fan;
  Fan fan_view(int v) const;
  double direction(const Fan& fan, const PathPoint& p) const;
  bool strip_faces(const PathPoint& prev, std::span<const PathPoint> run, const PathPoint& next, std::vector<int>& g) const;
  bool pull_string(const PathPoint& prev, std::span<const PathPoint> run, const PathPoint& next, std::vector<PathPoint>& out) const;
  bool local_step(const PathPoint& prev, PathPoint& cur, const PathPoint& next) const;
  bool unfold_pair(const PathPoint& prev, const PathPoint& cur, const PathPoint& next, Unfolded& out) const;
  void vertex_step(const PathPoint& prev, const PathPoint& cur, const PathPoint& next, std::vector<PathPoint>& out) const;
  double min_side(const PathPoint& prev, const PathPoint& cur, const PathPoint& next) const;
  double point_error(const PathPoint& prev, const PathPoint& cur, const PathPoint& next) const;
  void sweep(std::vector<PathPoint>& path, bool strips) const;
  void cleanup(std::vector<PathPoint>& path) const;

  const DiskMap& map_;
  TriangleLocator locator_;
  std::unordered_map<uint64_t, int> face_of_;  // directed edge key -> face
  std::vector<int> fan_start_, fan_faces_;     // CSR over vertices, counter-clockwise
  std::vector<uint8_t> open_fan_;              // boundary vertex: the fan does not close
};

// Throws kInvalidArgument naming the first option out of range.
void check_frame_options(const GeodesicFrameOptions& options);

// A frame curve both ways: the pulled-back straight segment, and (options.correct_paths) its
// correction, with whether the corrected path still has consecutive points sharing faces.
struct TracedPath {
  FramePath straight, corrected;
  bool correction_valid = false;
};
// Throws what pull_back throws.
TracedPath trace_path(const SurfacePaths& paths, const Vec2& from, const Vec2& to, const GeodesicFrameOptions& options);

// ---- What the pull-back and the correction share: points at a vertex or on an edge ----
namespace path_points {

// A crossing this close to an edge's end (in the edge's own parameter) is taken as the vertex: the
// two-triangle unfolding of a point that near a vertex says nothing reliable.
inline constexpr double kSnap = 1e-12;

inline int corner_of(const Face& f, int v) {
  for (int k = 0; k < 3; ++k) {
    if (f[k] == v) return k;
  }
  return -1;
}

inline PathPoint vertex_point(int v) { return {PathPoint::kVertex, v, -1, 0, Vec3::Zero()}; }
inline PathPoint edge_point(int a, int b, double t) { return {PathPoint::kEdge, a, b, t, Vec3::Zero()}; }

}  // namespace path_points

}  // namespace facemorph
