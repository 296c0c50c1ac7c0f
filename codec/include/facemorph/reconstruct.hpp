// The decoder's core (paper §6, method-notes §8, spec/method.md §5): what a keyframe stores on the
// shared disk grid G, and the Laplace-Beltrami reconstruction of a surface from it.
//
// The discrete Laplacian on G is the P1 finite-element one (cotangent weights of G's flat
// triangulation, lumped Voronoi mass): Δ_h S = -M⁻¹ K S. On G's Cartesian interior it is the
// 5-point stencil; everywhere it is symmetric, so it is factored once per grid by Cholesky. The
// encoder computes the stored fields with exactly these operators, so a keyframe decodes to a
// fixed point equal to its resampled surface (closed loop).
#pragma once

#include "facemorph/disk_grid.hpp"
#include "facemorph/geometry.hpp"
#include "facemorph/mesh.hpp"

#include <Eigen/Core>
#include <Eigen/Sparse>

#include <memory>
#include <string>
#include <vector>

namespace facemorph {

enum class Representation {
  kHL,   // the paper's: mean curvature H and log λ
  kHLT,  // H, log λ and the tangential part (a, b) of Δ_h S; Cartesian Δ_h S in the rim band
  kXYZ,  // positions
};
const char* representation_name(Representation representation);  // "hl", "hl+t", "xyz"
Representation parse_representation(const std::string& name);     // throws kInvalidArgument

// The operators on G that encoder and decoder share.
class GridGeometry {
 public:
  explicit GridGeometry(DiskGrid grid);

  const DiskGrid& grid() const { return grid_; }
  int interior_count() const { return grid_.interior_count; }
  // The rim band: interior nodes with |w| > 1 - 2h; hl+t stores their Laplacian in boundary frames.
  const std::vector<int32_t>& band_nodes() const { return band_nodes_; }
  int band_count() const { return static_cast<int>(band_nodes_.size()); }

  // Δ_h S = -M⁻¹ K S at the interior nodes (S given at every node of G).
  std::vector<Vec3> laplacian(const std::vector<Vec3>& positions) const;
  // λ² per interior node: surface area over disk area of the faces around it.
  std::vector<double> conformal_factor_squared(const std::vector<Vec3>& positions) const;
  // Orthonormal frame (t_u, t_v, n) per interior node: n = S_u × S_v / |S_u × S_v|, t_u along S_u,
  // t_v = n × t_u. Central differences where the four neighbours are interior nodes (every node
  // outside the rim band), else the area-weighted Jacobian of the surrounding faces.
  void frames(const std::vector<Vec3>& positions, std::vector<Vec3>& tu, std::vector<Vec3>& tv, std::vector<Vec3>& n) const;

  // Orthonormal frame for each of `nodes` from the boundary curve alone (`rim`: positions at the
  // rim nodes): the rim's tangent at the node's angle, the direction towards the rim's centroid
  // orthogonal to it, and their cross product. It rotates with the boundary and, the boundary
  // being data, does not change while the decoder iterates.
  std::vector<std::array<Vec3, 3>> boundary_frames(const std::vector<Vec3>& rim, const std::vector<int32_t>& nodes) const;

  const SparseMatrix& stiffness() const { return K_; }        // over all nodes, SPD on the interior block
  const Eigen::VectorXd& mass() const { return mass_; }       // lumped, per node

 private:
  DiskGrid grid_;
  SparseMatrix K_;
  Eigen::VectorXd mass_;
  std::vector<int32_t> band_nodes_;
  std::vector<std::array<int32_t, 4>> neighbours_;  // interior node: E, W, N, S interior indices or -1
  std::vector<std::vector<int32_t>> faces_of_;      // faces around each node
};

// What one surface stores on G, dequantised (spec/method.md §5.2).
struct GridFields {
  Representation representation = Representation::kHLT;
  int grid_n = 0;
  std::vector<double> mean_curvature;        // H per interior node (hl, hl+t; 0 at fixed-frame nodes for hl+t)
  std::vector<double> log_conformal_factor;  // log λ per interior node (hl, hl+t)
  std::vector<double> tangential_u;          // a = <Δ_h S, t_u> per interior node (hl+t; 0 at fixed-frame nodes)
  std::vector<double> tangential_v;          // b = <Δ_h S, t_v>
  // hl+t: the nodes whose Δ_h S is stored in a boundary frame instead (sorted): the rim band, plus
  // any crowded nodes the encoder adds; and those vectors' components in their boundary frames.
  std::vector<int32_t> fixed_nodes;
  std::vector<Vec3> fixed_laplacian;
  std::vector<Vec3> positions;               // per interior node (xyz)
  std::vector<Vec3> rim;                     // the boundary curve: positions at the rim nodes
};

// The fields of a surface sampled at every node of G (interior nodes, then rim nodes). For hl+t,
// `extra_fixed_nodes` are stored in boundary frames like the band (see folded_nodes); keyframes to
// be blended must share them, so a sequence passes the union over its keyframes.
GridFields compute_fields(const GridGeometry& geometry, const std::vector<Vec3>& positions, Representation representation,
                          const std::vector<int32_t>& extra_fixed_nodes = {});

// Interior nodes where the sampled surface folds at the grid's resolution — a grid neighbour's normal
// more than 60° away (90° misses a fold along a grid line, whose own normal lies sideways) — and
// the two rings around them. There (ICT's closed-lip grooves, thinner than
// a grid cell) the frame-dependent equations have a second solution the decoder converges to
// (measured: 2.4% RMS instead of 0.17%); stored in boundary frames, their equations are linear.
std::vector<int32_t> folded_nodes(const GridGeometry& geometry, const std::vector<Vec3>& positions);

// Σ weights[k] · fields of keys[k], field by field (log λ in log space, band vectors in their band
// frames, the boundary curve point by point): how keyframes are interpolated. The keys must share
// the representation and grid (kInvalidArgument otherwise); weights need not sum to 1 (spline
// extrapolation).
GridFields combine_fields(const std::vector<const GridFields*>& keys, const std::vector<double>& weights);

// Rounds every field to 16 bits (fixed point over its own [min, max]; the band separately from
// the interior) and back: what a container keyframe holds (spec/method.md §5.3).
GridFields quantize_fields(const GridFields& fields);

struct ReconstructOptions {
  int max_iterations = 200;
  // Stop when max |S⁺ - S| < tolerance x diameter of the boundary curve. 1e-5 is the level of the
  // 16-bit quantisation (spec/method.md §5.4); the notes' 1e-6 costs 3-4 more iterations per frame.
  double tolerance = 1e-5;
  double damping = 1.0;  // n ← normalize((1 - ω) n_old + ω n_new); 1: none
  // Anderson acceleration over this many past iterates (0: the plain iteration). The plain iteration
  // oscillates where the grid under-resolves crowded regions (ICT: no convergence in 200 steps);
  // with depth 5 it converged in 42 (N = 256) and cut Medusa's 24 steps to 14.
  int anderson_depth = 5;
  // In a sequence, start from 2 S(previous) - S(one before) rather than S(previous).
  bool extrapolate_warm_start = true;
  // Not meeting the tolerance throws kNotConverged; false returns the best effort with
  // converged = false and the last change, for callers that prefer a frame to an error.
  bool throw_on_failure = true;
};

struct ReconstructResult {
  std::vector<Vec3> positions;  // every node of G
  int iterations = 0;
  double change = 0;            // last max |S⁺ - S| / diameter
  bool converged = false;
};

// The decoder's state for one grid: the factorisation of the interior Laplacian (done once) and the
// previous surface, the warm start for the next frame of a sequence. Not thread-safe; one per thread.
class Reconstructor {
 public:
  explicit Reconstructor(int grid_n);
  ~Reconstructor();
  Reconstructor(const Reconstructor&) = delete;
  Reconstructor& operator=(const Reconstructor&) = delete;

  const GridGeometry& geometry() const { return *geometry_; }

  // Solves Δ_h S = F(S) with S = rim on the boundary, F from the fields (hl: 2Hλ²n; hl+t: 2Hλ²n +
  // a t_u + b t_v inside, the stored vector in the band), iterating on the frame. Starts from the
  // previous result when there is one (warm), else from the harmonic surface. Throws
  // kInvalidArgument for fields of another grid; kNotConverged, naming the residual, when the
  // iteration does not meet the tolerance or produces NaN (never returns garbage silently).
  ReconstructResult reconstruct(const GridFields& fields, const ReconstructOptions& options = {});

  void forget_warm_start();
  // Bytes held by the factorisation (its factor's nonzeros and indices).
  size_t factorization_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<GridGeometry> geometry_;
  std::unique_ptr<Impl> impl_;
};

// The grid surface as a mesh: G's faces, positions per node, UV = (w + 1) / 2.
TriangleMesh grid_mesh(const DiskGrid& grid, const std::vector<Vec3>& positions);

}  // namespace facemorph
