// The inverse disk map: disk point -> surface point, exact on the rim.
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <unordered_map>
#include <utility>
#include <vector>

namespace facemorph {

InverseDiskMap::InverseDiskMap(const DiskMap& map) : map_(map), locator_(map.disk, map.surface.faces) {
  const MeshTopology topology(map.surface.faces, map.surface.vertex_count());
  const size_t m = map.rim.size();
  std::vector<std::pair<double, size_t>> order;
  for (size_t k = 0; k < m; ++k) {
    const Vec2& p = map.disk[static_cast<size_t>(map.rim[k])];
    double a = std::atan2(p.y(), p.x());
    if (a < 0) a += 2 * std::numbers::pi;
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
    boundary_face[undirected_edge_key(a, b)] = topology.edge_faces(e)[0];
  }
  for (size_t i = 0; i < m; ++i) {
    const auto it = boundary_face.find(undirected_edge_key(rim_order_[i], rim_order_[(i + 1) % m]));
    rim_edge_face_.push_back(it == boundary_face.end() ? -1 : it->second);
  }
}

std::optional<SurfacePoint> InverseDiskMap::locate(const Vec2& w) const {
  const double r = w.norm();
  if (!(r <= 1 + 1e-9)) return std::nullopt;
  if (auto hit = locator_.locate(w, 1e-9)) return hit;
  // Between a rim chord and the circle: the point on the rim edge at the same angle.
  double theta = std::atan2(w.y(), w.x());
  if (theta < 0) theta += 2 * std::numbers::pi;
  const size_t m = rim_angle_.size();
  size_t i = static_cast<size_t>(std::upper_bound(rim_angle_.begin(), rim_angle_.end(), theta) - rim_angle_.begin());
  i = (i + m - 1) % m;
  const size_t j = (i + 1) % m;
  double span = rim_angle_[j] - rim_angle_[i];
  double offset = theta - rim_angle_[i];
  if (span <= 0) span += 2 * std::numbers::pi;
  if (offset < 0) offset += 2 * std::numbers::pi;
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

Vec3 InverseDiskMap::colour(const SurfacePoint& p) const {
  const Face& f = map_.surface.faces[static_cast<size_t>(p.face)];
  return p.bary[0] * map_.surface.colours[static_cast<size_t>(f[0])] + p.bary[1] * map_.surface.colours[static_cast<size_t>(f[1])] +
         p.bary[2] * map_.surface.colours[static_cast<size_t>(f[2])];
}

}  // namespace facemorph
