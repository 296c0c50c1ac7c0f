// The repairs that make a scanner's non-manifold mesh a surface (spec/method.md §2.1): edges with
// three or more faces resolved to the sheet that holds the face, bow-tie vertices split, and the
// component that holds the face chosen. Free functions over a TriangleMesh; frame_prep.cpp runs
// them in order and counts what they changed in the frame's RepairReport.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <cstdint>
#include <vector>

namespace facemorph {

// Removes the faces marked in `drop` (one flag a face), with their texture-coordinate faces.
void remove_faces(TriangleMesh& mesh, const std::vector<uint8_t>& drop);

// How many of `face_points` (the frame's landmarks) each of `group_count` groups of faces holds: a
// point counts for the group of the face whose centroid is nearest. `group_of_face[f]` in
// [0, group_count).
std::vector<int> landmark_votes(const TriangleMesh& mesh, const std::vector<int>& group_of_face, int group_count,
                                const std::vector<Vec3>& face_points);

// Which group holds the face: the one of most landmark_votes, ties settled by the larger area.
// Returns its index, or -1 where no point is given (the caller decides).
int choose_face_group(const TriangleMesh& mesh, const std::vector<int>& group_of_face, int group_count,
                      const std::vector<double>& group_area, const std::vector<Vec3>& face_points);

struct NonManifoldEdgeRepair {
  int edges = 0;           // edges that had three or more faces
  int dropped_faces = 0;   // faces dropped to resolve them (with the sheets dropped whole)
  int dropped_sheets = 0;  // sheets that lost at every such edge they met, dropped whole
};

// Resolves every edge with three or more faces. Faces join into sheets across edges with exactly
// two faces; at each such edge the faces are ranked by their sheet's landmark_votes, then by
// whether the sheet passes through the edge (two faces there: a fin ends at it), then by its area;
// the first is kept with another face of its sheet if it has one, else with the second. A sheet that keeps no face at any such edge is
// dropped whole (a fin, a hair or torso surface fused to the face along a seam). Marks the faces to drop; `mesh` unchanged.
// `topologies` gives the mesh's topology (built there only if the caller's steps have not).
std::vector<uint8_t> non_manifold_edge_drops(const TriangleMesh& mesh, const std::vector<Vec3>& face_points, NonManifoldEdgeRepair* counts,
                                             TopologyCache& topologies);

struct BowTieRepair {
  int vertices = 0;         // bow-tie vertices split
  int added_vertices = 0;   // copies made, one for each fan after the first
  int rewired_faces = 0;    // faces moved onto a copy
  double largest_move = 0;  // how far a copy was moved into its fan (capture units)
};

// Splits every vertex whose faces form several fans (joined across edges with two faces): the fan
// of most faces keeps the vertex, each other fan gets a copy (same colour and `source` entry) moved
// kBowTieSeparation of the way towards its fan's centre, so the copies do not coincide (a pinched
// hole becomes one loop with a waist, which hole filling can triangulate). Needs no edge with three
// or more faces. `source` (one entry a vertex) grows with the copies. `topologies` as above.
inline constexpr double kBowTieSeparation = 0.25;
BowTieRepair split_bow_tie_vertices(TriangleMesh& mesh, std::vector<int>& source, TopologyCache& topologies);

}  // namespace facemorph
