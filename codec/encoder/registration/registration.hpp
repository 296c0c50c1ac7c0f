// Registration of a frame's disk to the reference frame's disk through landmarks (paper §3-5,
// method-notes §4-6, spec/method.md): the optimal Möbius transform (OMT), then a global matching
// function (GMF) composed after it, f = (id + d) ∘ m, kept a bijection of the closed unit disk;
// and the paper's third registration, the piecewise-affine map Φ on the partition mesh that a
// geodesic frame of the reference cuts the disk into.
// Disk coordinates throughout: points of the closed unit disk |w| <= 1, dimensionless.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/conformal/moebius.hpp"
#include "codec/meshkit/geometry/locator.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// The same landmarks on two disks: reference[j] = p_j on the reference frame's disk, frame[j] = q_j
// on the frame's disk. Boundary markers (rim_0..rim_7) are ordinary landmarks flagged in on_rim;
// they must lie on the circle (within 1e-3: an interpolated rim point sits on a chord) and are
// projected onto it exactly, since only there is the boundary correspondence known.
struct DiskLandmarks {
  std::vector<Vec2> reference, frame;
  std::vector<double> weights;  // ω_j >= 0 (e.g. λ_b(q)/λ_a(p), notes §4); empty: all 1
  std::vector<uint8_t> on_rim;  // 1 for a boundary marker; empty: none
};

enum class RegistrationMethod {
  kMoebius,  // the OMT alone: conformal, can only match the landmarks approximately
  kGmf,      // OMT, then the GMF (default)
  kFrame,    // the GMF interpolated piecewise-affinely on a geodesic frame's partition mesh (notes §6)
};
const char* registration_method_name(RegistrationMethod method);        // "moebius" | "gmf" | "frame"
RegistrationMethod parse_registration_method(const std::string& name);  // throws kInvalidArgument

enum class GmfForm {
  kThinPlate,  // standard thin-plate spline with an affine part on the landmarks (notes §5, default)
  kPaperGrid,  // the paper's n×n grid of r² log r centres on [-1,1]², fitted as a displacement
};
const char* gmf_form_name(GmfForm form);          // "thin-plate" | "paper-grid"
GmfForm parse_gmf_form(const std::string& name);  // throws kInvalidArgument

// ---- The optimal Möbius transform (notes §4) ----

enum class MoebiusStart {
  kBest,       // both starts below, keep the lower final energy (default)
  kRotation,   // a = 0, θ = arg Σ ω q p̄
  kAlgebraic,  // the linearised fit of (αz + β)/(β̄z + ᾱ) by its smallest right singular vector
};

struct MoebiusFitOptions {
  MoebiusStart start = MoebiusStart::kBest;
  int max_iterations = 100;  // Levenberg-Marquardt steps per start
};

struct MoebiusFit {
  DiskMoebius map;                               // reference disk -> frame disk
  double energy = 0;                             // E_D = Σ ω |m(p) - q|², disk units squared
  int iterations = 0;                            // accepted and rejected LM steps of the start that won
  MoebiusStart start = MoebiusStart::kRotation;  // the start that won
};

// Levenberg-Marquardt on (Re a, Im a, θ) minimising E_D, steps with |a| >= 1 - 1e-9 rejected.
// Throws kInvalidArgument for bad landmarks (see register_disks) or max_iterations < 0.
MoebiusFit fit_moebius(const DiskLandmarks& landmarks, const MoebiusFitOptions& options = {});

// ---- The GMF's displacement field ----

// d(x) = offset + linear x + Σ_i weights(i) G(|x - centres[i]|), G(r) = r² log r (G(0) = 0): both
// GMF forms evaluate this way (the paper's grid form has no affine part).
struct ThinPlateDisplacement {
  std::vector<Vec2> centres;
  Eigen::Matrix<double, Eigen::Dynamic, 2> weights;  // one row (x, y) per centre
  Vec2 offset = Vec2::Zero();
  Eigen::Matrix2d linear = Eigen::Matrix2d::Zero();

  Vec2 operator()(const Vec2& x) const;
  // x_p += d(x_p) for every point p = (x[p], y[p]): the same bits as operator(), many points at once.
  void displace(std::span<double> x, std::span<double> y) const;
  // displace(), and jacobians[p] carried through the step by the chain rule: J ← (I + ∇d(x_p)) J.
  void displace_with_jacobians(std::span<double> x, std::span<double> y, std::span<Eigen::Matrix2d> jacobians) const;
  Eigen::Matrix2d gradient(const Vec2& x) const;                            // ∂d_k/∂x_l in row k, column l
  Vec2 value_and_gradient(const Vec2& x, Eigen::Matrix2d& gradient) const;  // both in one pass
};

// The standard thin-plate spline through centres[i] -> displacements[i], with the side conditions
// Σ w = 0, Σ w y = 0: (K + diag(smoothing)) w + P a = d, Pᵀ w = 0. `smoothing[i]` >= 0 is the
// absolute λ of centre i (empty: 0, exact interpolation). Throws kInvalidArgument for mismatched
// sizes or fewer than 3 centres, kNumerical when the system is singular (e.g. collinear or
// coincident centres without smoothing).
ThinPlateDisplacement fit_thin_plate(const std::vector<Vec2>& centres, const std::vector<Vec2>& displacements,
                                     const std::vector<double>& smoothing = {});

// The paper's form: centres on the n×n grid of [-1,1]², least squares of the rows
// sqrt(weights[i]) (d(points[i]) - displacements[i]) by column-pivoted QR when n² <= rows and
// `epsilon_scale` is 0, by Tikhonov (εI + SᵀS) α = Sᵀ d with ε = epsilon_scale · tr(SᵀS)/n²
// otherwise (epsilon_scale 0 with n² > rows uses 1e-6). Column weights λ_b/λ_a are 1 (notes §5,
// point 2: they change nothing under QR). Throws kInvalidArgument for n < 2 or bad sizes.
ThinPlateDisplacement fit_paper_grid(const std::vector<Vec2>& points, const std::vector<Vec2>& displacements,
                                     const std::vector<double>& weights, int n, double epsilon_scale);

// ---- Registration ----

enum class RegistrationFallback {
  kNone,               // the GMF as asked (or method kMoebius)
  kMoreSmoothing,      // the GMF folded (or nearly); a smoother one (smoothing × 10 per try) does not
  kSubsteps,           // smoothing did not help; k composed sub-steps, each fitted to an equal share
                       // (1/(steps left)) of the displacement that remains, at the asked smoothing
  kMoebiusOnly,        // nothing did: the OMT alone
  kGmfInsteadOfFrame,  // method kFrame: Φ folded (an image triangle not positive, or the circle's
                       // images out of order), so the GMF f̄ itself is used
};
const char* registration_fallback_name(RegistrationFallback fallback);  // "none" | "more-smoothing" | ...

struct RegistrationOptions {
  RegistrationMethod method = RegistrationMethod::kGmf;
  GmfForm form = GmfForm::kThinPlate;
  MoebiusFitOptions moebius = {};
  // Thin plate: λ_tps in units of the mean squared nearest-neighbour landmark spacing (0
  // interpolates). Paper grid: ε in units of tr(SᵀS)/n² (0: QR where n² <= rows, else 1e-6).
  double smoothing = 0;
  int paper_grid_n = 8;
  double boundary_spacing_degrees = 5;  // boundary samples on the circle; 0: none
  int fold_grid = 129;                  // fold check on fold_grid² points of [-1,1]², those in the disk
  // A GMF whose area ratio det Df / |m'|² falls to this anywhere on the check's points counts as
  // folding: a fold thinner than the grid shows there as a near-zero ratio (measured: one of 120
  // jittered faces folded on a 513² grid with a minimum ratio of 1e-4 on the refined 129² one).
  double min_area_ratio = 0.02;
  int smoothing_tries = 4;     // fallback 1: smoothing × 10, × 100, ...
  int max_substeps = 8;        // fallback 2: k = 2, 4, ... up to this
  bool allow_fallback = true;  // false: keep a folded GMF (check.ok() says so)
};

// Whether a registration is a bijection of the disk, as far as a grid can tell. register_disks keeps
// a GMF when ok() and min_area_ratio > RegistrationOptions::min_area_ratio. For Φ (method kFrame)
// the check is exact rather than sampled: the "grid" is the partition's triangles (det Df is each
// triangle's area ratio, a fold one not above 1e-12 × its source area, worst_point its centroid)
// and the circle's points are the partition's boundary vertices.
struct BijectionCheck {
  int grid_points = 0;                   // points with |w| <= 1 where det Df was evaluated, refined ones included
  int refined_points = 0;                // of those, the finer looks near centres and small det Df
  int folded_points = 0;                 // of those, det Df <= 0 (or not finite)
  double min_jacobian = 0;               // min det Df over the grid (disk area ratio)
  double min_area_ratio = 0;             // min det Df / |m'|²: the GMF's own area ratio (1 for m alone)
  Vec2 worst_point = Vec2::Zero();       // where that minimum is (reference disk)
  bool stopped = false;                  // an internal check stopped at the first failing point
  int boundary_samples = 0;              // circle points whose images were ordered
  int boundary_order_breaks = 0;         // consecutive images not strictly counter-clockwise, or winding != 1
  double max_boundary_radius_error = 0;  // max ||image| - 1| of circle points before the projection
  int clamped_points = 0;                // grid points whose image left the disk and was clamped
  bool ok() const { return folded_points == 0 && boundary_order_breaks == 0; }
};

struct GeodesicFrame;
struct PiecewiseAffineMap;  // Φ's data (codec/registration/partition_map.hpp): shared, immutable

// The map f: reference disk -> frame disk, f = (id + d_k) ∘ ... ∘ (id + d_1) ∘ m; for method kFrame
// (unless it fell back) Φ, the piecewise-affine interpolant of that composition f̄ on a partition
// mesh. Copies are cheap: Φ's tables are shared.
struct DiskRegistration {
  RegistrationMethod method = RegistrationMethod::kGmf;
  GmfForm form = GmfForm::kThinPlate;
  DiskMoebius moebius;                       // m, the OMT
  std::vector<ThinPlateDisplacement> steps;  // the GMF: one field, several sub-steps, or none
  double energy_moebius = 0;                 // E_D of m alone (disk units²)
  double energy = 0;                         // E_D of f
  int moebius_iterations = 0;
  MoebiusStart moebius_start = MoebiusStart::kRotation;
  RegistrationFallback fallback = RegistrationFallback::kNone;
  std::string fallback_reason;                              // why, for the encoder's list of frames; empty if none
  double smoothing = 0;                                     // the smoothing (options' units) of the kept GMF
  int boundary_samples = 0;                                 // boundary centres / rows added to the GMF
  BijectionCheck check;                                     // of the kept map (empty for method kMoebius)
  std::shared_ptr<const PiecewiseAffineMap> partition_map;  // Φ; null unless Φ is the map

  // f(w) for |w| <= 1 (1e-9 of slack). Points on the circle (|w| >= 1 - 1e-12) map onto the circle,
  // radially projected; an interior point whose image leaves the disk is clamped to radius
  // 1 - 1e-12 and, with `clamped`, counted. Throws kInvalidArgument for |w| > 1 + 1e-9 or NaN.
  Vec2 operator()(const Vec2& w) const { return map(w, nullptr); }
  Vec2 map(const Vec2& w, int* clamped) const;
  // map() of every point, in place: the same bits, the GMF's kernels vectorised over the points.
  // Throws before changing any point if one is outside the disk.
  void map_points(std::span<Vec2> points, int* clamped) const;
  // Df(w) of the smooth map (before the projection and the clamp): what λ's area correction uses,
  // λ̃² = λ_b²(f(w)) |det Df(w)| (notes §6). Any finite w. For Φ: the constant Jacobian of w's
  // partition triangle, or between the partition's boundary polygon and the circle the derivative of
  // the radial gap map; the notes' λ̃ wants the smooth f̄ there instead, smooth_base().
  Eigen::Matrix2d jacobian(const Vec2& w) const;
  // The image before the projection and the clamp (any finite w); with `jacobian`, also Df(w),
  // from the same pass through the composition.
  Vec2 smooth(const Vec2& w, Eigen::Matrix2d* jacobian = nullptr) const;
  // The composition (id + d_k) ∘ ... ∘ m itself, whatever the method: for Φ the f̄ it interpolates;
  // otherwise the same as smooth(). Any finite w.
  Vec2 smooth_base(const Vec2& w, Eigen::Matrix2d* jacobian = nullptr) const;
  // smooth() of every point of `w` into `images`, and with `jacobians` (empty: none) Df: the same
  // bits, the GMF's kernels vectorised over the points (ThinPlateDisplacement::displace).
  void smooth_points(std::span<const Vec2> w, std::span<Vec2> images, std::span<Eigen::Matrix2d> jacobians) const;
};

// Registers the frame's disk to the reference disk: f with f(p_j) ≈ q_j (method-notes §4-5). The
// GMF interpolates (smoothing 0) the landmarks after m and boundary samples whose targets follow
// the rim markers' correspondence angle-linearly (the Möbius map alone without markers); when the
// check finds a fold it falls back (RegistrationFallback) and says why.
// Method kFrame needs `frame`, the reference's geodesic frame (make_geodesic_frame, built once per
// capture): f̄ is the GMF as above (its fallbacks included) and the result Φ takes every partition
// triangle V to the triangle f̄(V) (paper §5: the frame's partition on the frame's disk is f̄ of the
// reference's); it falls back to f̄ itself (kGmfInsteadOfFrame) when an image triangle is not
// positive or the circle's images are out of order. Φ matches a landmark exactly as f̄ does when its
// reference point is a vertex of the frame (the landmarks the frame was made with); landmarks a
// frame lacks simply leave f̄ unconstrained there. E_D is Φ's.
// Throws kInvalidArgument for mismatched sizes, fewer than 3 landmarks, points outside the closed
// disk or not finite, negative or non-finite weights or all zero, coincident reference landmarks, rim
// markers off the circle or in a different cyclic order on the two disks, bad options, method kFrame
// without a frame.
DiskRegistration register_disks(const DiskLandmarks& landmarks, const RegistrationOptions& options = {},
                                const GeodesicFrame* frame = nullptr);

// Checks `f` on the grid_size² points of [-1,1]² inside the disk (det Df > 0), again at a quarter
// of the spacing around the GMF's centres and wherever the GMF shrinks areas below 1/4, and on
// 4 (grid_size - 1) circle points (images in strictly increasing cyclic angle, winding once).
// A grid can still miss a fold thinner than its finest spacing. Throws kInvalidArgument for
// grid_size outside [3, 4097].
BijectionCheck check_bijection(const DiskRegistration& f, int grid_size);

// E_D = Σ ω |f(p) - q|² of any map of the disk (disk units²). Throws as register_disks.
double matching_energy(const DiskRegistration& f, const DiskLandmarks& landmarks);

// ---- The geodesic frame and the partition mesh (paper §4-5, method-notes §6) ----

struct GeodesicFrameOptions {
  // The landmark graph: the Delaunay triangulation of the landmarks and of samples of the circle
  // every this many degrees (besides the markers), so that the frame reaches the circle.
  double graph_boundary_spacing_degrees = 10;
  // The partition mesh: circle samples every this many degrees, and samples along every frame curve
  // about `sample_spacing` apart (disk units, by arc length on the disk).
  double partition_boundary_spacing_degrees = 2;
  double sample_spacing = 0.02;
  // Path correction (Martínez, Velho, Carvalho 2005; notes §6 step 3) stops when the largest angle
  // error is below angle_tolerance (radians), when a sweep shortens the path by less than
  // length_tolerance (relative), or after max_sweeps sweeps.
  double angle_tolerance = 1e-6;
  double length_tolerance = 1e-10;
  int max_sweeps = 50;
  // The edge step on a whole run of consecutive edge points at once: the strip of faces it crosses
  // unfolded, the run replaced by the shortest path inside the strip (the funnel algorithm; for one
  // point exactly the notes' two-triangle step), and the strip vertices that path bends round given
  // the vertex step at once. Same steps, same fixed points, same stopping rule; 1-3 sweeps where the
  // point-by-point relaxation (false: the notes' steps one point at a time) needs O(n²) for a path
  // of n points (measured: none of 113 synthetic-face paths converged in 50 sweeps).
  bool unfold_strips = true;
  bool correct_paths = true;  // false: the straight disk segments pulled back, uncorrected
};

// One curve of the frame: the surface geodesic between two graph points, on the reference disk.
struct FramePath {
  int from = -1, to = -1;  // graph points (GeodesicFrame::graph_points), from < to; -1 for geodesic_path
  std::vector<Vec2> disk;  // the curve on the reference disk, from graph point `from` to `to`
  // The path on the reference surface (capture units): points on mesh edges and vertices, the ends
  // where the disk segment enters the triangulation (a circle point's segment first crosses the gap
  // between the circle and the mesh's rim chord, a straight piece of `disk`).
  std::vector<Vec3> surface;
  std::vector<double> lengths;  // 3D length of the pulled-back straight segment, then after each sweep
  int sweeps = 0;
  double angle_error = 0;  // largest final angle error (radians): |π - angle| at edge points,
                           // max(0, π - min(θ_l, θ_r)) at vertex points
  int vertex_points = 0;   // path points at mesh vertices (saddles, the boundary: legitimate corners)
  bool converged = false;  // angle_error < angle_tolerance
  bool straight = false;   // the pulled-back straight segment is used instead (see `reason`)
  std::string reason;      // why the correction was not used; empty otherwise
};

// The partition mesh of the reference disk (paper §5, φ_a(M_a)): the landmarks, samples along the
// frame curves and of the circle, triangulated so the triangles follow the curves. Immutable once
// built, shared by every registration through the frame; not copyable (its locator points into it).
class PartitionMesh {
 public:
  // Takes counter-clockwise triangles of positive area over all `vertices` (points of the closed
  // disk) covering a convex polygon that contains the origin. Throws kInvalidArgument otherwise
  // (naming the face or vertex).
  PartitionMesh(std::vector<Vec2> vertices, std::vector<Face> faces);
  PartitionMesh(const PartitionMesh&) = delete;
  PartitionMesh& operator=(const PartitionMesh&) = delete;

  const std::vector<Vec2>& vertices() const { return vertices_; }
  const std::vector<Face>& faces() const { return faces_; }
  // The boundary polygon, counter-clockwise from the vertex of smallest angle in [0, 2π).
  const std::vector<int>& boundary() const { return boundary_; }

  // The triangle holding w (barycentrics clamped within 1e-9 of its size); nullopt outside the
  // polygon, in the gap between a boundary chord and the circle (or beyond the circle).
  std::optional<SurfacePoint> locate(const Vec2& w) const { return locator_.locate(w); }
  // The boundary chord whose wedge from the origin holds w: k for the chord from boundary()[k] to
  // boundary()[k + 1] (cyclically). Any w but the origin.
  int chord(const Vec2& w) const;

 private:
  std::vector<Vec2> vertices_;
  std::vector<Face> faces_;
  std::vector<int> boundary_;
  std::vector<double> boundary_angle_;  // angle of each boundary vertex, increasing
  TriangleLocator locator_;             // over vertices_ and faces_: declared after them
};

// A geodesic frame of the reference frame (paper §4) and its partition mesh (§5).
struct GeodesicFrame {
  // The landmark graph on the reference disk: the landmarks in the order given (rim markers, and
  // landmarks within 1e-9 of the circle, projected onto it), then the circle samples.
  std::vector<Vec2> graph_points;
  int landmark_count = 0;
  std::vector<Face> graph_faces;  // counter-clockwise
  // One curve per graph edge inside the disk. The graph's hull chords are not curves: the partition
  // reaches the circle with its own, finer circle samples.
  std::vector<FramePath> paths;
  std::shared_ptr<const PartitionMesh> partition;  // vertices: the graph points first, same indices
  int straight_paths = 0;                          // curves that fell back to the straight segment
  int unconverged_paths = 0;                       // corrected curves that stopped above the angle tolerance
  int unconforming_segments = 0;                   // curve pieces between samples that are not partition edges
  double seconds_paths = 0, seconds_partition = 0;
};

// Builds the frame once per capture from the reference frame's disk map and its landmarks on that
// disk (`on_rim`: 1 for a boundary marker, one per landmark, or empty for none). Each graph edge's
// straight disk segment is pulled back onto the surface, corrected toward a geodesic and mapped back;
// a curve that would leave its two graph triangles or cross another curve falls back to its straight
// segment (FramePath::straight says why). Throws kInvalidArgument for fewer than 3 landmarks,
// mismatched sizes, points not finite or outside the closed disk, rim markers more than 1e-3 off the
// circle, coincident landmarks, bad options, a map whose sizes disagree; kNumerical when the graph
// or the partition cannot be triangulated or a segment cannot be walked (a broken map).
GeodesicFrame make_geodesic_frame(const DiskMap& reference, const std::vector<Vec2>& landmarks, const std::vector<uint8_t>& on_rim,
                                  const GeodesicFrameOptions& options = {});

// The corrected geodesic between two points of the closed disk on `map`'s surface, as a frame curve
// (from = to = -1; never straight). Throws kInvalidArgument for points outside the closed disk or not
// finite or equal, bad options; kNumerical as make_geodesic_frame.
FramePath geodesic_path(const DiskMap& map, const Vec2& from, const Vec2& to, const GeodesicFrameOptions& options = {});

// Φ from given images of the partition vertices (register_disks passes f̄(V)): each triangle mapped
// affinely onto its image triangle, the gap between a boundary chord and the circle radially onto the
// gap beyond the image chord; `base` supplies m and the GMF (smooth_base) and is what a fold falls back
// to (kGmfInsteadOfFrame, unless allow_fallback is false: then Φ, with check.ok() false). E_D is
// computed on `landmarks`. Throws kInvalidArgument for a frame without a partition, one image per
// vertex missing or not finite, or landmarks as register_disks.
DiskRegistration register_through_partition(const GeodesicFrame& frame, const DiskRegistration& base, std::vector<Vec2> images,
                                            const DiskLandmarks& landmarks, bool allow_fallback = true);

}  // namespace facemorph
