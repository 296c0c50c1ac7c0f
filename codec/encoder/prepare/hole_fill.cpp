// Hole filling after Liepa (2003), "Filling holes in meshes": a minimal-area triangulation of the
// hole's boundary polygon, refined until its edge lengths match the surrounding mesh, relaxed by
// Delaunay edge flips, then faired as a membrane (harmonic), which spans the rim of the hole
// instead of bulging into it. The membrane is what keeps an open mouth from becoming a deep
// cavity whose conformal image would be crowded beyond any grid (spec/method.md §2).
#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <unordered_map>
#include <unordered_set>

namespace facemorph {
namespace {

constexpr int kMaxLoop = 3000;  // the O(n³) triangulation takes about a second at this size

// The fill under construction, in local indices: 0..n-1 are the loop vertices in polygon order
// (the loop reversed, so fill faces orient like the mesh), n.. are new vertices.
class Fill {
 public:
  Fill(const TriangleMesh& mesh, const std::vector<int>& loop, const std::vector<double>& sigma, const std::vector<Vec2>* loop_uvs)
      : n_(static_cast<int>(loop.size())), has_uv_(loop_uvs != nullptr) {
    for (int i = 0; i < n_; ++i) {
      const auto k = static_cast<size_t>(n_ - 1 - i);
      global_.push_back(loop[k]);
      p_.push_back(mesh.positions[static_cast<size_t>(loop[k])]);
      sigma_.push_back(sigma[k]);
      uv_.push_back(has_uv_ ? (*loop_uvs)[k] : Vec2::Zero());
    }
    // Existing mesh edges between two loop vertices: the fill must not add them again.
    std::unordered_map<int, int> local;
    for (int i = 0; i < n_; ++i) local[global_[static_cast<size_t>(i)]] = i;
    for (const Face& f : mesh.faces) {
      for (int k = 0; k < 3; ++k) {
        auto a = local.find(f[k]), b = local.find(f[(k + 1) % 3]);
        if (a != local.end() && b != local.end()) forbidden_.insert(undirected_edge_key(a->second, b->second));
      }
    }
    // The side the fill faces point to: the area-weighted normal of the surface around the hole
    // (faces within 1.5x the hole's radius). The loop's own Newell normal is ill-defined for
    // slit-shaped holes such as a closed mouth.
    Vec3 centre = Vec3::Zero();
    for (const Vec3& p : p_) centre += p / static_cast<double>(n_);
    double radius = 0;
    for (const Vec3& p : p_) radius = std::max(radius, (p - centre).norm());
    reference_normal_ = Vec3::Zero();
    for (const Face& f : mesh.faces) {
      const Vec3 &a = mesh.positions[static_cast<size_t>(f[0])], &b = mesh.positions[static_cast<size_t>(f[1])],
                 &c = mesh.positions[static_cast<size_t>(f[2])];
      if (((a + b + c) / 3.0 - centre).norm() < 1.5 * radius) reference_normal_ += 0.5 * (b - a).cross(c - a);
    }
    if (reference_normal_.norm() > 0) reference_normal_.normalize();
  }

  void triangulate_minimal_area() {
    const auto n = static_cast<size_t>(n_);
    const double inf = std::numeric_limits<double>::infinity();
    double scale = 0;
    for (int i = 0; i < n_; ++i) scale += (p_[static_cast<size_t>(i)] - p_[static_cast<size_t>((i + 1) % n_)]).norm();
    const double fold_penalty = scale * scale;  // more than any honest triangle's area
    std::vector<double> cost(n * n, 0.0);
    std::vector<int> split(n * n, -1);
    auto chord_ok = [&](size_t i, size_t j) {
      if (j == i + 1 || (i == 0 && j == n - 1)) return true;  // a loop edge
      return !forbidden_.contains(undirected_edge_key(static_cast<int>(i), static_cast<int>(j)));
    };
    for (size_t span = 2; span < n; ++span) {
      for (size_t i = 0; i + span < n; ++i) {
        const size_t j = i + span;
        double best = inf;
        int best_k = -1;
        if (chord_ok(i, j)) {
          for (size_t k = i + 1; k < j; ++k) {
            const double sub = cost[i * n + k] + cost[k * n + j];
            if (!(sub < best)) continue;
            const Vec3 normal = (p_[k] - p_[i]).cross(p_[j] - p_[i]);
            const double area = 0.5 * normal.norm();
            const double facing = area > 0 ? normal.dot(reference_normal_) / (2 * area) : 0.0;
            const double c = sub + area * (1 + 4 * std::max(0.0, -facing)) + (facing < 0 ? fold_penalty : 0.0);
            if (c < best) {
              best = c;
              best_k = static_cast<int>(k);
            }
          }
        }
        cost[i * n + j] = best;
        split[i * n + j] = best_k;
      }
    }
    if (split[n - 1] < 0) {
      throw Error(ErrorCode::kNotADisk,
                  "a hole of " + std::to_string(n) + " boundary vertices cannot be triangulated without duplicating an existing edge");
    }
    std::vector<std::pair<size_t, size_t>> stack = {{0, n - 1}};
    while (!stack.empty()) {
      const auto [i, j] = stack.back();
      stack.pop_back();
      if (j < i + 2) continue;
      const auto k = static_cast<size_t>(split[i * n + j]);
      faces_.push_back({static_cast<int32_t>(i), static_cast<int32_t>(k), static_cast<int32_t>(j)});
      stack.push_back({i, k});
      stack.push_back({k, j});
    }
  }

  // Liepa's refinement: split a triangle at its centroid while the centroid is farther than
  // local edge length / sqrt(2) from all three corners; relax by flips after each pass.
  void refine() {
    for (int pass = 0; pass < 64; ++pass) {
      bool split = false;
      const size_t count = faces_.size();
      for (size_t f = 0; f < count; ++f) {
        const Face face = faces_[f];
        Vec3 c = Vec3::Zero();
        double sc = 0;
        Vec2 uc = Vec2::Zero();
        for (int32_t v : face) {
          c += p_[static_cast<size_t>(v)] / 3.0;
          sc += sigma_[static_cast<size_t>(v)] / 3.0;
          uc += uv_[static_cast<size_t>(v)] / 3.0;
        }
        bool big = true;
        for (int32_t v : face) {
          const double d = std::sqrt(2.0) * (c - p_[static_cast<size_t>(v)]).norm();
          big = big && d > sc && d > sigma_[static_cast<size_t>(v)];
        }
        if (!big) continue;
        const auto v = static_cast<int32_t>(p_.size());
        p_.push_back(c);
        sigma_.push_back(sc);
        uv_.push_back(uc);
        faces_[f] = {face[0], face[1], v};
        faces_.push_back({face[1], face[2], v});
        faces_.push_back({face[2], face[0], v});
        split = true;
      }
      relax();
      if (!split) return;
    }
  }

  // Flips interior fill edges whose opposite angles sum past π (3D Delaunay criterion).
  void relax() {
    for (int round = 0; round < 200; ++round) {
      std::unordered_map<uint64_t, std::pair<int, int>> owner;  // edge -> (face, corner opposite)
      std::unordered_map<uint64_t, std::pair<int, int>> other;
      for (size_t f = 0; f < faces_.size(); ++f) {
        for (int k = 0; k < 3; ++k) {
          const uint64_t key = undirected_edge_key(faces_[f][(k + 1) % 3], faces_[f][(k + 2) % 3]);
          auto [it, inserted] = owner.try_emplace(key, static_cast<int>(f), k);
          if (!inserted) other[key] = {static_cast<int>(f), k};
        }
      }
      std::vector<uint8_t> touched(faces_.size(), 0);
      int flips = 0;
      for (const auto& [key, second] : other) {
        const auto first = owner[key];
        if (touched[static_cast<size_t>(first.first)] || touched[static_cast<size_t>(second.first)]) continue;
        Face& f1 = faces_[static_cast<size_t>(first.first)];
        Face& f2 = faces_[static_cast<size_t>(second.first)];
        const int32_t c = f1[first.second], d = f2[second.second];
        const int32_t a = f1[(first.second + 1) % 3], b = f1[(first.second + 2) % 3];
        if (angle_at(c, a, b) + angle_at(d, a, b) <= std::numbers::pi + 1e-9) continue;
        if (c == d || forbidden_.contains(undirected_edge_key(c, d)) || owner.contains(undirected_edge_key(c, d))) continue;
        // f1 = (a, b, c) and f2 = (b, a, d) become (a, d, c) and (d, b, c).
        f1 = {a, d, c};
        f2 = {d, b, c};
        touched[static_cast<size_t>(first.first)] = touched[static_cast<size_t>(second.first)] = 1;
        ++flips;
      }
      if (flips == 0) return;
    }
  }

  // Membrane fairing: new vertices solve a Laplace equation with the loop fixed. Uniform weights
  // first (a Tutte embedding of the fill, robust), then cotangent weights clamped positive.
  void fair() {
    const int total = static_cast<int>(p_.size());
    const int unknowns = total - n_;
    if (unknowns <= 0) return;
    for (int pass = 0; pass < 3; ++pass) {
      const bool uniform = pass == 0;
      const auto cot = corner_cotangents(p_, faces_);
      std::vector<Eigen::Triplet<double>> triplets;
      Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(unknowns, 5);
      auto add = [&](int i, int j, double w) {
        if (i < n_) return;
        triplets.emplace_back(i - n_, i - n_, w);
        if (j >= n_) {
          triplets.emplace_back(i - n_, j - n_, -w);
        } else {
          rhs.row(i - n_).head<3>() += w * p_[static_cast<size_t>(j)];
          rhs.row(i - n_).tail<2>() += w * uv_[static_cast<size_t>(j)];
        }
      };
      for (size_t f = 0; f < faces_.size(); ++f) {
        for (int k = 0; k < 3; ++k) {
          const int i = faces_[f][(k + 1) % 3], j = faces_[f][(k + 2) % 3];
          const double w = uniform ? 0.5 : std::max(0.5 * cot[f][k], 0.05);
          add(i, j, w);
          add(j, i, w);
        }
      }
      SparseMatrix A(unknowns, unknowns);
      A.setFromTriplets(triplets.begin(), triplets.end());
      Eigen::SimplicialLDLT<SparseMatrix> solver(A);
      if (solver.info() != Eigen::Success) throw Error(ErrorCode::kNumerical, "hole fairing: singular system");
      const Eigen::MatrixXd x = solver.solve(rhs);
      for (int i = 0; i < unknowns; ++i) {
        p_[static_cast<size_t>(n_ + i)] = x.row(i).head<3>().transpose();
        uv_[static_cast<size_t>(n_ + i)] = x.row(i).tail<2>().transpose();
      }
      relax();
    }
  }

  HoleFill result(int mesh_vertex_count) const {
    HoleFill fill;
    auto global = [&](int32_t v) { return v < n_ ? global_[static_cast<size_t>(v)] : static_cast<int32_t>(mesh_vertex_count + v - n_); };
    for (const Face& f : faces_) fill.faces.push_back({global(f[0]), global(f[1]), global(f[2])});
    fill.positions.assign(p_.begin() + n_, p_.end());
    if (has_uv_) fill.uvs.assign(uv_.begin() + n_, uv_.end());
    // Smallest angle the fill chose: a loop vertex with a single fill corner has the hole's own
    // interior angle there, which no triangulation can widen, so it does not count.
    std::vector<int> fill_corners(p_.size(), 0);
    for (const Face& f : faces_) {
      for (int32_t v : f) ++fill_corners[static_cast<size_t>(v)];
    }
    const auto angles = corner_angles(p_, faces_);
    double min_angle = std::numbers::pi, forced = std::numbers::pi;
    for (size_t f = 0; f < faces_.size(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const auto v = static_cast<size_t>(faces_[f][k]);
        double& target = (static_cast<int>(v) < n_ && fill_corners[v] == 1) ? forced : min_angle;
        target = std::min(target, angles[f][k]);
      }
    }
    fill.min_angle_degrees = min_angle * 180 / std::numbers::pi;
    fill.sharpest_hole_corner_degrees = forced * 180 / std::numbers::pi;
    // Folded back: turned more than 120 degrees from the surrounding surface (a grazing strip in a
    // slit-shaped hole may tilt slightly past 90 without folding).
    for (const Vec3& normal : face_normals(p_, faces_)) fill.folded_faces += normal.dot(reference_normal_) < -0.5;
    return fill;
  }

 private:
  double angle_at(int32_t apex, int32_t a, int32_t b) const {
    const Vec3 u = p_[static_cast<size_t>(a)] - p_[static_cast<size_t>(apex)];
    const Vec3 v = p_[static_cast<size_t>(b)] - p_[static_cast<size_t>(apex)];
    return angle_between(u, v);
  }

  int n_;
  bool has_uv_;
  std::vector<int32_t> global_;
  std::vector<Vec3> p_;
  std::vector<double> sigma_;
  std::vector<Vec2> uv_;
  std::vector<Face> faces_;
  std::unordered_set<uint64_t> forbidden_;
  Vec3 reference_normal_;
};

// A fill vertex's colour: the rim's, each rim vertex weighted by its inverse squared distance, so
// an eye's fill shades from lid to lid instead of taking one flat average. (Decoding cuts an open
// eye back out; with --keep-holes-filled this is the colour shown.)
std::vector<Vec3> rim_colours(const TriangleMesh& mesh, const std::vector<int>& loop, const std::vector<Vec3>& points) {
  std::vector<Vec3> colours;
  colours.reserve(points.size());
  for (const Vec3& p : points) {
    Vec3 sum = Vec3::Zero();
    double total = 0;
    for (int v : loop) {
      const double w = 1 / std::max((mesh.positions[static_cast<size_t>(v)] - p).squaredNorm(), 1e-300);
      sum += w * mesh.colours[static_cast<size_t>(v)];
      total += w;
    }
    colours.push_back(sum / total);
  }
  return colours;
}

}  // namespace

HoleFill fill_hole(const TriangleMesh& mesh, const std::vector<int>& loop, const std::vector<double>& target_edge_length,
                   const std::vector<Vec2>* loop_uvs) {
  if (loop.size() < 3) throw Error(ErrorCode::kNotADisk, "a hole with fewer than 3 boundary vertices");
  if (loop.size() > static_cast<size_t>(kMaxLoop)) {
    throw Error(ErrorCode::kNotADisk, "a hole of " + std::to_string(loop.size()) + " boundary vertices is too large to fill (at most " +
                                          std::to_string(kMaxLoop) + ")");
  }
  Fill fill(mesh, loop, target_edge_length, loop_uvs);
  fill.triangulate_minimal_area();
  fill.refine();
  fill.fair();
  HoleFill result = fill.result(mesh.vertex_count());
  if (mesh.has_colours()) result.colours = rim_colours(mesh, loop, result.positions);
  return result;
}

}  // namespace facemorph
