// The Riemann conformal map: preconditioning, linear start, QIEM on the double cover, projection.
#include "facemorph/encoder/conformal.hpp"
#include "facemorph/distance.hpp"
#include "facemorph/error.hpp"
#include "facemorph/geometry.hpp"
#include "facemorph/topology.hpp"

#include "codec/conformal/double_cover.hpp"
#include "codec/conformal/spd_solver.hpp"

#include <Eigen/SparseLU>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <numeric>
#include <unordered_map>

namespace facemorph {
namespace {

constexpr double kPi = std::numbers::pi;

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

double signed_area(const Vec2& a, const Vec2& b, const Vec2& c) {
  return 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x()));
}

// The intrinsic Delaunay triangulation of a mesh: its faces and edge lengths (the Laplacian built
// from them has non-negative weights everywhere but on boundary edges, which are never flipped).
struct IntrinsicMesh {
  std::vector<Face> faces;
  std::vector<CornerValues> lengths;
  int flips = 0;
};
IntrinsicMesh intrinsic_delaunay(const TriangleMesh& mesh) {
  IntrinsicMesh out{mesh.faces, face_edge_lengths(mesh), 0};
  out.flips = flip_to_intrinsic_delaunay(out.faces, out.lengths);
  return out;
}

// Harmonic map onto the disk with the rim on the unit circle at arc-length angles. With the
// intrinsic Delaunay weights (all interior weights >= 0) this is a convex-combination map.
std::vector<Vec2> linear_disk_map(const TriangleMesh& mesh, const IntrinsicMesh& intrinsic, const std::vector<int>& rim) {
  const int n = mesh.vertex_count();
  const SparseMatrix K = laplacian_from_cotangents(intrinsic.faces, corner_cotangents_from_lengths(intrinsic.lengths), n);
  std::vector<Vec2> w(static_cast<size_t>(n), Vec2::Zero());
  std::vector<int> unknown(static_cast<size_t>(n), 0);
  double perimeter = 0;
  std::vector<double> arc = {0.0};
  for (size_t i = 0; i < rim.size(); ++i) {
    perimeter += (mesh.positions[static_cast<size_t>(rim[i])] - mesh.positions[static_cast<size_t>(rim[(i + 1) % rim.size()])]).norm();
    arc.push_back(perimeter);
  }
  std::vector<uint8_t> fixed(static_cast<size_t>(n), 0);
  for (size_t i = 0; i < rim.size(); ++i) {
    const double theta = 2 * kPi * arc[i] / perimeter;
    w[static_cast<size_t>(rim[i])] = Vec2(std::cos(theta), std::sin(theta));
    fixed[static_cast<size_t>(rim[i])] = 1;
  }
  int m = 0;
  for (int v = 0; v < n; ++v) unknown[static_cast<size_t>(v)] = fixed[static_cast<size_t>(v)] ? -1 : m++;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(m, 2);
  for (int k = 0; k < K.outerSize(); ++k) {
    for (SparseMatrix::InnerIterator it(K, k); it; ++it) {
      const int i = static_cast<int>(it.row()), j = static_cast<int>(it.col());
      if (unknown[static_cast<size_t>(i)] < 0) continue;
      if (unknown[static_cast<size_t>(j)] >= 0) {
        triplets.emplace_back(unknown[static_cast<size_t>(i)], unknown[static_cast<size_t>(j)], it.value());
      } else {
        rhs.row(unknown[static_cast<size_t>(i)]) -= it.value() * w[static_cast<size_t>(j)].transpose();
      }
    }
  }
  if (m > 0) {
    SparseMatrix A(m, m);
    A.setFromTriplets(triplets.begin(), triplets.end());
    SpdSolver solver;
    solver.analyze(A);
    if (!solver.factorize(A)) throw Error(ErrorCode::kNumerical, "linear disk map: the Laplacian could not be factored");
    const Eigen::MatrixXd x = solver.solve(rhs);
    if (!x.allFinite()) throw Error(ErrorCode::kNumerical, "linear disk map: non-finite solution");
    for (int v = 0; v < n; ++v) {
      if (unknown[static_cast<size_t>(v)] >= 0) w[static_cast<size_t>(v)] = x.row(unknown[static_cast<size_t>(v)]).transpose();
    }
  }
  return w;
}

// Stereographic coordinates of a southern-hemisphere point, and back.
Complex to_plane(const Eigen::RowVector3d& p) { return Complex(p.x(), p.y()) / (1.0 - p.z()); }
Eigen::RowVector3d to_sphere(const Complex& w) {
  const double r2 = std::norm(w);
  return Eigen::RowVector3d(2 * w.real(), 2 * w.imag(), r2 - 1) / (1 + r2);
}

// Centres a symmetric spherical map: finds the disk automorphism w -> (w - a)/(1 - ā w) (applied to
// copy 1 in stereographic coordinates, mirrored to copy 2) after which the area-weighted centroid
// of the image is the origin, and applies it. The map is only defined up to such automorphisms, so
// this fixes the gauge without changing the (continuum) energy. The radial projection
// (φ - c)/|φ - c| some codes use is not a Möbius map: it perturbed the energy by ~1e-7 per step
// and stalled the flow on real faces (spec/method.md §3.2).
void centre_by_moebius(Eigen::MatrixXd& p, const Eigen::VectorXd& areas, const DoubleCover& cover) {
  const int n = cover.disk_vertices;
  std::vector<Complex> w(static_cast<size_t>(n));
  std::vector<double> weight(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    w[static_cast<size_t>(i)] = to_plane(p.row(i));
    const int mi = cover.mirror[static_cast<size_t>(i)];
    weight[static_cast<size_t>(i)] = areas[i] + (mi != i ? areas[mi] : 0.0);
  }
  // Centroid (x + iy) of the image after the automorphism with parameter a (copy 2 has the same x, y).
  auto centroid = [&](const Complex& a) {
    Complex sum = 0;
    for (int i = 0; i < n; ++i) {
      const Complex z = (w[static_cast<size_t>(i)] - a) / (1.0 - std::conj(a) * w[static_cast<size_t>(i)]);
      sum += weight[static_cast<size_t>(i)] * 2.0 * z / (1 + std::norm(z));
    }
    return sum;
  };
  const double total = std::accumulate(weight.begin(), weight.end(), 0.0);
  Complex a = 0;
  for (int iteration = 0; iteration < 8; ++iteration) {
    const Complex f = centroid(a);
    if (std::abs(f) < 1e-13 * total) break;
    // Newton on R²: the Jacobian by central differences.
    const double h = 1e-7;
    const Complex dx = (centroid(a + Complex(h, 0)) - centroid(a - Complex(h, 0))) / (2 * h);
    const Complex dy = (centroid(a + Complex(0, h)) - centroid(a - Complex(0, h))) / (2 * h);
    Eigen::Matrix2d J;
    J << dx.real(), dy.real(), dx.imag(), dy.imag();
    const Eigen::Vector2d step = J.fullPivLu().solve(Eigen::Vector2d(f.real(), f.imag()));
    Complex next = a - Complex(step.x(), step.y());
    if (!(std::abs(next) < 0.9)) break;  // a wild step: keep what we have
    a = next;
  }
  if (a == Complex(0)) return;
  for (int i = 0; i < n; ++i) {
    const Complex z = (w[static_cast<size_t>(i)] - a) / (1.0 - std::conj(a) * w[static_cast<size_t>(i)]);
    Eigen::RowVector3d q = to_sphere(z);
    const int mi = cover.mirror[static_cast<size_t>(i)];
    if (mi == i) q.z() = 0;
    p.row(i) = q.normalized();
    if (mi != i) p.row(mi) << q.x(), q.y(), -q.z();
  }
}

struct FlowResult {
  Eigen::MatrixXd phi;  // one unit vector per double-cover vertex
  int iterations = 0;
  int factorizations = 0;
  double energy = 0;
};

// The QIEM system restricted to the mirror-symmetric maps it produces. On the double cover
// x and y are even (equal on both copies) and z is odd (opposite, 0 on the boundary), and
// A = I + δt(K - D) commutes with the mirror, so A φ = b splits exactly into the Galerkin systems
// Pᵀ A P x = Pᵀ b for the even prolongation P_e (disk vertices) and the odd one P_o (interior
// vertices). Two systems of the disk's size instead of one of twice it: cheaper to factor, and the
// symmetry (boundary exactly on the equator) holds by construction.
class SymmetricSystems {
 public:
  SymmetricSystems(const SparseMatrix& K, const DoubleCover& cover) : cover_(cover), n_(cover.disk_vertices) {
    odd_index_.assign(static_cast<size_t>(n_), -1);
    for (int i = 0; i < n_; ++i) {
      if (!cover.on_boundary[static_cast<size_t>(i)]) odd_index_[static_cast<size_t>(i)] = odd_count_++;
    }
    even_mass_.resize(n_);
    odd_mass_ = Eigen::VectorXd::Constant(odd_count_, 2.0);
    for (int i = 0; i < n_; ++i) even_mass_[i] = cover.on_boundary[static_cast<size_t>(i)] ? 1.0 : 2.0;
    std::vector<Eigen::Triplet<double>> even, odd;
    for (int c = 0; c < K.outerSize(); ++c) {
      for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
        const int r = static_cast<int>(it.row());
        const int fr = fold(r), fc = fold(static_cast<int>(it.col()));
        even.emplace_back(fr, fc, it.value());
        const int orow = odd_index_[static_cast<size_t>(fr)], ocol = odd_index_[static_cast<size_t>(fc)];
        if (orow >= 0 && ocol >= 0) odd.emplace_back(orow, ocol, sign(r) * sign(static_cast<int>(it.col())) * it.value());
      }
    }
    K_even_.resize(n_, n_);
    K_even_.setFromTriplets(even.begin(), even.end());
    K_odd_.resize(odd_count_, odd_count_);
    K_odd_.setFromTriplets(odd.begin(), odd.end());
    A_even_ = K_even_;
    A_odd_ = K_odd_;
    even_solver_.analyze(A_even_);
    odd_solver_.analyze(A_odd_);
  }

  // One step: solves [I + δt(K - D)] φ⁺ = φ for symmetric φ. False when a factorisation fails.
  bool step(const Eigen::MatrixXd& phi, const Eigen::VectorXd& D, double dt, Eigen::MatrixXd& next) {
    A_even_ = K_even_ * dt;
    for (int i = 0; i < n_; ++i) A_even_.coeffRef(i, i) += even_mass_[i] * (1.0 - dt * D[i]);
    A_odd_ = K_odd_ * dt;
    Eigen::VectorXd rhs_odd(odd_count_);
    for (int i = 0; i < n_; ++i) {
      const int o = odd_index_[static_cast<size_t>(i)];
      if (o < 0) continue;
      A_odd_.coeffRef(o, o) += odd_mass_[o] * (1.0 - dt * D[i]);
      rhs_odd[o] = odd_mass_[o] * phi(i, 2);
    }
    if (!even_solver_.factorize(A_even_) || !odd_solver_.factorize(A_odd_)) return false;
    Eigen::MatrixXd rhs_even(n_, 2);
    for (int i = 0; i < n_; ++i) rhs_even.row(i) = even_mass_[i] * phi.row(i).head<2>();
    const Eigen::MatrixXd xy = even_solver_.solve(rhs_even);
    const Eigen::MatrixXd z = odd_solver_.solve(rhs_odd);
    next.resize(phi.rows(), 3);
    for (int i = 0; i < n_; ++i) {
      const int o = odd_index_[static_cast<size_t>(i)];
      next.row(i) << xy(i, 0), xy(i, 1), o >= 0 ? z(o, 0) : 0.0;
      const int mi = cover_.mirror[static_cast<size_t>(i)];
      if (mi != i) next.row(mi) << xy(i, 0), xy(i, 1), -next(i, 2);
    }
    return next.allFinite();
  }

 private:
  int fold(int v) const { return v < n_ ? v : cover_.mirror[static_cast<size_t>(v)]; }
  double sign(int v) const { return v < n_ ? 1.0 : -1.0; }

  const DoubleCover& cover_;
  int n_;
  int odd_count_ = 0;
  std::vector<int> odd_index_;
  Eigen::VectorXd even_mass_, odd_mass_;  // Pᵀ P: 2 for vertices with two copies, 1 on the boundary
  SparseMatrix K_even_, K_odd_, A_even_, A_odd_;
  SpdSolver even_solver_, odd_solver_;
};

// QIEM on the double cover (method-notes §2.4): [I + δt (K - D)] φ⁺ = φ, projection to the sphere,
// centring by a disk Möbius map. Symmetric throughout (see SymmetricSystems).
FlowResult spherical_flow(const SparseMatrix& K, const Eigen::VectorXd& areas, const DoubleCover& cover,
                          Eigen::MatrixXd phi, const ConformalOptions& options) {
  const Eigen::Index N = K.rows();
  auto energy_of = [&](const Eigen::MatrixXd& p) { return 0.5 * (p.transpose() * (K * p)).trace(); };
  auto project = [&](Eigen::MatrixXd& p) {
    for (Eigen::Index i = 0; i < N; ++i) p.row(i).normalize();
    centre_by_moebius(p, areas, cover);
  };
  project(phi);
  double energy = energy_of(phi);
  SymmetricSystems systems(K, cover);
  FlowResult result;
  // The fixed point K φ = D φ does not depend on δt, only the path does. 0.9 / max D keeps
  // I + δt(K - D) SPD, but on crowded faces max D is set by a few tiny triangles and that step is
  // far too short for the rest. So start at twice it and grow δt by 1.25 after every step that
  // lowered the energy at the first try (halve it when a try did not). A long step can make the
  // matrix indefinite; a failed factorisation, like a rise in energy, just halves the step.
  // Measured (spec/method.md §3.3): growth 1.25 of {1, 1.25, 1.5, 2, 4}, start 2x of {1, 2, 4, 8, 16}
  // took fewest factorisations on synthetic, Medusa and ICT frames.
  double growth = 2.0;
  for (int step = 0; step < options.max_iterations; ++step) {
    const Eigen::MatrixXd Kphi = K * phi;
    const Eigen::VectorXd D = (Kphi.array() * phi.array()).rowwise().sum();
    const double max_d = D.maxCoeff();
    if (!(max_d > 0) || !std::isfinite(max_d)) throw Error(ErrorCode::kNumerical, "QIEM: degenerate map (max D = " + std::to_string(max_d) + ")");
    Eigen::MatrixXd next;
    double next_energy = energy;
    bool accepted = false, rejected = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      const double dt = growth * 0.9 / max_d;
      ++result.factorizations;
      if (systems.step(phi, D, dt, next)) {
        project(next);
        next_energy = energy_of(next);
        accepted = next_energy <= energy * (1 + 1e-12);
      }
      if (!accepted) {
        growth = std::max(growth * 0.5, 1.0 / 64);
        rejected = true;
      }
    }
    if (!accepted) throw Error(ErrorCode::kNumerical, "QIEM: no step lowers the energy");
    growth = std::min(growth * (rejected ? 1.0 : 1.25), 1e6);
    phi = std::move(next);
    const double change = std::abs(energy - next_energy) / energy;
    energy = next_energy;
    result.iterations = step + 1;
    if (change < options.energy_tolerance) {
      result.phi = std::move(phi);
      result.energy = energy;
      return result;
    }
  }
  throw Error(ErrorCode::kNotConverged, "QIEM: no convergence in " + std::to_string(options.max_iterations) + " steps");
}

// Inverse stereographic projection of a disk map onto the southern hemisphere, mirrored on copy 2.
Eigen::MatrixXd initial_sphere_map(const std::vector<Vec2>& w, const DoubleCover& cover) {
  Eigen::MatrixXd phi(cover.vertex_count(), 3);
  for (int i = 0; i < cover.disk_vertices; ++i) {
    const Vec2& p = w[static_cast<size_t>(i)];
    const double r2 = p.squaredNorm();
    phi.row(i) << 2 * p.x() / (1 + r2), 2 * p.y() / (1 + r2), (r2 - 1) / (1 + r2);
    const int mi = cover.mirror[static_cast<size_t>(i)];
    if (mi != i) phi.row(mi) << phi(i, 0), phi(i, 1), -phi(i, 2);
  }
  return phi;
}

int count_flipped(const std::vector<Vec2>& w, const std::vector<Face>& faces) {
  int flipped = 0;
  for (const Face& f : faces) {
    flipped += signed_area(w[static_cast<size_t>(f[0])], w[static_cast<size_t>(f[1])], w[static_cast<size_t>(f[2])]) <= 0;
  }
  return flipped;
}

// Mean-value weights (Floater 2003) of the edges at vertex i, from the surface's angles: always
// positive, so with a fixed convex border the solution is an embedding (Tutte-Floater).
void add_mean_value_row(const TriangleMesh& surface, const std::vector<std::vector<int>>& faces_of, int i,
                        std::vector<std::pair<int, double>>& row) {
  row.clear();
  for (int f : faces_of[static_cast<size_t>(i)]) {
    const Face& t = surface.faces[static_cast<size_t>(f)];
    int k = 0;
    while (t[k] != i) ++k;
    const int j = t[(k + 1) % 3], l = t[(k + 2) % 3];
    const Vec3& p = surface.positions[static_cast<size_t>(i)];
    const Vec3 a = surface.positions[static_cast<size_t>(j)] - p, b = surface.positions[static_cast<size_t>(l)] - p;
    const double half_tan = std::tan(0.5 * std::atan2(a.cross(b).norm(), a.dot(b)));
    row.push_back({j, half_tan / std::max(a.norm(), 1e-300)});
    row.push_back({l, half_tan / std::max(b.norm(), 1e-300)});
  }
}

// Removes flipped triangles from a disk map: the vertices within `rings` of a flipped face (rim
// excluded) are re-solved with mean-value weights, the patch border fixed; the patch doubles until
// no face is flipped. At worst the patch is the whole disk, whose border (the rim on the circle)
// is convex, and the result is then guaranteed to be an embedding. Returns the vertices moved.
int untangle(DiskMap& map) {
  const auto& faces = map.surface.faces;
  const int n = map.surface.vertex_count();
  std::vector<std::vector<int>> faces_of(static_cast<size_t>(n));
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int32_t v : faces[f]) faces_of[static_cast<size_t>(v)].push_back(static_cast<int>(f));
  }
  std::vector<uint8_t> on_rim(static_cast<size_t>(n), 0);
  for (int v : map.rim) on_rim[static_cast<size_t>(v)] = 1;
  auto flipped_faces = [&] {
    std::vector<int> out;
    for (size_t f = 0; f < faces.size(); ++f) {
      if (signed_area(map.disk[static_cast<size_t>(faces[f][0])], map.disk[static_cast<size_t>(faces[f][1])],
                      map.disk[static_cast<size_t>(faces[f][2])]) <= 0) out.push_back(static_cast<int>(f));
    }
    return out;
  };
  std::vector<int> flipped = flipped_faces();
  int moved = 0;
  std::vector<std::pair<int, double>> row;
  for (int rings = 1; !flipped.empty(); rings *= 2) {
    // Grow the patch ring by ring from the flipped faces' vertices.
    std::vector<int> in_patch(static_cast<size_t>(n), -1);
    std::vector<int> patch;
    for (int f : flipped) {
      for (int32_t v : faces[static_cast<size_t>(f)]) {
        if (in_patch[static_cast<size_t>(v)] < 0 && !on_rim[static_cast<size_t>(v)]) {
          in_patch[static_cast<size_t>(v)] = static_cast<int>(patch.size());
          patch.push_back(v);
        }
      }
    }
    const bool whole = rings >= n;
    for (size_t begin = 0, ring = 0; (whole || ring < static_cast<size_t>(rings)) && begin < patch.size(); ++ring) {
      const size_t end = patch.size();
      for (size_t k = begin; k < end; ++k) {
        for (int f : faces_of[static_cast<size_t>(patch[k])]) {
          for (int32_t v : faces[static_cast<size_t>(f)]) {
            if (in_patch[static_cast<size_t>(v)] < 0 && !on_rim[static_cast<size_t>(v)]) {
              in_patch[static_cast<size_t>(v)] = static_cast<int>(patch.size());
              patch.push_back(v);
            }
          }
        }
      }
      begin = end;
    }
    const auto m = static_cast<Eigen::Index>(patch.size());
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(m, 2);
    for (Eigen::Index r = 0; r < m; ++r) {
      add_mean_value_row(map.surface, faces_of, patch[static_cast<size_t>(r)], row);
      double diagonal = 0;
      for (const auto& [j, w] : row) {
        diagonal += w;
        const int c = in_patch[static_cast<size_t>(j)];
        if (c >= 0) triplets.emplace_back(r, c, -w);
        else rhs.row(r) += w * map.disk[static_cast<size_t>(j)].transpose();
      }
      triplets.emplace_back(r, r, diagonal);
    }
    SparseMatrix A(m, m);
    A.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SparseLU<SparseMatrix> solver(A);  // mean-value weights are not symmetric
    if (solver.info() != Eigen::Success) throw Error(ErrorCode::kNumerical, "untangling the disk map: singular patch system");
    const Eigen::MatrixXd x = solver.solve(rhs);
    for (Eigen::Index r = 0; r < m; ++r) map.disk[static_cast<size_t>(patch[static_cast<size_t>(r)])] = x.row(r).transpose();
    moved = std::max(moved, static_cast<int>(m));
    flipped = flipped_faces();
    if (whole && !flipped.empty()) throw Error(ErrorCode::kNumerical, "untangling the disk map failed even on the whole disk");
  }
  return moved;
}

}  // namespace

const char* conformal_method_name(ConformalMethod method) { return method == ConformalMethod::kQiem ? "qiem" : "linear"; }

ConformalMethod parse_conformal_method(const std::string& name) {
  if (name == "qiem") return ConformalMethod::kQiem;
  if (name == "linear") return ConformalMethod::kLinear;
  throw Error(ErrorCode::kInvalidArgument, "unknown conformal method '" + name + "' (qiem, linear)");
}

DiskMap conformal_disk_map(const TriangleMesh& input, const ConformalOptions& options) {
  auto start = std::chrono::steady_clock::now();
  DiskMap map;
  map.surface = input;
  map.source_vertex.resize(input.positions.size());
  for (size_t i = 0; i < map.source_vertex.size(); ++i) map.source_vertex[i] = static_cast<int>(i);
  {
    const MeshTopology topology(input.faces, input.vertex_count());
    if (!topology.is_manifold() || topology.boundary_loops().size() != 1 || topology.euler_characteristic() != 1) {
      throw Error(ErrorCode::kNotADisk, "the conformal map needs a disk (one boundary loop, Euler characteristic 1); got " +
                                            std::to_string(topology.boundary_loops().size()) + " loops, Euler characteristic " +
                                            std::to_string(topology.euler_characteristic()));
    }
  }
  ConformalReport& report = map.report;
  const DiskPreconditioning pre = precondition_disk(map.surface, map.source_vertex);
  report.split_chords = pre.split_chords;
  report.split_ears = pre.split_ears;
  report.split_obtuse_boundary = pre.split_obtuse_boundary;
  report.split_caps = pre.split_caps;
  const MeshTopology topology(map.surface.faces, map.surface.vertex_count());
  map.rim = topology.boundary_loops()[0];
  report.seconds_prepare = seconds_since(start);

  start = std::chrono::steady_clock::now();
  const IntrinsicMesh intrinsic = intrinsic_delaunay(map.surface);
  report.intrinsic_flips = intrinsic.flips;
  map.disk = linear_disk_map(map.surface, intrinsic, map.rim);
  report.method = ConformalMethod::kLinear;
  report.seconds_initial = seconds_since(start);

  if (options.method == ConformalMethod::kQiem) {
    start = std::chrono::steady_clock::now();
    try {
      // The disk is already intrinsic Delaunay; glued, only its boundary edges (now interior, with
      // equal opposite angles) can still need a flip.
      std::vector<uint8_t> on_boundary(static_cast<size_t>(map.surface.vertex_count()), 0);
      for (int v : map.rim) on_boundary[static_cast<size_t>(v)] = 1;
      const DoubleCover cover = build_double_cover(intrinsic.faces, intrinsic.lengths, on_boundary);
      std::vector<Face> faces = cover.faces;
      std::vector<CornerValues> lengths = cover.lengths;
      report.intrinsic_flips += flip_to_intrinsic_delaunay(faces, lengths);
      const SparseMatrix K = laplacian_from_cotangents(faces, corner_cotangents_from_lengths(lengths), cover.vertex_count());
      Eigen::VectorXd areas = Eigen::VectorXd::Zero(cover.vertex_count());
      for (size_t f = 0; f < faces.size(); ++f) {
        const auto& l = lengths[f];
        const double s = 0.5 * (l[0] + l[1] + l[2]);
        const double area = std::sqrt(std::max(s * (s - l[0]) * (s - l[1]) * (s - l[2]), 0.0));
        for (int32_t v : faces[f]) areas[v] += area / 3;
      }
      const FlowResult flow = spherical_flow(K, areas, cover, initial_sphere_map(map.disk, cover), options);
      report.iterations = flow.iterations;
      report.factorizations = flow.factorizations;
      report.energy = flow.energy;
      // Image area: the spherical triangles' flat areas approach 4π from below as the map refines.
      double image_area = 0;
      for (const Face& f : faces) {
        const Eigen::Vector3d a = flow.phi.row(f[0]), b = flow.phi.row(f[1]), c = flow.phi.row(f[2]);
        image_area += 0.5 * (b - a).cross(c - a).norm();
      }
      report.energy_excess = flow.energy - image_area;
      // Stereographic projection of copy 1 (southern hemisphere) from the north pole.
      std::vector<Vec2> w(map.disk.size());
      for (int i = 0; i < cover.disk_vertices; ++i) {
        const double denominator = 1.0 - flow.phi(i, 2);
        w[static_cast<size_t>(i)] = Vec2(flow.phi(i, 0), flow.phi(i, 1)) / denominator;
      }
      for (int v : map.rim) w[static_cast<size_t>(v)].normalize();  // exactly on the circle
      map.disk = std::move(w);
      report.method = ConformalMethod::kQiem;
    } catch (const Error& e) {
      if (!options.fallback) throw;
      report.fallback_reason = e.what();
    }
    report.seconds_flow = seconds_since(start);
  }

  start = std::chrono::steady_clock::now();
  double total = 0;
  for (const Face& f : map.surface.faces) {
    total += signed_area(map.disk[static_cast<size_t>(f[0])], map.disk[static_cast<size_t>(f[1])], map.disk[static_cast<size_t>(f[2])]);
  }
  if (total < 0) {
    for (Vec2& p : map.disk) p.y() = -p.y();  // w -> conj(w): orientation-preserving
    std::reverse(map.rim.begin(), map.rim.end());
  }
  report.flipped_triangles = count_flipped(map.disk, map.surface.faces);
  report.untangled_vertices = untangle(map);
  report.seconds_finish = seconds_since(start);
  return map;
}

SurfacePoint closest_surface_point(const TriangleMesh& surface, const Vec3& point) {
  SurfacePoint best;
  double best_distance = std::numeric_limits<double>::infinity();
  for (size_t f = 0; f < surface.faces.size(); ++f) {
    const Vec3& a = surface.positions[static_cast<size_t>(surface.faces[f][0])];
    const Vec3& b = surface.positions[static_cast<size_t>(surface.faces[f][1])];
    const Vec3& c = surface.positions[static_cast<size_t>(surface.faces[f][2])];
    const Vec3 bary = closest_point_barycentric(point, a, b, c);
    const double distance = (bary[0] * a + bary[1] * b + bary[2] * c - point).squaredNorm();
    if (distance < best_distance) {
      best_distance = distance;
      best = {static_cast<int>(f), bary};
    }
  }
  return best;
}

void normalize(DiskMap& map, const Vec3& centre, const Vec3& direction) {
  const SurfacePoint c = closest_surface_point(map.surface, centre), d = closest_surface_point(map.surface, direction);
  auto disk_point = [&](const SurfacePoint& s) {
    const Face& f = map.surface.faces[static_cast<size_t>(s.face)];
    return to_complex(s.bary[0] * map.disk[static_cast<size_t>(f[0])] + s.bary[1] * map.disk[static_cast<size_t>(f[1])] +
                      s.bary[2] * map.disk[static_cast<size_t>(f[2])]);
  };
  // Möbius maps are not affine, so a landmark's interpolated disk point moves slightly when the
  // map is transformed. Iterating to the fixed point (centre interpolates to 0, direction onto the
  // positive imaginary axis, in the final coordinates) makes the result independent of whatever
  // Möbius map the disk came with.
  for (int iteration = 0; iteration < 20; ++iteration) {
    const Complex cw = disk_point(c);
    if (std::abs(cw) >= 1) throw Error(ErrorCode::kInvalidArgument, "the centre landmark lies on the boundary of the face");
    const DiskMoebius m = DiskMoebius::normalizing(cw, disk_point(d));
    for (Vec2& w : map.disk) w = m(w);
    for (int v : map.rim) map.disk[static_cast<size_t>(v)].normalize();
    map.normalization = m.after(map.normalization);
    if (std::abs(m.a) < 1e-15 && std::abs(std::remainder(m.theta, 2 * kPi)) < 1e-15) break;
  }
  // In floating point a Möbius map can turn over triangles whose disk area is ~1e-18 (crowded
  // regions); the map keeps its no-flip guarantee.
  map.report.untangled_vertices += untangle(map);
}

Eigen::VectorXd conformal_factor(const DiskMap& map) {
  const auto n = static_cast<Eigen::Index>(map.surface.positions.size());
  Eigen::VectorXd surface_area = Eigen::VectorXd::Zero(n), disk_area = Eigen::VectorXd::Zero(n);
  for (const Face& f : map.surface.faces) {
    const double a3 = triangle_area(map.surface.positions[static_cast<size_t>(f[0])], map.surface.positions[static_cast<size_t>(f[1])],
                                    map.surface.positions[static_cast<size_t>(f[2])]);
    const double a2 = std::abs(signed_area(map.disk[static_cast<size_t>(f[0])], map.disk[static_cast<size_t>(f[1])], map.disk[static_cast<size_t>(f[2])]));
    for (int32_t v : f) {
      surface_area[v] += a3;
      disk_area[v] += a2;
    }
  }
  return (surface_area.array() / disk_area.array().max(1e-300)).sqrt();
}

Distortion measure_distortion(const DiskMap& map) {
  const auto& faces = map.surface.faces;
  const auto surface_angles = corner_angles(map.surface.positions, faces);
  Distortion d;
  d.checkerboard_histogram.assign(91, 0.0);
  std::vector<double> errors;
  errors.reserve(3 * faces.size());
  double area_sum = 0, mu_sum = 0, within = 0;
  for (size_t f = 0; f < faces.size(); ++f) {
    const Vec2 w[3] = {map.disk[static_cast<size_t>(faces[f][0])], map.disk[static_cast<size_t>(faces[f][1])], map.disk[static_cast<size_t>(faces[f][2])]};
    const Vec3 s[3] = {map.surface.positions[static_cast<size_t>(faces[f][0])], map.surface.positions[static_cast<size_t>(faces[f][1])],
                       map.surface.positions[static_cast<size_t>(faces[f][2])]};
    d.flipped += signed_area(w[0], w[1], w[2]) <= 0;
    for (int k = 0; k < 3; ++k) {
      const Vec2 e1 = w[(k + 1) % 3] - w[k], e2 = w[(k + 2) % 3] - w[k];
      const double disk_angle = std::atan2(std::abs(e1.x() * e2.y() - e1.y() * e2.x()), e1.dot(e2));
      errors.push_back(std::abs(disk_angle - surface_angles[f][k]) * 180 / kPi);
    }
    // Beltrami coefficient (method-notes §2.7): the surface triangle laid flat in C, then f: z -> w.
    const Vec3 u = s[1] - s[0], v = s[2] - s[0];
    const double area3 = 0.5 * u.cross(v).norm();
    if (area3 <= 0) continue;
    const double ux = u.norm();
    const Complex z1(ux, 0), z2(u.dot(v) / ux, 2 * area3 / ux);
    const Complex e1 = to_complex(w[1] - w[0]), e2 = to_complex(w[2] - w[0]);
    const Complex det = z1 * std::conj(z2) - z2 * std::conj(z1);
    const Complex fz = (e1 * std::conj(z2) - e2 * std::conj(z1)) / det;
    const Complex fzbar = (z1 * e2 - z2 * e1) / det;
    const double mu = std::abs(fzbar / fz);
    mu_sum += mu * area3;
    area_sum += area3;
    d.mu_max = std::max(d.mu_max, mu);
    // Pulled-back checkerboard: the images on the surface of the disk's u and v directions.
    Eigen::Matrix2d W;
    W << (w[1] - w[0]).x(), (w[2] - w[0]).x(), (w[1] - w[0]).y(), (w[2] - w[0]).y();
    if (std::abs(W.determinant()) < 1e-300) continue;
    Eigen::Matrix<double, 3, 2> S;
    S << u, v;
    const Eigen::Matrix<double, 3, 2> J = S * W.inverse();
    const double angle = std::atan2(J.col(0).cross(J.col(1)).norm(), J.col(0).dot(J.col(1))) * 180 / kPi;
    const int bin = std::clamp(static_cast<int>(std::lround(angle - 45)), 0, 90);
    d.checkerboard_histogram[static_cast<size_t>(bin)] += area3;
    if (std::abs(angle - 90) <= 1) within += area3;
  }
  if (area_sum > 0) {
    d.mu_mean = mu_sum / area_sum;
    d.checkerboard_within_1_degree = within / area_sum;
    for (double& h : d.checkerboard_histogram) h /= area_sum;
  }
  if (!errors.empty()) {
    double sum = 0;
    for (double e : errors) sum += e;
    d.mean_degrees = sum / static_cast<double>(errors.size());
    std::nth_element(errors.begin(), errors.begin() + static_cast<long>(errors.size() * 95 / 100), errors.end());
    d.p95_degrees = errors[errors.size() * 95 / 100];
    d.max_degrees = *std::max_element(errors.begin(), errors.end());
  }
  return d;
}

InverseDiskMap::InverseDiskMap(const DiskMap& map) : map_(map), locator_(map.disk, map.surface.faces) {
  const MeshTopology topology(map.surface.faces, map.surface.vertex_count());
  const size_t m = map.rim.size();
  std::vector<std::pair<double, size_t>> order;
  for (size_t k = 0; k < m; ++k) {
    const Vec2& p = map.disk[static_cast<size_t>(map.rim[k])];
    double a = std::atan2(p.y(), p.x());
    if (a < 0) a += 2 * kPi;
    order.push_back({a, k});
  }
  std::sort(order.begin(), order.end());
  for (size_t i = 0; i < m; ++i) {
    rim_angle_.push_back(order[i].first);
    rim_order_.push_back(map.rim[order[i].second]);
  }
  // The face holding each rim edge between angle-consecutive rim vertices.
  std::unordered_map<uint64_t, int> boundary_face;
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (!topology.is_boundary_edge(e)) continue;
    const auto [a, b] = topology.edge(e);
    boundary_face[(uint64_t{static_cast<uint32_t>(a)} << 32) | static_cast<uint32_t>(b)] = topology.edge_faces(e)[0];
  }
  for (size_t i = 0; i < m; ++i) {
    const auto a = static_cast<uint32_t>(std::min(rim_order_[i], rim_order_[(i + 1) % m]));
    const auto b = static_cast<uint32_t>(std::max(rim_order_[i], rim_order_[(i + 1) % m]));
    const auto it = boundary_face.find((uint64_t{a} << 32) | b);
    rim_edge_face_.push_back(it == boundary_face.end() ? -1 : it->second);
  }
}

std::optional<SurfacePoint> InverseDiskMap::locate(const Vec2& w) const {
  const double r = w.norm();
  if (!(r <= 1 + 1e-9)) return std::nullopt;
  if (auto hit = locator_.locate(w, 1e-9)) return hit;
  // Between a rim chord and the circle: the point on the rim edge at the same angle.
  double theta = std::atan2(w.y(), w.x());
  if (theta < 0) theta += 2 * kPi;
  const size_t m = rim_angle_.size();
  size_t i = static_cast<size_t>(std::upper_bound(rim_angle_.begin(), rim_angle_.end(), theta) - rim_angle_.begin());
  i = (i + m - 1) % m;
  const size_t j = (i + 1) % m;
  double span = rim_angle_[j] - rim_angle_[i];
  double offset = theta - rim_angle_[i];
  if (span <= 0) span += 2 * kPi;
  if (offset < 0) offset += 2 * kPi;
  const double t = std::clamp(offset / span, 0.0, 1.0);
  const int face = rim_edge_face_[i];
  if (face < 0) return std::nullopt;
  SurfacePoint p{face, Vec3::Zero()};
  const Face& f = map_.surface.faces[static_cast<size_t>(face)];
  for (int k = 0; k < 3; ++k) {
    if (f[k] == rim_order_[i]) p.bary[k] = 1 - t;
    if (f[k] == rim_order_[j]) p.bary[k] = t;
  }
  return p;
}

Vec3 InverseDiskMap::position(const SurfacePoint& p) const {
  const Face& f = map_.surface.faces[static_cast<size_t>(p.face)];
  return p.bary[0] * map_.surface.positions[static_cast<size_t>(f[0])] + p.bary[1] * map_.surface.positions[static_cast<size_t>(f[1])] +
         p.bary[2] * map_.surface.positions[static_cast<size_t>(f[2])];
}

Vec2 InverseDiskMap::texture_uv(const SurfacePoint& p) const {
  const Face& t = map_.surface.uv_faces[static_cast<size_t>(p.face)];
  return p.bary[0] * map_.surface.uvs[static_cast<size_t>(t[0])] + p.bary[1] * map_.surface.uvs[static_cast<size_t>(t[1])] +
         p.bary[2] * map_.surface.uvs[static_cast<size_t>(t[2])];
}

}  // namespace facemorph
