#include "codec/meshkit/mesh/topology.hpp"

#include <algorithm>
#include <numeric>

namespace facemorph {

DisjointSets::DisjointSets(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), size_t{0}); }

size_t DisjointSets::find(size_t x) {
  while (parent_[x] != x) {
    parent_[x] = parent_[parent_[x]];
    x = parent_[x];
  }
  return x;
}

bool DisjointSets::unite(size_t a, size_t b) {
  a = find(a);
  b = find(b);
  if (a == b) return false;
  parent_[std::max(a, b)] = std::min(a, b);
  return true;
}

std::span<const int32_t> MeshTopology::edge_faces(int e) const {
  const auto begin = static_cast<size_t>(edge_face_offsets_[static_cast<size_t>(e)]);
  const auto end = static_cast<size_t>(edge_face_offsets_[static_cast<size_t>(e) + 1]);
  return std::span<const int32_t>(edge_face_list_).subspan(begin, end - begin);
}

const MeshTopology& TopologyCache::of(std::span<const Face> faces, int vertex_count) {
  if (topology_ && topology_->vertex_count() == vertex_count && std::equal(faces.begin(), faces.end(), faces_.begin(), faces_.end()))
    return *topology_;
  topology_.emplace(faces, vertex_count);
  faces_.assign(faces.begin(), faces.end());
  ++builds_;
  return *topology_;
}

MeshTopology::MeshTopology(std::span<const Face> faces, int vertex_count) : vertex_count_(vertex_count) {
  const size_t face_total = faces.size();
  face_edges_.assign(face_total, {-1, -1, -1});

  // Half-edges sorted by their undirected key group into edges without a hash map.
  struct HalfEdge {
    uint64_t key;
    int32_t face;
    int8_t corner;
  };
  // Ordered by (key, face): counted into buckets by the key's lower vertex (in face order, as they
  // are made), then each bucket, a vertex's few edges, sorted by the key stably. A full sort of the
  // 3F half-edges was 6% of an encode's time: the topology is built a dozen times a frame.
  std::vector<HalfEdge> unordered;
  unordered.reserve(3 * face_total);
  uint32_t lowest_end = 0;
  for (size_t f = 0; f < face_total; ++f) {
    for (int k = 0; k < 3; ++k) {
      const uint64_t key = undirected_edge_key(faces[f][k], faces[f][(k + 1) % 3]);
      unordered.push_back({key, static_cast<int32_t>(f), static_cast<int8_t>(k)});
      lowest_end = std::max(lowest_end, static_cast<uint32_t>(key >> 32) + 1);
    }
  }
  std::vector<HalfEdge> half_edges;
  if (lowest_end > static_cast<uint32_t>(std::max(vertex_count, 0))) {
    // An index outside the vertices (callers validate first, so not in practice): a plain sort.
    std::sort(unordered.begin(), unordered.end(),
              [](const HalfEdge& x, const HalfEdge& y) { return x.key != y.key ? x.key < y.key : x.face < y.face; });
    half_edges = std::move(unordered);
  } else {
    std::vector<uint32_t> bucket_start(static_cast<size_t>(lowest_end) + 1, 0);
    for (const HalfEdge& h : unordered) ++bucket_start[(h.key >> 32) + 1];
    std::partial_sum(bucket_start.begin(), bucket_start.end(), bucket_start.begin());
    half_edges.resize(unordered.size());
    std::vector<uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (const HalfEdge& h : unordered) half_edges[fill[h.key >> 32]++] = h;
    for (size_t b = 0; b + 1 < bucket_start.size(); ++b) {
      // Insertion sort by the key, stable: the bucket came in face order.
      for (size_t i = bucket_start[b] + 1; i < bucket_start[b + 1]; ++i) {
        const HalfEdge h = half_edges[i];
        size_t at = i;
        for (; at > bucket_start[b] && half_edges[at - 1].key > h.key; --at) half_edges[at] = half_edges[at - 1];
        half_edges[at] = h;
      }
    }
  }

  edge_face_offsets_.push_back(0);
  std::vector<std::array<int32_t, 2>> boundary_half_edges;  // (from, to) with the face on the left
  for (size_t i = 0; i < half_edges.size();) {
    size_t j = i;
    while (j < half_edges.size() && half_edges[j].key == half_edges[i].key) ++j;
    const int e = static_cast<int>(edges_.size());
    edges_.push_back({static_cast<int32_t>(half_edges[i].key >> 32), static_cast<int32_t>(half_edges[i].key & 0xffffffffu)});
    for (size_t h = i; h < j; ++h) {
      edge_face_list_.push_back(half_edges[h].face);
      face_edges_[static_cast<size_t>(half_edges[h].face)][static_cast<size_t>(half_edges[h].corner)] = e;
    }
    edge_face_offsets_.push_back(static_cast<int32_t>(edge_face_list_.size()));
    const size_t count = j - i;
    auto from = [&](size_t h) { return faces[static_cast<size_t>(half_edges[h].face)][static_cast<size_t>(half_edges[h].corner)]; };
    if (count > 2) {
      non_manifold_edges_.push_back(e);
    } else if (count == 2) {
      if (from(i) == from(i + 1)) inconsistent_edges_.push_back(e);
    } else {
      const Face& face = faces[static_cast<size_t>(half_edges[i].face)];
      const int k = half_edges[i].corner;
      boundary_half_edges.push_back({face[static_cast<size_t>(k)], face[static_cast<size_t>((k + 1) % 3)]});
    }
    i = j;
  }

  // Fans: corners around a vertex are joined across each manifold edge they share; a vertex whose
  // corners fall into several groups is a pinch point.
  DisjointSets corners(3 * face_total);
  for (int e = 0; e < edge_count(); ++e) {
    const auto incident = edge_faces(e);
    if (incident.size() != 2) continue;
    for (int32_t endpoint : edges_[static_cast<size_t>(e)]) {
      int c0 = -1, c1 = -1;
      for (int k = 0; k < 3; ++k) {
        if (faces[static_cast<size_t>(incident[0])][static_cast<size_t>(k)] == endpoint) c0 = 3 * incident[0] + k;
        if (faces[static_cast<size_t>(incident[1])][static_cast<size_t>(k)] == endpoint) c1 = 3 * incident[1] + k;
      }
      corners.unite(static_cast<size_t>(c0), static_cast<size_t>(c1));
    }
  }
  std::vector<int64_t> fan_root(static_cast<size_t>(vertex_count), -1);
  std::vector<uint8_t> pinched(static_cast<size_t>(vertex_count), 0);
  for (size_t f = 0; f < face_total; ++f) {
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<size_t>(faces[f][static_cast<size_t>(k)]);
      const auto root = static_cast<int64_t>(corners.find(3 * f + static_cast<size_t>(k)));
      if (fan_root[v] < 0)
        fan_root[v] = root;
      else if (fan_root[v] != root)
        pinched[v] = 1;
    }
  }
  for (size_t v = 0; v < pinched.size(); ++v) {
    if (fan_root[v] >= 0) ++referenced_vertices_;
    if (pinched[v]) non_manifold_vertices_.push_back(static_cast<int>(v));
  }

  // Boundary loops: follow boundary half-edges; at a pinch vertex the walk may pick either branch,
  // which is why loops are only meaningful on manifold meshes.
  on_boundary_.assign(static_cast<size_t>(vertex_count), 0);
  std::vector<int32_t> next(static_cast<size_t>(vertex_count), -1);
  for (const auto& h : boundary_half_edges) {
    next[static_cast<size_t>(h[0])] = h[1];
    on_boundary_[static_cast<size_t>(h[0])] = 1;
    on_boundary_[static_cast<size_t>(h[1])] = 1;
  }
  std::vector<uint8_t> visited(static_cast<size_t>(vertex_count), 0);
  for (const auto& h : boundary_half_edges) {
    if (visited[static_cast<size_t>(h[0])]) continue;
    std::vector<int> loop;
    int v = h[0];
    while (v >= 0 && !visited[static_cast<size_t>(v)]) {
      visited[static_cast<size_t>(v)] = 1;
      loop.push_back(v);
      v = next[static_cast<size_t>(v)];
    }
    boundary_loops_.push_back(std::move(loop));
  }

  // Components through shared vertices.
  DisjointSets vertices(static_cast<size_t>(vertex_count));
  for (const Face& f : faces) {
    vertices.unite(static_cast<size_t>(f[0]), static_cast<size_t>(f[1]));
    vertices.unite(static_cast<size_t>(f[0]), static_cast<size_t>(f[2]));
  }
  std::vector<int> component_of_root(static_cast<size_t>(vertex_count), -1);
  face_component_.resize(face_total);
  for (size_t f = 0; f < face_total; ++f) {
    const size_t root = vertices.find(static_cast<size_t>(faces[f][0]));
    if (component_of_root[root] < 0) component_of_root[root] = component_count_++;
    face_component_[f] = component_of_root[root];
  }
}

}  // namespace facemorph
