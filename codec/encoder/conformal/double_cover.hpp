// The closed surface the spherical conformal map runs on (method-notes §2.1-2.2), and the intrinsic
// Delaunay triangulation that makes its cotangent weights non-negative.
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/mesh.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <span>
#include <vector>

namespace facemorph {

struct DiskPreconditioning {
  int split_chords = 0;           // interior edges joining two boundary vertices, split at the midpoint
  int split_ears = 0;             // faces with three boundary vertices, split at the centroid
  int split_obtuse_boundary = 0;  // boundary edges facing an obtuse angle, split at the midpoint
  int split_caps = 0;             // edges facing an angle above 150°, split at the altitude's foot
  int caps_left = 0;              // caps still there when preconditioning stopped (see below)
  int obtuse_boundary_left = 0;   // obtuse boundary edges still there
  int rounds = 0;                 // rounds of splits taken
};

// Splits, in place, what would break the double cover or give it negative weights: chords and ears
// would duplicate an edge or face when the copies are glued; a boundary edge facing an obtuse
// angle becomes an interior edge whose two (equal) opposite angles sum past π. "Caps" (an angle
// above 150°) are split too: the intrinsic Delaunay triangulation flips them away, and the straight
// chords of the original triangle can then fold in the disk (ICT's mouth corners have 172°). Splits add real
// surface points on existing edges (or a centroid), so the geometry is unchanged; UVs are
// interpolated. `source_vertex` (one entry per vertex) grows with -1 for new vertices.
// Terminates on every disk: ears and chords take at most two rounds and never come back; caps and
// obtuse boundary edges get a bounded number of rounds each, and those left are counted in the
// report (the cover's intrinsic flips and untangling cope with them at some cost in distortion).
// Each round's topology comes from `topologies`: the caller's disk check has built the first, and
// the last (no split follows it) is the preconditioned mesh's, left there for the rim.
DiskPreconditioning precondition_disk(TriangleMesh& mesh, std::vector<int>& source_vertex, TopologyCache& topologies);
inline DiskPreconditioning precondition_disk(TriangleMesh& mesh, std::vector<int>& source_vertex) {
  TopologyCache topologies;
  return precondition_disk(mesh, source_vertex, topologies);
}

// Two copies of a disk glued along the boundary: vertices 0..n-1 are the disk's, n.. the mirror
// copies of its interior vertices; copy-2 faces are reversed so the closed surface is consistently
// oriented. Only intrinsic data (edge lengths) is kept: both sheets coincide in space.
struct DoubleCover {
  int disk_vertices = 0;
  std::vector<Face> faces;
  std::vector<CornerValues> lengths;  // lengths[f][k]: edge opposite corner k
  std::vector<int> mirror;            // the other sheet's copy of each vertex (itself on the boundary)
  std::vector<uint8_t> on_boundary;   // per vertex

  int vertex_count() const { return static_cast<int>(mirror.size()); }
};
// `faces` and `lengths` may be an intrinsic triangulation of the disk (flipped interior edges);
// `on_boundary` flags the disk's boundary vertices.
DoubleCover build_double_cover(std::span<const Face> faces, std::span<const CornerValues> lengths, const std::vector<uint8_t>& on_boundary);

// Edge lengths of each face of a mesh (lengths[f][k] opposite corner k).
std::vector<CornerValues> face_edge_lengths(const TriangleMesh& mesh);

// Flips edges on the intrinsic metric until every edge is locally Delaunay (opposite angles sum to
// at most π), so the cotangent weights are non-negative. Edges flagged in `fixed` (per face corner,
// may be empty) are never flipped. Returns the number of flips. The triangulation may stop being
// simplicial (two edges between the same vertices); the Laplacian does not mind.
int flip_to_intrinsic_delaunay(std::vector<Face>& faces, std::vector<CornerValues>& lengths,
                               const std::vector<std::array<uint8_t, 3>>& fixed = {});

}  // namespace facemorph
