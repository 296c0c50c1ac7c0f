#include "codec/decoder/sequence/hole_cut.hpp"

#include "codec/core/geometry/mesh.hpp"
#include "format/error.hpp"

#include <cmath>
#include <unordered_map>

namespace facemorph {

TriangleMesh cut_holes(const DiskGrid& grid, const std::vector<Vec3>& positions, const std::vector<double>& level) {
  const size_t n = grid.nodes.size();
  if (positions.size() != n || level.size() != n) {
    throw Error(ErrorCode::kInvalidArgument, "cut_holes: " + std::to_string(positions.size()) + " positions and " +
                                                 std::to_string(level.size()) + " level values for a grid of " + std::to_string(n) +
                                                 " nodes");
  }
  for (size_t v = 0; v < n; ++v) {
    if (!std::isfinite(level[v]) || !positions[v].allFinite())
      throw Error(ErrorCode::kInvalidArgument, "cut_holes: non-finite value at node " + std::to_string(v));
  }
  TriangleMesh mesh;
  std::vector<int32_t> output_vertex(n, -1);  // node -> its vertex in the result, once used
  auto vertex_of_node = [&](int32_t v) {
    if (output_vertex[static_cast<size_t>(v)] < 0) {
      output_vertex[static_cast<size_t>(v)] = mesh.vertex_count();
      mesh.positions.push_back(positions[static_cast<size_t>(v)]);
      mesh.uvs.push_back(0.5 * (grid.nodes[static_cast<size_t>(v)] + Vec2(1, 1)));
    }
    return output_vertex[static_cast<size_t>(v)];
  };
  std::unordered_map<uint64_t, int32_t> crossing;  // undirected edge -> its zero-level vertex
  auto vertex_on_edge = [&](int32_t a, int32_t b) {
    const uint64_t key = undirected_edge_key(a, b);
    if (const auto it = crossing.find(key); it != crossing.end()) return it->second;
    // Interpolate from the lower index so both triangles of the edge compute the same point.
    const int32_t lo = std::min(a, b), hi = std::max(a, b);
    const double s = level[static_cast<size_t>(lo)] / (level[static_cast<size_t>(lo)] - level[static_cast<size_t>(hi)]);
    if (s <= 0) return vertex_of_node(lo);  // a node exactly on the zero level is the crossing itself
    if (s >= 1) return vertex_of_node(hi);
    const auto id = static_cast<int32_t>(mesh.vertex_count());
    mesh.positions.push_back((1 - s) * positions[static_cast<size_t>(lo)] + s * positions[static_cast<size_t>(hi)]);
    mesh.uvs.push_back(0.5 * ((1 - s) * grid.nodes[static_cast<size_t>(lo)] + s * grid.nodes[static_cast<size_t>(hi)] + Vec2(1, 1)));
    crossing.emplace(key, id);
    return id;
  };
  auto keeps = [&](int32_t v) { return level[static_cast<size_t>(v)] >= 0; };  // outside every hole
  auto add = [&](int32_t a, int32_t b, int32_t c) {
    if (a != b && b != c && c != a) mesh.faces.push_back({a, b, c});  // crossings on a node collapse a corner
  };
  for (const Face& f : grid.faces) {
    const int count = keeps(f[0]) + keeps(f[1]) + keeps(f[2]);
    if (count == 0) continue;
    if (count == 3) {
      const int32_t v0 = vertex_of_node(f[0]), v1 = vertex_of_node(f[1]), v2 = vertex_of_node(f[2]);  // in order: deterministic numbering
      add(v0, v1, v2);
      continue;
    }
    // Rotate so that f[k] is the odd one out: the single kept corner (count 1) or the single
    // dropped one (count 2); the winding is kept.
    const bool odd_is_kept = count == 1;
    int k = 0;
    while (keeps(f[static_cast<size_t>(k)]) != odd_is_kept) ++k;
    const int32_t a = f[static_cast<size_t>(k)], b = f[static_cast<size_t>((k + 1) % 3)], c = f[static_cast<size_t>((k + 2) % 3)];
    const int32_t ab = vertex_on_edge(a, b), ca = vertex_on_edge(c, a);
    if (count == 1) {
      const int32_t va = vertex_of_node(a);
      add(va, ab, ca);
    } else {  // a is dropped: the quad b, c, ca, ab remains
      const int32_t vb = vertex_of_node(b), vc = vertex_of_node(c);
      add(ab, vb, vc);
      add(ab, vc, ca);
    }
  }
  mesh.uv_faces = mesh.faces;
  return mesh;
}

}  // namespace facemorph
