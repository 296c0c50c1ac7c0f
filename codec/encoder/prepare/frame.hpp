// Turning a captured frame into what the encoder needs: a validated, repaired triangle mesh that is
// a topological disk (one boundary loop, Euler characteristic 1). Holes other than the outer rim
// (open eyes and mouth, missing data) are filled with a fair triangulation and recorded, so the
// decoder can cut them out again (spec/method.md §2).
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <string>
#include <vector>

namespace facemorph {

struct FilledHole {
  std::vector<int> loop;  // its boundary in the prepared mesh, surface on the left
  int first_vertex = 0;   // fill vertices: [first_vertex, first_vertex + vertex_count)
  int vertex_count = 0;
  int first_face = 0;  // fill faces: [first_face, first_face + face_count)
  int face_count = 0;
  double perimeter = 0;                     // capture units
  double area = 0;                          // of the fill
  double min_angle_degrees = 0;             // smallest angle the fill chose (corners forced by the hole excluded)
  double sharpest_hole_corner_degrees = 0;  // smallest interior angle of the hole itself
  int folded_faces = 0;                     // fill faces folded back: > 120 deg from the surrounding surface
};

// What a frame's repairs changed in all (RepairReport's totals): what the encoder keeps of a frame
// for its summary and the file's settings.
struct RepairTotals {
  int faces_changed = 0;
  int vertices_changed = 0;
  double largest_move = 0;  // capture units
  double diagonal = 0;      // of the captured frame
};

struct RepairReport {
  int merged_vertices = 0;           // exact duplicate positions welded
  int dropped_degenerate_faces = 0;  // repeated vertex or zero area
  int split_faces = 0;               // neighbours split to absorb a zero-area face (T-junction)
  int dropped_duplicate_faces = 0;   // same three vertices as an earlier face
  int dropped_unreferenced_vertices = 0;
  int reoriented_faces = 0;         // flipped to agree with their neighbours
  int dropped_components = 0;       // separate surfaces (eyeballs, teeth) dropped by keep_largest_component
  int dropped_component_faces = 0;  // and their faces
  // The non-manifold repairs (PrepareOptions::repair_non_manifold; spec/method.md §2.1).
  int non_manifold_edges = 0;   // edges with three or more faces, resolved
  int dropped_sheet_faces = 0;  // faces dropped to resolve them
  int dropped_sheets = 0;       // of which whole sheets (fins, a fused hair or torso surface)
  int split_vertices = 0;       // bow-tie vertices split
  int added_vertices = 0;       // copies they made
  int rewired_faces = 0;        // faces moved onto a copy
  int dropped_specks = 0;       // islands under kSpeckAreaFraction of the face's area
  int dropped_speck_faces = 0;
  // Totals over every repair above (hole filling apart): faces dropped, added, re-attached or
  // flipped; vertices dropped (welded included), added or moved; and the largest distance from a
  // captured vertex to the repaired surface or moved by a repair (capture units; diagonal: the
  // captured frame's bounding-box diagonal, for relative figures).
  int faces_changed = 0;
  int vertices_changed = 0;
  double largest_move = 0;
  double diagonal = 0;
  std::vector<FilledHole> holes;

  bool changed() const;
  std::string summary() const;  // one line, e.g. "filled 3 holes (118 faces); merged 2 vertices"
  RepairTotals totals() const { return {faces_changed, vertices_changed, largest_move, diagonal}; }
};

// An island of less than this fraction of the face component's area is a speck: dropped by default,
// without --largest-component (spec/method.md §2.1).
inline constexpr double kSpeckAreaFraction = 0.01;

struct PrepareOptions {
  bool fill_holes = true;  // false: a frame with holes is an error
  // Points on the outer rim (the rim_* landmarks); they pick the rim among the boundary loops.
  // Without them the loop with the longest perimeter is the rim.
  std::vector<Vec3> rim_markers;
  // Keep only the component of largest area and drop the others (eyeballs, teeth, stray shells),
  // saying so in the report; false: several components are an error naming their count.
  bool keep_largest_component = false;
  // Repair what scanners write (true, the default): edges with three or more faces resolved to the
  // sheet that holds the face, bow-tie vertices split, specks dropped. false (fmenc --strict): each
  // is an error naming it, as kInvalidMesh / kNotADisk below.
  bool repair_non_manifold = true;
  // Points on the face (the frame's landmarks, any of them): they pick the sheet and the component
  // that hold the face. Without them the larger (by area) is the face.
  std::vector<Vec3> face_points = {};
};

struct PreparedFrame {
  TriangleMesh mesh;               // a disk
  std::vector<int> rim;            // its boundary loop, surface on the left
  std::vector<int> source_vertex;  // input vertex of each mesh vertex; -1 for fill vertices
  RepairReport report;
};

// Validates and repairs `mesh` (named `name` in messages). Throws facemorph::Error:
//   kInvalidMesh  no faces, non-finite coordinates, out-of-range indices, a non-orientable surface;
//                 with repair_non_manifold off, non-manifold edges or vertices;
//   kNotADisk     several components (beyond specks, without keep_largest_component; with
//                 repair_non_manifold off, any), a closed surface, handles, or holes with fill_holes off.
// Each message names the frame and the defect, e.g. "frame_0012.obj: 2 components; a face capture
// must be one open surface".
PreparedFrame prepare_frame(const TriangleMesh& mesh, const std::string& name, const PrepareOptions& options = {});

// The fill of one hole: new vertices and faces. `loop` is a boundary loop of the mesh (surface on
// its left); `target_edge_length[k]` the local edge length at loop[k]. Faces use mesh indices for
// loop vertices and mesh.vertex_count() + i for new vertex i. Throws kNotADisk if the loop cannot
// be triangulated without duplicating an existing edge.
struct HoleFill {
  std::vector<Vec3> positions;
  std::vector<Vec2> uvs;      // per new vertex, when `loop_uvs` was given
  std::vector<Vec3> colours;  // per new vertex, when the mesh has colours: the rim's, weighted by inverse distance
  std::vector<Face> faces;
  double min_angle_degrees = 0;
  double sharpest_hole_corner_degrees = 0;
  int folded_faces = 0;
};
HoleFill fill_hole(const TriangleMesh& mesh, const std::vector<int>& loop, const std::vector<double>& target_edge_length,
                   const std::vector<Vec2>* loop_uvs);

}  // namespace facemorph
