// Distances between surfaces and nearest points on them: how the benchmarks measure geometric error
// (design §6) and where the encoder finds landmarks on a frame.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/meshkit/geometry/locator.hpp"

#include <limits>
#include <span>
#include <vector>

namespace facemorph {

// The diagonal of the points' axis-aligned bounding box: the scale relative errors are given in
// (0 for no points).
double bounding_box_diagonal(std::span<const Vec3> points);

// Barycentric coordinates of the point of triangle abc nearest to p (Ericson, Real-Time Collision
// Detection §5.1.5: by Voronoi regions of the vertices, edges and face). A collapsed triangle (its
// vertices on one line, or one point) is the longest of its edges, which covers the other two: the
// nearest point of that segment, with 0 at the vertex off it.
Vec3 closest_point_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// The 99th percentile of `values` by nearest rank: the ceil(0.99 n)-th smallest, the smallest value
// that at least 99% of them do not exceed (0 for none). Reorders `values`. What surface_distance's
// p99 and the frame patches' measure (patch_measure.hpp) take.
double nearest_rank_p99(std::vector<double>& values);

// Closest-point queries against one triangle mesh, through a uniform grid of buckets.
class PointToMesh {
 public:
  explicit PointToMesh(const TriangleMesh& mesh);  // the mesh must outlive this
  // Distance from p to the nearest point of the mesh (infinity for a mesh without faces).
  double distance(const Vec3& p) const;
  // The same where it is under `bound`; otherwise some value at least `bound` (the search stops
  // there: a caller that only needs to know "that far or farther" saves the far shells).
  double distance_below(const Vec3& p, double bound) const;
  // The nearest point of the mesh: its face and barycentric coordinates. Of equally near faces the
  // lowest index wins, as in a scan over all faces. Face -1 for a mesh without faces. `distance`:
  // where given, distance(p), from the same search.
  SurfacePoint closest(const Vec3& p, double* distance = nullptr) const;
  // closest(), the search started from face `hint` (its distance the first bound on the nearest, so
  // that the boxes past it are skipped from the first cell): the same face, coordinates and distance
  // to the bit, whatever the hint (-1: none). A neighbour's nearest face, or the same point's before
  // it moved a little, is a hint near the nearest.
  SurfacePoint closest_from(const Vec3& p, int hint, double* distance = nullptr) const;
  // closest() with its squared distance (`squared`: infinity where no face is left), over the faces
  // `skip_face` (one flag a face, where given) does not mark: a caller whose mesh changed in a few
  // faces searches the rest here and the changed ones in a locator of their own. The squared
  // distances of both searches compare as one search's would (ties: the lower face index). Faces
  // `bound` or farther away go unsearched, and unmeasured (distance_below measures the faces of the
  // cells it visits): where the nearest is nearer than `bound` it is found, ties included; otherwise
  // what comes back is at least `bound` away, or nothing (face -1, infinity).
  // `hint`: as closest_from's.
  SurfacePoint closest_squared(const Vec3& p, double& squared, const std::vector<char>* skip_face = nullptr,
                               double bound = std::numeric_limits<double>::infinity(), int hint = -1) const;

 private:
  // best: its squared distance; the search ends once nothing nearer than `bound` can be left, and
  // with `skip_past_bound` skips from the start the boxes farther than `bound`; `hint` (>= 0): a
  // face measured first.
  SurfacePoint nearest(const Vec3& p, double& best, double bound = std::numeric_limits<double>::infinity(),
                       const std::vector<char>* skip_face = nullptr, bool skip_past_bound = false, int hint = -1) const;

  // A face's axis-aligned box: a search skips a face (and a cell) whose box is farther from p than
  // the nearest face found so far, plus `slack_`, without measuring it.
  struct Box {
    Vec3 lo, hi;
  };

  const TriangleMesh& mesh_;
  Vec3 origin_;
  double cell_ = 1;
  int nx_ = 1, ny_ = 1, nz_ = 1;
  std::vector<int> start_, faces_;
  std::vector<Box> boxes_;  // one a face
  // Far above the rounding of a computed distance or cell edge (1e-9 of the coordinates' size), so
  // that no face as near as the nearest found, ties included, is skipped.
  double slack_ = 0;
};

struct SurfaceDistance {
  double rms = 0;  // over the vertices of both meshes, each to the other surface
  double max = 0;  // Hausdorff distance (at vertices)
  // 99th percentile of the same distances (nearest rank: the smallest distance that at least 99% of
  // them do not exceed): the worst region's error, which one stray vertex cannot set as it sets max.
  double p99 = 0;
  // The same percentile of each direction apart: the test mesh's vertices to the reference surface,
  // and the reference's to the test surface (one side's points can decide the union's).
  double p99_test_to_reference = 0;
  double p99_reference_to_test = 0;
  double diagonal = 0;  // bounding-box diagonal of the reference
};

// Symmetric point-to-surface distance between `reference` and `test` (each mesh's vertices to the
// other surface), with the reference's bounding-box diagonal for relative figures. On up to
// `threads` threads (0: one per hardware thread), the same figures to the bit on any number: a
// caller that measures one pair while the other cores wait passes them; one inside a parallel
// loop leaves it at 1.
SurfaceDistance surface_distance(const TriangleMesh& reference, const TriangleMesh& test, int threads = 1);

}  // namespace facemorph
