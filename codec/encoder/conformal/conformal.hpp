// The Riemann conformal map of a captured frame onto the unit disk (paper §2, method-notes §2-3,
// spec/method.md §3): double covering, spherical conformal map by the quasi-implicit Euler method
// (QIEM), stereographic projection of one hemisphere; a linear harmonic map as the fallback.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/encoder/conformal/moebius.hpp"
#include "codec/meshkit/geometry/locator.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace facemorph {

enum class ConformalMethod {
  kQiem,    // conformal: double cover + QIEM (default)
  kLinear,  // harmonic map with the boundary on the circle at arc length: bijective, not conformal
  kTutte,   // Tutte's map (positive weights blind to the geometry): the last resort, far from conformal
};
const char* conformal_method_name(ConformalMethod method);
ConformalMethod parse_conformal_method(const std::string& name);  // "qiem" | "linear" | "tutte"

struct ConformalOptions {
  ConformalMethod method = ConformalMethod::kQiem;
  // If QIEM fails, use the linear map; if the linear map fails too, Tutte's map (and say so).
  bool fallback = true;
  int max_iterations = 100;
  // Stop when the relative harmonic-energy change is below this. Measured: angle statistics do not
  // change (to 0.001°) between 1e-7 and 1e-9 on synthetic, Medusa and ICT frames.
  double energy_tolerance = 1e-7;
};

struct ConformalReport {
  ConformalMethod method = ConformalMethod::kQiem;  // the method that produced the map
  std::string fallback_reason;                      // non-empty when the method asked for failed and `method` took over
  int iterations = 0;                               // QIEM steps taken
  int factorizations = 0;                           // numeric factorisations of its two symmetric systems together
  double energy = 0;                                // final harmonic energy of the spherical map (4π when conformal)
  double energy_excess = 0;                         // energy - area of the image (≥ 0; 0 when conformal)
  int intrinsic_flips = 0;                          // edge flips to reach the intrinsic Delaunay triangulation
  int split_chords = 0, split_ears = 0, split_obtuse_boundary = 0, split_caps = 0;
  int caps_left = 0, obtuse_boundary_left = 0;  // what preconditioning's bounded rounds left

  int flipped_triangles = 0;   // faces the method left with non-positive disk area...
  int untangled_vertices = 0;  // ...and the vertices re-placed (mean-value weights) to unflip them
  double seconds_prepare = 0;  // preconditioning, double cover, intrinsic Delaunay
  double seconds_initial = 0;  // the linear disk map (QIEM's start)
  double seconds_flow = 0;     // QIEM iterations
  double seconds_finish = 0;   // projection, orientation, checks
};

// A surface with one boundary loop and its conformal image in the unit disk.
struct DiskMap {
  TriangleMesh surface;            // the frame as mapped (a few edges may have been split)
  std::vector<Vec2> disk;          // per surface vertex; the rim exactly on |w| = 1
  std::vector<int> rim;            // boundary loop, surface on its left (counter-clockwise on the disk)
  std::vector<int> source_vertex;  // vertex of the input mesh, -1 for vertices added by splits
  DiskMoebius normalization;       // the Möbius map applied by normalize()
  ConformalReport report;
};

// Maps `surface` (a disk: one boundary loop, Euler characteristic 1; see prepare_frame) onto the
// unit disk. Throws kNotADisk for other topology; with options.fallback, kNumerical only when even
// Tutte's map fails (its solver), else what the method asked for throws. The image is orientation-preserving; its rotation and Möbius
// position are arbitrary until normalize().
DiskMap conformal_disk_map(const TriangleMesh& surface, const ConformalOptions& options = {});

// Applies the disk Möbius map sending the surface point nearest `centre` to 0 and the one nearest
// `direction` onto the positive imaginary axis (the reference pose; spec/method.md §3.5). Triangles
// rounding may turn over in crowded regions are untangled, as in conformal_disk_map.
void normalize(DiskMap& map, const Vec3& centre, const Vec3& direction);

// The disk point of a surface point (barycentric interpolation of its face's disk corners).
Vec2 disk_point(const DiskMap& map, const SurfacePoint& point);

// Conformal factor per vertex: λ_v² = Σ A_surface(f) / Σ A_disk(f) over the faces around v.
Eigen::VectorXd conformal_factor(const DiskMap& map);

// Quality of a map (spec/method.md §3.6).
struct Distortion {
  double mean_degrees = 0;  // mean |disk angle - surface angle| over triangle corners
  double p95_degrees = 0;
  double max_degrees = 0;
  double mu_mean = 0;  // quasi-conformal dilatation |μ| per triangle (area-weighted mean)
  double mu_max = 0;
  int flipped = 0;  // triangles with non-positive disk area
  // The paper's Figure 3: angles between the pulled-back checkerboard lines on the surface,
  // area-weighted, in 1° bins from 45° to 135° (outside values land in the end bins).
  std::vector<double> checkerboard_histogram;
  double checkerboard_within_1_degree = 0;  // area fraction with |angle - 90°| <= 1°
};
Distortion measure_distortion(const DiskMap& map);

// Disk point -> surface point, through the disk triangulation with a bucket grid. Points in the
// thin gaps between a boundary chord and the circle (and exactly on the circle) map onto the
// boundary edge at the same angle, so the boundary is exact. Needs the map to outlive it.
class InverseDiskMap {
 public:
  explicit InverseDiskMap(const DiskMap& map);
  // Any |w| <= 1 (+1e-9) succeeds; farther points are nullopt.
  std::optional<SurfacePoint> locate(const Vec2& w) const;
  Vec3 position(const SurfacePoint& p) const;
  Vec2 texture_uv(const SurfacePoint& p) const;  // requires surface UVs
  Vec3 colour(const SurfacePoint& p) const;      // linear RGB in [0, 1]; requires surface colours

 private:
  const DiskMap& map_;
  TriangleLocator locator_;
  std::vector<double> rim_angle_;   // sorted angles of the rim vertices, in [0, 2π)
  std::vector<int> rim_edge_face_;  // face of the rim edge starting at each sorted rim vertex
  std::vector<int> rim_order_;      // rim vertex index in angle order
};

}  // namespace facemorph
