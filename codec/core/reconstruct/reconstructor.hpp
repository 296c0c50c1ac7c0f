// The decoder's core (paper §6, method-notes §8, spec/method.md §5.4): the Laplace-Beltrami
// reconstruction of a surface on the shared disk grid G from the fields a keyframe stores (or a
// blend of them). The discrete Laplacian is symmetric positive definite on G's interior; each step
// solves it for x, y and z together, with the right-hand side from the current frame, by one
// multigrid V-cycle from the current surface (its hierarchy built once per grid).
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"

#include <memory>
#include <vector>

namespace facemorph {

// A reconstruction stopped by its work meter (ReconstructOptions::work): its iterate and the
// iteration's state, so that the next reconstruct given it goes on to the result the reconstruction
// would have reached without the stop, to the bit. Held by the caller, who gives it back only with
// the same fields and options (the decoder keys it by keyframe or by t).
class ReconstructSuspension {
 public:
  ReconstructSuspension();
  ~ReconstructSuspension();
  ReconstructSuspension(ReconstructSuspension&&) noexcept;
  ReconstructSuspension& operator=(ReconstructSuspension&&) noexcept;
  bool held() const { return state_ != nullptr; }
  void clear();

 private:
  friend class Reconstructor;
  struct State;
  std::unique_ptr<State> state_;
};

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
  // Start from this surface (every node of G; interior values used) instead of the warm start or
  // the harmonic surface: e.g. the spline of the keyframes' own decoded surfaces. Not owned.
  const std::vector<Vec3>* start = nullptr;
  // Not meeting the tolerance throws kNotConverged; false returns the best effort with
  // converged = false and the last change, for callers that prefer a frame to an error. (A
  // non-finite iterate has no best effort: it always throws kNumerical.)
  bool throw_on_failure = true;
  // Give up when the change has not reached a new low for this many iterations (0: run to
  // max_iterations): an iteration that stops falling does not converge, and a file whose fields
  // never settle then costs this many steps a call instead of max_iterations (spec/container.md §10.3).
  int stall_iterations = 40;
  // The call's work meter (not owned; null: unbounded): each iteration is charged G's interior nodes
  // before it runs. Where the meter refuses one, the iteration's state goes to `suspended` (when
  // given: resumed from there by the next reconstruct given it) and kLimit is thrown.
  WorkMeter* work = nullptr;
  ReconstructSuspension* suspended = nullptr;
};

struct ReconstructResult {
  std::vector<Vec3> positions;  // every node of G
  int iterations = 0;
  double change = 0;  // last max |S⁺ - S| / diameter
  bool converged = false;
};

// The decoder's state for one grid: the multigrid hierarchy of the interior Laplacian (built once) and the
// previous surface, the warm start for the next frame of a sequence. Not thread-safe; one per thread.
class Reconstructor {
 public:
  explicit Reconstructor(int grid_n);
  // On a G and geometry built before and shared (immutable): several decoders of one file build G
  // once (KeyframeSource::grid_geometry). Null: kInvalidArgument.
  explicit Reconstructor(std::shared_ptr<const GridGeometry> geometry);
  ~Reconstructor();
  Reconstructor(const Reconstructor&) = delete;
  Reconstructor& operator=(const Reconstructor&) = delete;

  const GridGeometry& geometry() const { return *geometry_; }
  const std::shared_ptr<const GridGeometry>& shared_geometry() const { return geometry_; }

  // Solves Δ_h S = F(S) with S = rim on the boundary, F from the fields (hl: 2Hλ²n; hl+t: 2Hλ²n +
  // a t_u + b t_v inside, the stored vector in the band), iterating on the frame. Starts from the
  // previous result when there is one (warm), else from the harmonic surface. Throws
  //   kInvalidArgument  fields that fail validate_fields, or were made for another grid;
  //   kNumerical        an iterate that is not finite (inconsistent or overflowing fields);
  //   kNotConverged     the tolerance not met in max_iterations, naming the last change (unless
  //                     throw_on_failure is false: then the best effort, converged = false).
  // Never returns garbage silently. A throw leaves the warm start as it was.
  ReconstructResult reconstruct(const GridFields& fields, const ReconstructOptions& options = {});

  void forget_warm_start();
  // Bytes held by the solver of K_II (the multigrid hierarchy: its matrices and work arrays).
  size_t solver_bytes() const;

 private:
  struct Impl;
  std::shared_ptr<const GridGeometry> geometry_;
  std::unique_ptr<Impl> impl_;
};

// The grid surface as a mesh: G's faces, positions per node, UV = (w + 1) / 2.
TriangleMesh grid_mesh(const DiskGrid& grid, const std::vector<Vec3>& positions);

}  // namespace facemorph
