#include "codec/encoder/prepare/frame.hpp"
#include "codec/core/geometry/differential.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>

namespace facemorph {
namespace {

using testing::expect_error;

// A dome z = 1 - r² over the unit disk, sampled on a polar grid (rings x sectors), optionally
// with circular holes (centre, radius) cut out by dropping faces inside them.
TriangleMesh dome(int rings, int sectors, std::vector<std::pair<Vec2, double>> holes = {}) {
  TriangleMesh m = testing::polar_disk(rings, sectors, [](const Vec2& w) { return Vec3(w.x(), w.y(), 1 - w.squaredNorm()); });
  if (!holes.empty()) {
    std::vector<Face> kept;
    for (const Face& f : m.faces) {
      bool inside = false;
      for (int32_t v : f) {
        const Vec2 p = m.positions[static_cast<size_t>(v)].head<2>();
        for (const auto& [c, radius] : holes) inside = inside || (p - c).norm() < radius;
      }
      if (!inside) kept.push_back(f);
    }
    m.faces = kept;
  }
  return m;
}

bool is_disk(const TriangleMesh& m) {
  const MeshTopology t(m.faces, m.vertex_count());
  return t.is_manifold() && t.component_count() == 1 && t.boundary_loops().size() == 1 && t.euler_characteristic() == 1;
}

TEST(PrepareFrame, AValidDiskPassesUnchangedAndFacesOutward) {
  TriangleMesh m = dome(12, 40);
  for (Face& f : m.faces) std::swap(f[1], f[2]);  // inward: must be flipped to the convex side
  const PreparedFrame p = prepare_frame(m, "dome.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  EXPECT_EQ(p.mesh.vertex_count(), m.vertex_count());
  EXPECT_EQ(p.report.reoriented_faces, m.face_count());
  const auto normals = vertex_normals(p.mesh.positions, p.mesh.faces);
  EXPECT_GT(normals[0].z(), 0.99);  // apex normal points out of the dome
  EXPECT_EQ(p.rim.size(), 40u);
}

TEST(PrepareFrame, FillsEyeAndMouthHolesFairlyAndRecordsThem) {
  const TriangleMesh m = dome(30, 120, {{{-0.3, 0.3}, 0.12}, {{0.3, 0.3}, 0.12}, {{0.0, -0.35}, 0.2}});
  ASSERT_EQ(MeshTopology(m.faces, m.vertex_count()).boundary_loops().size(), 4u);
  const PreparedFrame p = prepare_frame(m, "holes.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  ASSERT_EQ(p.report.holes.size(), 3u);
  for (const FilledHole& h : p.report.holes) {
    EXPECT_EQ(h.folded_faces, 0);
    EXPECT_GT(h.min_angle_degrees, 12.0);  // no slivers
    EXPECT_GT(h.vertex_count, 0);          // refined to the surrounding density, not a bare fan
    // A membrane over a loop of radius R on z = 1 - r² solves Δu = Δ(dome) = -4 with u = 0 on the
    // loop: it lies below the dome by R² - ρ² at distance ρ from the centre, never above it.
    Vec2 centre = Vec2::Zero();
    for (int v : h.loop) centre += p.mesh.positions[static_cast<size_t>(v)].head<2>() / static_cast<double>(h.loop.size());
    double radius = 0;
    for (int v : h.loop) radius = std::max(radius, (p.mesh.positions[static_cast<size_t>(v)].head<2>() - centre).norm());
    for (int v = h.first_vertex; v < h.first_vertex + h.vertex_count; ++v) {
      const Vec3& q = p.mesh.positions[static_cast<size_t>(v)];
      const double below = (1 - q.head<2>().squaredNorm()) - q.z();
      EXPECT_GT(below, -0.003);
      EXPECT_LT(below, radius * radius - (q.head<2>() - centre).squaredNorm() + 0.006);
    }
    for (int f = h.first_face; f < h.first_face + h.face_count; ++f) EXPECT_LT(f, p.mesh.face_count());
  }
  // The original vertices keep their identity; fill vertices have none.
  EXPECT_EQ(p.source_vertex[0], 0);
  EXPECT_EQ(p.source_vertex.back(), -1);
  EXPECT_NE(p.report.summary().find("filled 3 holes"), std::string::npos);
}

TEST(PrepareFrame, RimMarkersChooseTheOuterLoopEvenWhenAHoleIsLonger) {
  // A big hole with more boundary length than the rim: markers decide.
  const TriangleMesh m = dome(24, 60, {{{0.0, 0.0}, 0.75}});
  std::vector<Vec3> markers;
  for (int k = 0; k < 6; ++k) {
    const double a = 2 * std::numbers::pi * k / 6;
    markers.emplace_back(std::cos(a), std::sin(a), 0);
  }
  const PreparedFrame p = prepare_frame(m, "ring.obj", {.fill_holes = true, .rim_markers = markers});
  EXPECT_TRUE(is_disk(p.mesh));
  for (int v : p.rim) EXPECT_NEAR(p.mesh.positions[static_cast<size_t>(v)].head<2>().norm(), 1.0, 1e-9);
}

TEST(PrepareFrame, RepairsDuplicatesDegenerateFacesAndUnreferencedVertices) {
  TriangleMesh m = dome(6, 16);
  const int original = m.vertex_count();
  // A duplicate of vertex 5 used by one face, an unreferenced vertex, a repeated-index face and
  // a duplicate face.
  m.positions.push_back(m.positions[5]);
  m.positions.emplace_back(9, 9, 9);
  for (Face& f : m.faces) {
    if (f[0] == 5) {
      f[0] = original;
      break;
    }
  }
  m.faces.push_back({1, 1, 2});
  m.faces.push_back(m.faces[3]);
  const PreparedFrame p = prepare_frame(m, "messy.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  EXPECT_EQ(p.report.merged_vertices, 1);
  EXPECT_EQ(p.report.dropped_degenerate_faces, 1);
  EXPECT_EQ(p.report.dropped_duplicate_faces, 1);
  EXPECT_EQ(p.report.dropped_unreferenced_vertices, 1);
  EXPECT_EQ(p.mesh.vertex_count(), original);
  EXPECT_TRUE(p.report.changed());
}

// A colour that is a linear function of position: interpolation along an edge or across a face
// reproduces it exactly, so a vertex whose colour is not its position's was renumbered wrongly.
Vec3 linear_colour(const Vec3& p) { return Vec3(0.5 + 0.4 * p.x(), 0.5 + 0.4 * p.y(), 0.2 + 0.6 * p.z()); }

TEST(PrepareFrame, VertexColoursSurviveRepairsAndHoleFilling) {
  TriangleMesh m = dome(30, 120, {{{-0.3, 0.3}, 0.12}, {{0.0, -0.35}, 0.2}});
  m.positions.emplace_back(0.5, 0.5, 5);  // unreferenced: dropped, and every later vertex renumbered
  std::swap(m.positions.front(), m.positions.back());
  for (Face& f : m.faces) {
    for (int32_t& v : f) v = v == 0 ? m.vertex_count() - 1 : v;
  }
  for (const Vec3& p : m.positions) m.colours.push_back(p.z() > 1 ? Vec3(1, 0, 1) : linear_colour(p));
  const PreparedFrame p = prepare_frame(m, "colours.ply");
  EXPECT_GT(p.report.dropped_unreferenced_vertices, 1);  // the one added and those the holes' faces left
  ASSERT_EQ(p.report.holes.size(), 2u);
  ASSERT_TRUE(p.mesh.has_colours());
  const int captured = p.report.holes.front().first_vertex;
  for (int v = 0; v < captured; ++v) {
    const Vec3& q = p.mesh.positions[static_cast<size_t>(v)];
    ASSERT_LT((p.mesh.colours[static_cast<size_t>(v)] - linear_colour(q)).norm(), 1e-15) << "vertex " << v;
  }
  // A fill vertex takes its rim's colours, weighted: within their range, and near the colour the
  // surface would have there (the fill lies a little below the dome, so z's channel is looser).
  for (const FilledHole& h : p.report.holes) {
    Vec3 lo = Vec3::Constant(1), hi = Vec3::Zero();
    for (int v : h.loop) {
      lo = lo.cwiseMin(p.mesh.colours[static_cast<size_t>(v)]);
      hi = hi.cwiseMax(p.mesh.colours[static_cast<size_t>(v)]);
    }
    ASSERT_GT(h.vertex_count, 0);
    for (int v = h.first_vertex; v < h.first_vertex + h.vertex_count; ++v) {
      const Vec3& c = p.mesh.colours[static_cast<size_t>(v)];
      EXPECT_TRUE((c.array() >= lo.array() - 1e-12).all() && (c.array() <= hi.array() + 1e-12).all()) << "fill vertex " << v;
      EXPECT_LT(std::abs(c.x() - linear_colour(p.mesh.positions[static_cast<size_t>(v)]).x()), 0.1) << "fill vertex " << v;
    }
  }
}

TEST(PrepareFrame, BadVertexColoursAreNamedErrors) {
  TriangleMesh m = dome(6, 16);
  m.colours.assign(static_cast<size_t>(m.vertex_count()) - 1, Vec3::Constant(0.5));
  expect_error(ErrorCode::kInvalidMesh, "short.ply: 96 vertex colours for 97 vertices", [&] { prepare_frame(m, "short.ply"); });
  m.colours.push_back(Vec3(0.5, 1.25, 0.5));
  expect_error(ErrorCode::kInvalidMesh, "bright.ply: vertex 96 has a colour outside [0, 1]", [&] { prepare_frame(m, "bright.ply"); });
}

TEST(PrepareFrame, ZeroAreaFaceAtATJunctionSplitsItsNeighbour) {
  // Square (0,1,2,3) as two triangles plus vertex 4 on edge 0-1 with a zero-area face (0,4,1)
  // stitched into the lower triangle's edge: a T-junction.
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {1, 0, 0}, {1, -1, 0}};
  m.faces = {{0, 1, 2}, {0, 2, 3}, {1, 0, 4}, {0, 5, 4}, {4, 5, 1}};
  const PreparedFrame p = prepare_frame(m, "tjunction.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  EXPECT_EQ(p.report.dropped_degenerate_faces, 1);
  EXPECT_EQ(p.report.split_faces, 1);
  EXPECT_NEAR(total_area(p.mesh.positions, p.mesh.faces), 5.0, 1e-12);
}

TEST(PrepareFrame, InconsistentOrientationIsRepaired) {
  TriangleMesh m = dome(8, 24);
  for (size_t f = 0; f < m.faces.size(); f += 7) std::swap(m.faces[f][1], m.faces[f][2]);
  const PreparedFrame p = prepare_frame(m, "flipped.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  EXPECT_TRUE(MeshTopology(p.mesh.faces, p.mesh.vertex_count()).inconsistently_oriented_edges().empty());
  EXPECT_GT(p.report.reoriented_faces, 0);
}

// --largest-component keeps the face (the component of largest area, not of most faces) and says
// what it dropped: a dome with a small, densely meshed closed ball beside it.
TEST(PrepareFrame, TheLargestComponentIsTheFace) {
  const TriangleMesh face = dome(6, 16);
  const TriangleMesh ball = testing::icosphere(0.05, 3);
  ASSERT_GT(ball.face_count(), face.face_count());  // more faces, far less area
  TriangleMesh both = ball;
  const auto offset = static_cast<int32_t>(both.positions.size());
  for (const Vec3& q : face.positions) both.positions.push_back(q);
  for (const Face& f : face.faces) both.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
  const PreparedFrame alone = prepare_frame(face, "face.obj");
  PrepareOptions options;
  options.keep_largest_component = true;
  options.repair_non_manifold = false;  // with repairs on, the ball is a speck (SpecksAreDropped... below)
  const PreparedFrame kept = prepare_frame(both, "both.obj", options);
  EXPECT_EQ(kept.mesh.vertex_count(), alone.mesh.vertex_count());
  EXPECT_EQ(kept.mesh.face_count(), alone.mesh.face_count());
  EXPECT_NEAR(total_area(kept.mesh.positions, kept.mesh.faces), total_area(alone.mesh.positions, alone.mesh.faces), 1e-12);
  EXPECT_NE(kept.report.summary().find("dropped 1 other component"), std::string::npos) << kept.report.summary();
}

TEST(PrepareFrame, BadFramesAreNamedErrors) {
  const TriangleMesh disk = dome(6, 16);

  TriangleMesh two = disk;
  for (const Vec3& q : disk.positions) two.positions.push_back(q + Vec3(5, 0, 0));
  for (const Face& f : disk.faces)
    two.faces.push_back({f[0] + disk.vertex_count(), f[1] + disk.vertex_count(), f[2] + disk.vertex_count()});
  expect_error(ErrorCode::kNotADisk, "frame_0012.obj: 2 components; a face capture must be one open surface",
               [&] { prepare_frame(two, "frame_0012.obj"); });

  const TriangleMesh sphere = testing::icosphere(1, 2);
  expect_error(ErrorCode::kNotADisk, "closed.obj: a closed surface", [&] { prepare_frame(sphere, "closed.obj"); });

  TriangleMesh nan = disk;
  nan.positions[3].y() = std::numeric_limits<double>::quiet_NaN();
  expect_error(ErrorCode::kInvalidMesh, "nan.obj: vertex 3 has a non-finite", [&] { prepare_frame(nan, "nan.obj"); });

  TriangleMesh inf = disk;
  inf.positions[2].x() = std::numeric_limits<double>::infinity();
  expect_error(ErrorCode::kInvalidMesh, "non-finite", [&] { prepare_frame(inf, "inf.obj"); });

  TriangleMesh range = disk;
  range.faces[0][1] = 1000;
  expect_error(ErrorCode::kInvalidMesh, "refers to vertex 1000", [&] { prepare_frame(range, "range.obj"); });

  TriangleMesh fin = disk;  // a third face on an interior edge
  fin.positions.emplace_back(0, 0, 3);
  fin.faces.push_back({fin.faces[0][0], fin.faces[0][1], fin.vertex_count() - 1});
  // With repairs off (fmenc --strict) the fin and the bow tie are refused, named; with them on, repaired.
  PrepareOptions strict;
  strict.repair_non_manifold = false;
  expect_error(ErrorCode::kInvalidMesh, "fin.obj: 1 non-manifold edges (edge", [&] { prepare_frame(fin, "fin.obj", strict); });
  EXPECT_EQ(prepare_frame(fin, "fin.obj").report.non_manifold_edges, 1);

  TriangleMesh bow = disk;  // a second disk touching the first at one vertex
  const int32_t apex = 0, base = bow.vertex_count();
  bow.positions.emplace_back(0.1, 0.1, 2);
  bow.positions.emplace_back(-0.1, 0.1, 2);
  bow.faces.push_back({apex, base, base + 1});
  expect_error(ErrorCode::kInvalidMesh, "bow.obj: 1 non-manifold vertices where separate fans of faces touch (vertex 0)",
               [&] { prepare_frame(bow, "bow.obj", strict); });
  // Split, the second disk is an island of its own, too large for a speck: --largest-component drops it.
  expect_error(ErrorCode::kNotADisk, "bow.obj: 2 components", [&] { prepare_frame(bow, "bow.obj"); });
  PrepareOptions largest;
  largest.keep_largest_component = true;
  const RepairReport split = prepare_frame(bow, "bow.obj", largest).report;
  EXPECT_EQ(split.split_vertices, 1);
  EXPECT_EQ(split.dropped_components, 1);

  const TriangleMesh holes = dome(20, 60, {{{0.0, 0.0}, 0.3}});
  expect_error(ErrorCode::kNotADisk, "1 holes besides the outer rim",
               [&] { prepare_frame(holes, "h.obj", {.fill_holes = false, .rim_markers = {}}); });

  expect_error(ErrorCode::kInvalidMesh, "empty.obj: the mesh has no faces", [&] { prepare_frame(TriangleMesh{}, "empty.obj"); });
}

// A frame of fmsynth's face (3000 vertices) as written, with `defects` added; its landmarks, for
// the repairs' choice of the face's sheet and component.
struct DefectFrame {
  TriangleMesh clean, mesh;
  DefectCounts counts;
  PrepareOptions options;
};

DefectFrame defect_frame(uint32_t defects) {
  const SyntheticFace face(Expression::kMixed, 1);
  const MaterialSampling sampling = sample_material_ellipse(3000, false, 0);
  DefectFrame out;
  out.clean.faces = sampling.faces;
  for (const Vec2& m : sampling.points) {
    out.clean.positions.push_back(face.position(m, 0.5));
    out.clean.uvs.push_back(SyntheticFace::texture_coordinate(m));
  }
  out.clean.uv_faces = out.clean.faces;
  out.mesh = out.clean;
  out.counts = add_defects(out.mesh, sampling.points, sampling.boundary_count, defects);
  for (const NamedPoint& l : face.landmarks()) {
    (l.name.rfind("rim_", 0) == 0 ? out.options.rim_markers : out.options.face_points).push_back(face.position(l.material, 0.5));
  }
  return out;
}

// What fmsynth --defects writes, kind by kind: each repaired, counted as written, named in the
// summary, and the frame a disk whose surface is the clean frame's (the dropped sheets, specks and
// duplicates leave nothing behind). Repairs off (fmenc --strict): the topological kinds are refused
// with their named errors.
TEST(PrepareFrame, EachDefectKindIsRepairedAndNamed) {
  const PreparedFrame clean = prepare_frame(defect_frame(0).clean, "clean.obj", defect_frame(0).options);
  ASSERT_FALSE(clean.report.changed()) << clean.report.summary();
  const double edge = std::sqrt(total_area(clean.mesh.positions, clean.mesh.faces) / clean.mesh.face_count());
  for (uint32_t kind : std::vector<uint32_t>{kDefectBowTies, kDefectThreeFaceEdges, kDefectDuplicateFaces, kDefectDegenerateFaces,
                                             kDefectFlippedPatch, kDefectIslands, kDefectTorso, kDefectAll}) {
    SCOPED_TRACE(defect_names(kind));
    const DefectFrame frame = defect_frame(kind);
    const DefectCounts& c = frame.counts;
    const PreparedFrame p = prepare_frame(frame.mesh, "defects.obj", frame.options);
    const RepairReport& r = p.report;
    const std::string summary = r.summary();
    EXPECT_TRUE(is_disk(p.mesh)) << summary;
    EXPECT_EQ(r.split_vertices, c.bow_ties);
    EXPECT_EQ(r.added_vertices, c.bow_ties);
    EXPECT_EQ(r.non_manifold_edges, c.three_face_edges);
    EXPECT_EQ(r.dropped_sheets, c.fins + (c.torso_faces > 0 ? 1 : 0));
    EXPECT_EQ(r.dropped_sheet_faces, c.fins + c.torso_faces);
    EXPECT_EQ(r.dropped_duplicate_faces, c.duplicate_faces);
    EXPECT_EQ(r.dropped_degenerate_faces, c.degenerate_faces);
    if (kind & kDefectDegenerateFaces) {
      EXPECT_EQ(c.slivers, 1);
    }
    EXPECT_EQ(r.split_faces, c.slivers);  // the T-junction closed again, no slit left open
    EXPECT_EQ(r.reoriented_faces, c.flipped_faces);
    EXPECT_EQ(r.dropped_specks, c.islands + c.flaps);
    EXPECT_EQ(r.dropped_speck_faces, c.island_faces + c.flaps);
    EXPECT_EQ(r.dropped_components, 0);
    EXPECT_EQ(r.holes.size(), c.bow_ties > c.flaps ? 1u : 0u);  // the pinched hole, filled
    // A split copy is moved off its twin, so the pinched hole's fill has no needle at the waist.
    for (const FilledHole& hole : r.holes) EXPECT_GT(hole.min_angle_degrees, 2);
    std::vector<std::array<double, 3>> at;
    for (const Vec3& q : p.mesh.positions) at.push_back({q.x(), q.y(), q.z()});
    std::sort(at.begin(), at.end());
    EXPECT_EQ(std::adjacent_find(at.begin(), at.end()), at.end()) << "two vertices at one point";
    EXPECT_GT(r.faces_changed, 0);
    // Named, with the totals: never silently.
    if (c.bow_ties) {
      EXPECT_NE(summary.find("split " + std::to_string(c.bow_ties) + " bow-tie vertices"), std::string::npos) << summary;
    }
    if (c.three_face_edges) {
      EXPECT_NE(summary.find("resolved " + std::to_string(c.three_face_edges) + " edges with 3+ faces"), std::string::npos) << summary;
    }
    if (c.islands) {
      EXPECT_NE(summary.find("specks"), std::string::npos) << summary;
    }
    EXPECT_NE(summary.find("in all " + std::to_string(r.faces_changed) + " faces and " + std::to_string(r.vertices_changed) +
                           " vertices changed"),
              std::string::npos)
        << summary;
    // Added surface is gone: every prepared vertex lies on the clean frame's surface, but for the
    // pinched hole's fill and the split copies, which stay within an edge of it.
    const PointToMesh on_clean(clean.mesh);
    double farthest = 0;
    for (const Vec3& q : p.mesh.positions) farthest = std::max(farthest, on_clean.distance(q));
    EXPECT_LT(farthest, (c.bow_ties > 0 ? 0.5 : 1e-12) * edge);
    // The largest distance moved: the farthest dropped point (a fin's tip, the torso's last row, a
    // speck) or a split copy's move; zero where only faces were dropped or flipped.
    if (c.torso_faces > 0) {
      EXPECT_GT(r.largest_move, 0.04);  // five rows 12 mm apart
    } else if (c.fins > 0 || c.islands > 0 || c.bow_ties > 0) {
      EXPECT_GT(r.largest_move, 0.2 * edge);
    } else {
      EXPECT_EQ(r.largest_move, 0);
    }
    EXPECT_GT(r.diagonal, 0.1);

    PrepareOptions strict = frame.options;
    strict.repair_non_manifold = false;
    if (c.three_face_edges) {
      expect_error(ErrorCode::kInvalidMesh, "non-manifold edges (edge", [&] { prepare_frame(frame.mesh, "defects.obj", strict); });
    } else if (c.bow_ties) {
      expect_error(ErrorCode::kInvalidMesh, "non-manifold vertices where separate fans of faces touch",
                   [&] { prepare_frame(frame.mesh, "defects.obj", strict); });
    } else if (c.islands) {
      expect_error(ErrorCode::kNotADisk, std::to_string(c.islands + 1) + " components",
                   [&] { prepare_frame(frame.mesh, "defects.obj", strict); });
    } else {
      EXPECT_NO_THROW(prepare_frame(frame.mesh, "defects.obj", strict));  // duplicates, degenerate faces and orientation: repaired as ever
    }
  }
}

// Without landmarks the sheet kept at an edge of three faces is the one passing through it (two
// faces there), even where the sheet fused to the face is larger than the face.
TEST(PrepareFrame, TheSheetThroughTheEdgeIsKeptOverALargerFin) {
  const TriangleMesh disk = dome(6, 16);
  TriangleMesh m = disk;
  // A large flat sheet standing on one interior edge of the dome: a single-face fan of wide faces.
  const Face on = m.faces[20];
  const int32_t a = on[0], b = on[1], base = m.vertex_count();
  m.positions.push_back(m.positions[static_cast<size_t>(a)] + Vec3(0, 0, 60));
  m.positions.push_back(m.positions[static_cast<size_t>(b)] + Vec3(0, 0, 60));
  m.faces.push_back({a, b, base});
  m.faces.push_back({b, base + 1, base});
  ASSERT_GT(total_area(m.positions, std::span<const Face>(m.faces.end() - 2, m.faces.end())), total_area(disk.positions, disk.faces));
  const PreparedFrame p = prepare_frame(m, "fin.obj");
  EXPECT_EQ(p.mesh.face_count(), disk.face_count());
  EXPECT_EQ(p.report.dropped_sheets, 1);
  EXPECT_EQ(p.report.dropped_sheet_faces, 2);
  EXPECT_GT(p.report.largest_move, 55);  // the sheet's far edge, 60 above the dome
}

// A surface fused to the face along a closed seam (ring 4 of the dome) cuts the face into an inner
// part and an outer band, each ending at the seam as the fused surface does, which is larger than
// either: the landmarks (the centre; rim markers on the band) keep both parts, the fused one goes.
TEST(PrepareFrame, LandmarksKeepBothPartsOfAFaceCutByAClosedSeam) {
  const int sectors = 16, seam_ring = 4;
  const TriangleMesh disk = dome(6, sectors);
  TriangleMesh m = disk;
  const int32_t first = 1 + (seam_ring - 1) * sectors, base = m.vertex_count();
  for (int s = 0; s < sectors; ++s) m.positions.push_back(m.positions[static_cast<size_t>(first + s)] + Vec3(0, 0, -5));
  for (int s = 0; s < sectors; ++s) {
    const int32_t a = first + s, b = first + (s + 1) % sectors;
    m.faces.push_back({b, a, base + s});
    m.faces.push_back({b, base + s, base + (s + 1) % sectors});
  }
  PrepareOptions options;
  options.face_points = {Vec3(0, 0, 1)};
  for (int k = 0; k < 4; ++k) options.rim_markers.emplace_back(std::cos(k * std::numbers::pi / 2), std::sin(k * std::numbers::pi / 2), 0);
  const PreparedFrame p = prepare_frame(m, "collar.obj", options);
  EXPECT_EQ(p.mesh.face_count(), disk.face_count());
  EXPECT_EQ(p.report.non_manifold_edges, sectors);
  EXPECT_EQ(p.report.dropped_sheets, 1);
  EXPECT_EQ(p.report.dropped_sheet_faces, 2 * sectors);
  EXPECT_GT(p.report.largest_move, 4);  // the fused surface's far edge, 4.5 from the dome's rim
}

// Where the landmarks lie on a smaller component (a face beside a larger torso shell), that one is
// the face: --largest-component keeps it, and what counts as a speck is measured against it.
TEST(PrepareFrame, LandmarksPickTheFaceComponent) {
  const TriangleMesh face = dome(6, 16);
  TriangleMesh both = face;
  for (const Vec3& q : face.positions) both.positions.push_back(3 * q + Vec3(10, 0, 0));  // nine times the area
  for (const Face& f : face.faces)
    both.faces.push_back({f[0] + face.vertex_count(), f[1] + face.vertex_count(), f[2] + face.vertex_count()});
  PrepareOptions options;
  options.keep_largest_component = true;
  options.face_points = {Vec3(0, 0, 1), Vec3(0.5, 0, 0.75)};
  const PreparedFrame kept = prepare_frame(both, "shell.obj", options);
  EXPECT_EQ(kept.mesh.face_count(), face.face_count());
  EXPECT_NEAR(total_area(kept.mesh.positions, kept.mesh.faces), total_area(face.positions, face.faces), 1e-12);
  EXPECT_EQ(kept.report.dropped_components, 1);
}

// A component is a speck below 1% of the face's area: one just under is dropped by default, one
// just over is still an error naming the count (--largest-component drops it).
TEST(PrepareFrame, SpecksAreDroppedAndLargerIslandsNeedLargestComponent) {
  const TriangleMesh disk = dome(6, 16);
  const double area = total_area(disk.positions, disk.faces);
  for (double fraction : {0.9 * kSpeckAreaFraction, 1.1 * kSpeckAreaFraction}) {
    TriangleMesh m = disk;
    const double side = std::sqrt(2 * fraction * area);  // a right triangle of this area
    const int32_t base = m.vertex_count();
    m.positions.push_back({3, 0, 0});
    m.positions.push_back({3 + side, 0, 0});
    m.positions.push_back({3, side, 0});
    m.faces.push_back({base, base + 1, base + 2});
    if (fraction < kSpeckAreaFraction) {
      const PreparedFrame p = prepare_frame(m, "speck.obj");
      EXPECT_EQ(p.report.dropped_specks, 1);
      EXPECT_EQ(p.mesh.face_count(), disk.face_count());
      EXPECT_NE(p.report.summary().find("dropped 1 speck (1 faces"), std::string::npos) << p.report.summary();
    } else {
      expect_error(ErrorCode::kNotADisk, "island.obj: 2 components", [&] { prepare_frame(m, "island.obj"); });
      PrepareOptions largest;
      largest.keep_largest_component = true;
      EXPECT_EQ(prepare_frame(m, "island.obj", largest).report.dropped_components, 1);
    }
  }
}

// End to end: a capture with every defect in every frame encodes at the default settings, each
// frame's repairs named in the report with its totals; --strict refuses the first frame, named.
TEST(SequenceEncoder, ACaptureWithEveryDefectEncodesAndNamesItsRepairs) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 6;
  synth.vertices = 3000;
  synth.texture_size = 64;
  synth.defects = kDefectAll;
  write_synthetic_capture(dir.path(), synth);
  const Capture capture = read_capture(dir.path());
  EXPECT_EQ(capture.generator_value("defects"), defect_names(kDefectAll));
  EncodeOptions options;
  options.texture = false;
  EncodeReport report;
  const Sequence sequence = encode_capture(capture, options, &report);
  EXPECT_TRUE(report.dropped.empty());
  ASSERT_EQ(report.frames.size(), 6u);
  for (const EncodedFrameReport& f : report.frames) {
    EXPECT_NE(f.repair.find("resolved"), std::string::npos) << f.repair;
    EXPECT_NE(f.repair.find("bow-tie"), std::string::npos) << f.repair;
    EXPECT_NE(f.repair.find("specks"), std::string::npos) << f.repair;
    EXPECT_GT(f.repair_totals.faces_changed, 100);
    EXPECT_GT(f.repair_totals.largest_move, 0.04);
  }
  options.strict = true;
  options.threads = 1;
  expect_error(ErrorCode::kInvalidMesh, "frame_0000.obj: ", [&] { encode_capture(capture, options); });
}

TEST(PrepareFrame, TorusWithABoundaryIsRejectedForItsHandle) {
  // A torus grid with one face removed: one boundary, Euler characteristic -1, genus 1.
  TriangleMesh t = testing::grid_mesh(12, [](double u, double v) {
    const double a = 2 * std::numbers::pi * u, b = 2 * std::numbers::pi * v;
    return Vec3((2 + std::cos(b)) * std::cos(a), (2 + std::cos(b)) * std::sin(a), std::sin(b));
  });
  // Weld the seams u = 0 ~ 1 and v = 0 ~ 1 by index.
  auto id = [](int i, int j) { return static_cast<int32_t>((j % 12) * 13 + (i % 12)); };
  for (Face& f : t.faces) {
    for (int32_t& v : f) v = id(v % 13, v / 13);
  }
  t.faces.erase(t.faces.begin());
  expect_error(ErrorCode::kNotADisk, "handle", [&] { prepare_frame(t, "torus.obj"); });
}

TEST(PrepareFrame, RealCapturesBecomeDisks) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  for (int frame : {0, 115, 231}) {
    char name[64];
    std::snprintf(name, sizeof name, "medusa-mediapipe-4d/capture/frame_%04d.obj", frame);
    const TriangleMesh m = read_mesh(data / name);
    const PreparedFrame p = prepare_frame(m, name);
    EXPECT_TRUE(is_disk(p.mesh)) << name;
    EXPECT_TRUE(p.report.holes.empty()) << name;
  }
  // The ICT neutral face area: rim, mouth and two eyes.
  const TriangleMesh ict = read_mesh(data / "ict-facekit/derived/face_area_neutral.obj", {.allow_missing_texture = true});
  ASSERT_EQ(MeshTopology(ict.faces, ict.vertex_count()).boundary_loops().size(), 4u);
  const PreparedFrame p = prepare_frame(ict, "face_area_neutral.obj");
  EXPECT_TRUE(is_disk(p.mesh));
  EXPECT_EQ(p.report.holes.size(), 3u);
  for (const FilledHole& h : p.report.holes) EXPECT_EQ(h.folded_faces, 0);
}

}  // namespace
}  // namespace facemorph
