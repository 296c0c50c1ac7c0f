// Combinatorial structure of a triangle mesh: edges, boundary loops, manifoldness, components.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace facemorph {

class MeshTopology {
 public:
  // Builds the edge structure of `faces` over `vertex_count` vertices (indices must be in range).
  MeshTopology(std::span<const Face> faces, int vertex_count);

  int vertex_count() const { return vertex_count_; }
  int referenced_vertex_count() const { return referenced_vertices_; }
  int face_count() const { return static_cast<int>(face_edges_.size()); }
  int edge_count() const { return static_cast<int>(edges_.size()); }

  // Undirected edge e as (smaller index, larger index).
  const std::array<int32_t, 2>& edge(int e) const { return edges_[static_cast<size_t>(e)]; }
  // Faces incident to edge e (1 on the boundary, 2 inside; more only on non-manifold edges).
  std::span<const int32_t> edge_faces(int e) const;
  // Edge of face f between corners k and k+1.
  int face_edge(int f, int k) const { return face_edges_[static_cast<size_t>(f)][static_cast<size_t>(k)]; }
  bool is_boundary_edge(int e) const { return edge_faces(e).size() == 1; }

  // Edges with more than two faces.
  const std::vector<int>& non_manifold_edges() const { return non_manifold_edges_; }
  // Interior edges whose two faces traverse it in the same direction (inconsistent orientation).
  const std::vector<int>& inconsistently_oriented_edges() const { return inconsistent_edges_; }
  // Vertices whose faces form more than one fan (a "bow tie"), and referenced isolated vertices.
  const std::vector<int>& non_manifold_vertices() const { return non_manifold_vertices_; }
  bool is_manifold() const { return non_manifold_edges_.empty() && inconsistent_edges_.empty() && non_manifold_vertices_.empty(); }

  // Boundary loops as ordered vertex cycles, oriented so the surface lies to the left of each
  // step (the direction of the boundary half-edges of counter-clockwise faces). Meaningful only
  // when is_manifold().
  const std::vector<std::vector<int>>& boundary_loops() const { return boundary_loops_; }
  bool is_boundary_vertex(int v) const { return on_boundary_[static_cast<size_t>(v)] != 0; }

  // Connected components (through shared vertices) and each face's component id.
  int component_count() const { return component_count_; }
  const std::vector<int>& face_components() const { return face_component_; }

  // V - E + F over referenced vertices.
  int euler_characteristic() const { return referenced_vertices_ - edge_count() + face_count(); }

 private:
  int vertex_count_ = 0;
  int referenced_vertices_ = 0;
  std::vector<std::array<int32_t, 2>> edges_;
  std::vector<int32_t> edge_face_offsets_;
  std::vector<int32_t> edge_face_list_;
  std::vector<std::array<int32_t, 3>> face_edges_;
  std::vector<int> non_manifold_edges_;
  std::vector<int> inconsistent_edges_;
  std::vector<int> non_manifold_vertices_;
  std::vector<std::vector<int>> boundary_loops_;
  std::vector<uint8_t> on_boundary_;
  int component_count_ = 0;
  std::vector<int> face_component_;
};

// The topology of one mesh, built once while its faces stay the same: a frame's preparation asks
// for it at each step (sheets, bow ties, components, orientation, the disk check, the rim), and on a
// clean capture no step edits the mesh. Each request compares the faces with a copy of those the
// topology was built from (a 12-byte compare a face, against the build's sort of the half-edges),
// so a mesh edited in between gets a fresh topology, never a stale one. Holds one mesh's at a time.
class TopologyCache {
 public:
  const MeshTopology& of(std::span<const Face> faces, int vertex_count);
  const MeshTopology& of(const TriangleMesh& mesh) { return of(mesh.faces, mesh.vertex_count()); }
  int builds() const { return builds_; }  // topologies built so far (for tests)

 private:
  std::vector<Face> faces_;
  std::optional<MeshTopology> topology_;
  int builds_ = 0;
};

// Union-find over 0..n-1 with path halving; used by topology, validation and hole filling.
class DisjointSets {
 public:
  explicit DisjointSets(size_t n);
  size_t find(size_t x);
  bool unite(size_t a, size_t b);  // true when a and b were in different sets

 private:
  std::vector<size_t> parent_;
};

// The faces f of `mesh` with keep[f] set, as a mesh of their own (positions only): the faces in
// their order and each vertex numbered at its first use, so that of two faces the lower index stays
// the lower one (a nearest-face search's tie rule gives the same face in the part as in the whole).
template <class Keep>
TriangleMesh sub_mesh(const TriangleMesh& mesh, const Keep& keep) {
  TriangleMesh out;
  std::vector<int32_t> index(mesh.positions.size(), -1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (!keep[f]) continue;
    Face g;
    for (size_t k = 0; k < 3; ++k) {
      int32_t& i = index[static_cast<size_t>(mesh.faces[f][k])];
      if (i < 0) {
        i = static_cast<int32_t>(out.positions.size());
        out.positions.push_back(mesh.positions[static_cast<size_t>(mesh.faces[f][k])]);
      }
      g[k] = i;
    }
    out.faces.push_back(g);
  }
  return out;
}

}  // namespace facemorph
