// The inverse disk map: disk point -> surface point, exact on the rim.
#include "codec/encoder/conformal/conformal.hpp"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <numbers>
#include <unordered_map>
#include <utility>
#include <vector>

namespace facemorph {

InverseDiskMap::InverseDiskMap(const DiskMap& map) : map_(map), locator_(map.disk, map.surface.faces) {
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
  // The face holding each rim edge between angle-consecutive rim vertices: the edge's only face
  // (an edge of two faces is a chord, not a rim edge; a pair with no edge has none). Only these m
  // edges are looked up, in one pass over the faces, rather than building the surface's topology:
  // a stage that samples a frame builds this map again (spec/method.md §3.3).
  std::vector<uint8_t> on_rim(map.surface.positions.size(), 0);
  for (int v : map.rim) on_rim[static_cast<size_t>(v)] = 1;
  struct EdgeFaces {
    int count = 0;
    int face = -1;
  };
  std::unordered_map<uint64_t, EdgeFaces> rim_edges;
  for (size_t i = 0; i < m; ++i) rim_edges.emplace(undirected_edge_key(rim_order_[i], rim_order_[(i + 1) % m]), EdgeFaces{});
  const std::vector<Face>& faces = map.surface.faces;
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int32_t a = faces[f][static_cast<size_t>(k)], b = faces[f][static_cast<size_t>((k + 1) % 3)];
      if (!on_rim[static_cast<size_t>(a)] || !on_rim[static_cast<size_t>(b)]) continue;
      const auto it = rim_edges.find(undirected_edge_key(a, b));
      if (it == rim_edges.end()) continue;
      ++it->second.count;
      it->second.face = static_cast<int>(f);
    }
  }
  for (size_t i = 0; i < m; ++i) {
    const EdgeFaces& edge = rim_edges.at(undirected_edge_key(rim_order_[i], rim_order_[(i + 1) % m]));
    rim_edge_face_.push_back(edge.count == 1 ? edge.face : -1);
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
