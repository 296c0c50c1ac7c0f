// Operators on the shared disk grid, shared by the encoder (fields) and the decoder (reconstruction).
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/elementary.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "format/error.hpp"

#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

namespace facemorph {

GridGeometry::GridGeometry(DiskGrid grid) : grid_(std::move(grid)) {
  std::vector<Vec3> flat;
  flat.reserve(grid_.nodes.size());
  for (const Vec2& w : grid_.nodes) flat.emplace_back(w.x(), w.y(), 0);
  K_ = cotangent_laplacian(flat, grid_.faces);
  mass_ = mixed_voronoi_areas(flat, grid_.faces);

  neighbours_.assign(static_cast<size_t>(grid_.interior_count), {-1, -1, -1, -1});
  for (int v = 0; v < grid_.interior_count; ++v) {
    if (grid_.nodes[static_cast<size_t>(v)].norm() > 1 - 2 * grid_.h) band_nodes_.push_back(v);
    const auto [i, j] = grid_.cell[static_cast<size_t>(v)];
    neighbours_[static_cast<size_t>(v)] = {grid_.node(i + 1, j), grid_.node(i - 1, j), grid_.node(i, j + 1), grid_.node(i, j - 1)};
  }
  faces_of_.resize(grid_.nodes.size());
  for (size_t f = 0; f < grid_.faces.size(); ++f) {
    for (int32_t v : grid_.faces[f]) faces_of_[static_cast<size_t>(v)].push_back(static_cast<int32_t>(f));
  }
  build_jacobian_stencils();
}

// Near the rim S_u and S_v are the disk-area-weighted Jacobian of the faces around the node,
// Σ_f area_f · D_f W_f⁻¹ with D_f = [S_b − S_a, S_c − S_a] and W_f the same of the disk points: linear
// in S with coefficients that depend on G alone. Worked out once here; frames() was a quarter of a
// decoder step when it inverted every face's W in every step.
void GridGeometry::build_jacobian_stencils() {
  stencil_start_.assign(static_cast<size_t>(grid_.interior_count) + 1, 0);
  for (int v = 0; v < grid_.interior_count; ++v) {
    stencil_start_[static_cast<size_t>(v) + 1] = stencil_start_[static_cast<size_t>(v)];
    const auto& nb = neighbours_[static_cast<size_t>(v)];
    if (nb[0] >= 0 && nb[1] >= 0 && nb[2] >= 0 && nb[3] >= 0) continue;  // central differences
    std::vector<StencilEntry> entries;
    auto add = [&](int32_t node, double cu, double cv) {
      for (StencilEntry& e : entries) {
        if (e.node == node) {
          e.cu += cu;
          e.cv += cv;
          return;
        }
      }
      entries.push_back({node, cu, cv});
    };
    for (int32_t f : faces_of_[static_cast<size_t>(v)]) {
      const Face& t = grid_.faces[static_cast<size_t>(f)];
      const Vec2 &a = grid_.nodes[static_cast<size_t>(t[0])], &b = grid_.nodes[static_cast<size_t>(t[1])],
                 &c = grid_.nodes[static_cast<size_t>(t[2])];
      Eigen::Matrix2d W;
      W << b.x() - a.x(), c.x() - a.x(), b.y() - a.y(), c.y() - a.y();
      const double area = 0.5 * std::abs(W.determinant());
      const Eigen::Matrix2d Wi = W.inverse();
      // J.col(k) = (S_b − S_a) Wi(0, k) + (S_c − S_a) Wi(1, k).
      add(t[1], area * Wi(0, 0), area * Wi(0, 1));
      add(t[2], area * Wi(1, 0), area * Wi(1, 1));
      add(t[0], -area * (Wi(0, 0) + Wi(1, 0)), -area * (Wi(0, 1) + Wi(1, 1)));
    }
    stencil_.insert(stencil_.end(), entries.begin(), entries.end());
    stencil_start_[static_cast<size_t>(v) + 1] = static_cast<int32_t>(stencil_.size());
  }
}

std::vector<Vec3> GridGeometry::laplacian(const std::vector<Vec3>& positions) const {
  const auto count = static_cast<size_t>(grid_.interior_count);
  std::vector<Vec3> out(count, Vec3::Zero());
  for (int c = 0; c < K_.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(K_, c); it; ++it) {
      const auto r = static_cast<size_t>(it.row());
      if (r < count) out[r] -= it.value() * positions[static_cast<size_t>(c)];
    }
  }
  for (size_t i = 0; i < count; ++i) out[i] /= mass_[static_cast<Eigen::Index>(i)];
  return out;
}

std::vector<double> GridGeometry::conformal_factor_squared(const std::vector<Vec3>& positions) const {
  std::vector<double> out(static_cast<size_t>(grid_.interior_count));
  for (size_t v = 0; v < out.size(); ++v) {
    double surface = 0, disk = 0;
    for (int32_t f : faces_of_[v]) {
      const Face& t = grid_.faces[static_cast<size_t>(f)];
      surface +=
          triangle_area(positions[static_cast<size_t>(t[0])], positions[static_cast<size_t>(t[1])], positions[static_cast<size_t>(t[2])]);
      const Vec2 &a = grid_.nodes[static_cast<size_t>(t[0])], &b = grid_.nodes[static_cast<size_t>(t[1])],
                 &c = grid_.nodes[static_cast<size_t>(t[2])];
      disk += std::abs(signed_area(a, b, c));
    }
    out[v] = surface / disk;
  }
  return out;
}

void GridGeometry::frames(const std::vector<Vec3>& S, std::vector<Vec3>& tu, std::vector<Vec3>& tv, std::vector<Vec3>& n) const {
  const auto count = static_cast<size_t>(grid_.interior_count);
  tu.resize(count);
  tv.resize(count);
  n.resize(count);
  for (size_t v = 0; v < count; ++v) frame(v, S.data(), tu[v], tv[v], n[v]);
}

std::vector<std::array<Vec3, 3>> GridGeometry::boundary_frames(const std::vector<Vec3>& rim, const std::vector<int32_t>& nodes) const {
  const int count = grid_.rim_count;
  Vec3 centroid = Vec3::Zero();
  for (const Vec3& p : rim) centroid += p / static_cast<double>(rim.size());
  std::vector<std::array<Vec3, 3>> out(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i) {
    const Vec2& w = grid_.nodes[static_cast<size_t>(nodes[i])];
    double angle = std::atan2(w.y(), w.x());
    if (angle < 0) angle += 2 * std::numbers::pi;
    const double position = angle / (2 * std::numbers::pi) * count;  // rim samples are at k 2π / count
    const int k = static_cast<int>(std::floor(position)) % count;
    const double f = position - std::floor(position);
    const Vec3& a = rim[static_cast<size_t>(k)];
    const Vec3& c = rim[static_cast<size_t>((k + 1) % count)];
    const Vec3 tangent = (c - a).normalized();
    Vec3 inward = centroid - ((1 - f) * a + f * c);
    inward = (inward - inward.dot(tangent) * tangent).normalized();
    out[i] = {tangent, inward, tangent.cross(inward)};
  }
  return out;
}

TriangleMesh grid_mesh(const DiskGrid& grid, const std::vector<Vec3>& positions) {
  TriangleMesh mesh;
  mesh.positions = positions;
  mesh.faces = grid.faces;
  for (const Vec2& w : grid.nodes) mesh.uvs.push_back(0.5 * (w + Vec2(1, 1)));
  mesh.uv_faces = grid.faces;
  return mesh;
}

std::shared_ptr<const GridGeometry> shared_grid_geometry(int n) {
  static std::mutex mutex;
  static std::map<int, std::weak_ptr<const GridGeometry>> alive;
  {
    std::lock_guard lock(mutex);
    const auto at = alive.find(n);
    if (at != alive.end())
      if (std::shared_ptr<const GridGeometry> held = at->second.lock()) return held;
  }
  // Made outside the lock (a grid of N = 257 takes tens of milliseconds): two threads asking at
  // once may each make one, equal to the bit, and the later one is the one handed on.
  auto made = std::make_shared<const GridGeometry>(make_disk_grid(n));
  std::lock_guard lock(mutex);
  alive[n] = made;
  return made;
}

}  // namespace facemorph
