#include "codec/encoder/synth/synth.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace facemorph {
namespace {

using testing::expect_error;
using testing::TempDir;

SynthOptions small(int frames) {
  SynthOptions o;
  o.frames = frames;
  o.vertices = 3000;
  o.texture_size = 64;
  o.noise = 0;
  return o;
}

TEST(Synth, CaptureIsReadableAndEveryFrameIsAFaceSizedTexturedDisk) {
  TempDir dir;
  write_synthetic_capture(dir.path(), small(4));
  const Capture c = read_capture(dir.path());
  ASSERT_EQ(c.frames.size(), 4u);
  EXPECT_EQ(c.units, "m");
  EXPECT_DOUBLE_EQ(c.frames[3].time, 0.1);
  EXPECT_GE(c.landmark_names.size(), 20u);
  int rim_markers = 0;
  for (const auto& name : c.landmark_names) rim_markers += name.starts_with("rim_");
  EXPECT_GE(rim_markers, 6);
  EXPECT_EQ(c.generator_value("name"), "fmsynth");
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const TriangleMesh m = read_mesh(c.mesh_path(i));
    EXPECT_NEAR(m.vertex_count(), 3000, 300);
    EXPECT_TRUE(m.has_uvs());
    EXPECT_TRUE(std::filesystem::exists(m.texture));
    const PreparedFrame p = prepare_frame(m, c.frames[i].mesh.string());
    EXPECT_FALSE(p.report.changed()) << p.report.summary();
    Vec3 lo = m.positions[0], hi = lo;
    for (const Vec3& q : m.positions) {
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    EXPECT_NEAR(hi.x() - lo.x(), 0.16, 0.01);  // about 16 x 20 cm in metres
    EXPECT_NEAR(hi.y() - lo.y(), 0.20, 0.02);
    // Rim markers lie on the boundary loop.
    for (size_t l = 0; l < c.landmark_names.size(); ++l) {
      if (!c.landmark_names[l].starts_with("rim_")) continue;
      double nearest = 1e9;
      for (int v : p.rim) nearest = std::min(nearest, (p.mesh.positions[static_cast<size_t>(v)] - c.landmarks[i][l]).norm());
      EXPECT_LT(nearest, 0.006) << c.landmark_names[l];
    }
  }
}

TEST(Synth, FramesSampleTheExactSurfaceAndLandmarksFollowIt) {
  TempDir dir;
  const SynthOptions o = small(3);
  write_synthetic_capture(dir.path(), o);
  const Capture c = read_capture(dir.path());
  const SyntheticFace face(o.expression, o.seed);
  const MaterialSampling sampling = sample_material_ellipse(o.vertices, false, 0);
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const TriangleMesh m = read_mesh(c.mesh_path(i));
    ASSERT_EQ(m.positions.size(), sampling.points.size());
    for (size_t v = 0; v < m.positions.size(); v += 97) {
      EXPECT_LT((m.positions[v] - face.position(sampling.points[v], c.frames[i].time)).norm(), 1e-7);  // 7 digits
    }
    const int nose = c.landmark_index("nose_tip");
    ASSERT_GE(nose, 0);
    EXPECT_LT((c.landmarks[i][static_cast<size_t>(nose)] - face.position({0, -0.014}, c.frames[i].time)).norm(), 1e-9);
  }
}

TEST(Synth, ExpressionsAnimateSmoothly) {
  const SyntheticFace blink(Expression::kBlink, 1), mouth(Expression::kMouth, 1), smile(Expression::kSmile, 1);
  double most = 0, least = 1;
  for (double t = 0; t < 3; t += 0.01) {
    most = std::max(most, blink.weights(t).blink);
    least = std::min(least, blink.weights(t).blink);
  }
  EXPECT_GT(most, 0.95);
  EXPECT_LT(least, 0.01);
  // The jaw drops the lower lip; a smile lifts the mouth corners; both continuously in time.
  const Vec2 lower_lip(0, -0.058), corner(0.023, -0.046);
  EXPECT_LT(mouth.position(lower_lip, 1.0).y(), mouth.position(lower_lip, 0.0).y() - 0.005);
  EXPECT_GT(smile.position(corner, 1.5).y(), smile.position(corner, 0.0).y() + 0.002);
  for (double t = 0; t < 2; t += 0.05) {
    EXPECT_LT((mouth.position(lower_lip, t + 1e-4) - mouth.position(lower_lip, t)).norm(), 1e-4);
  }
  // The texture changes with the blink: the eye centre is iris when open, eyelid when closed.
  double open_t = 0, closed_t = 0;
  for (double t = 0; t < 3; t += 0.001) {
    if (blink.weights(t).blink < 0.01) open_t = t;
    if (blink.weights(t).blink > 0.99) closed_t = t;
  }
  EXPECT_NE(blink.color({0.032, 0.025}, open_t), blink.color({0.032, 0.025}, closed_t));
}

// --speech-rate r: the mouth at time t is the normal face's mouth at r t; blinks, brows and smiles
// keep their own time, and r = 1 is the face as it always was.
TEST(Synth, SpeechRateSpeedsUpOnlyTheMouth) {
  for (Expression e : {Expression::kTalk, Expression::kMixed}) {
    const SyntheticFace normal(e, 1), fast(e, 1, 0, 2.5), same(e, 1, 0, 1.0);
    for (double t : {0.0, 0.13, 0.41, 0.9, 1.7}) {
      const ExpressionWeights w = fast.weights(t), at = normal.weights(2.5 * t), now = normal.weights(t);
      EXPECT_DOUBLE_EQ(w.jaw, at.jaw) << t;
      EXPECT_DOUBLE_EQ(w.pucker, at.pucker) << t;
      EXPECT_DOUBLE_EQ(w.blink, now.blink) << t;
      EXPECT_DOUBLE_EQ(w.brow, now.brow) << t;
      EXPECT_DOUBLE_EQ(w.smile, now.smile) << t;
      EXPECT_DOUBLE_EQ(same.weights(t).jaw, now.jaw) << t;
    }
    EXPECT_NE(fast.weights(0.13).jaw, normal.weights(0.13).jaw);
  }
}

TEST(Synth, RemeshGivesEveryFrameItsOwnConnectivity) {
  TempDir dir;
  SynthOptions o = small(3);
  o.remesh = true;
  write_synthetic_capture(dir.path(), o);
  const Capture c = read_capture(dir.path());
  const TriangleMesh a = read_mesh(c.mesh_path(0)), b = read_mesh(c.mesh_path(1));
  EXPECT_NE(a.positions.size(), b.positions.size());
  for (const TriangleMesh* m : {&a, &b}) {
    const MeshTopology t(m->faces, m->vertex_count());
    EXPECT_TRUE(t.is_manifold());
    EXPECT_EQ(t.boundary_loops().size(), 1u);
    EXPECT_EQ(t.euler_characteristic(), 1);
  }
}

TEST(Synth, NoiseMovesVerticesAlongTheNormalByItsStandardDeviation) {
  TempDir dir;
  SynthOptions o = small(1);
  o.noise = 0.001;
  write_synthetic_capture(dir.path(), o);
  const TriangleMesh m = read_mesh(read_capture(dir.path()).mesh_path(0));
  const SyntheticFace face(o.expression, o.seed);
  const MaterialSampling sampling = sample_material_ellipse(o.vertices, false, 0);
  double sum2 = 0, tangential = 0;
  for (size_t v = 0; v < m.positions.size(); ++v) {
    const Vec3 d = m.positions[v] - face.position(sampling.points[v], 0);
    const Vec3 n = face.normal(sampling.points[v], 0);
    sum2 += d.squaredNorm();
    tangential = std::max(tangential, (d - d.dot(n) * n).norm());
  }
  EXPECT_NEAR(std::sqrt(sum2 / m.positions.size()), 0.001, 0.0001);
  EXPECT_LT(tangential, 1e-6);
}

TEST(Synth, TruthMeshAndBadOptions) {
  const SyntheticFace face(Expression::kMixed, 3);
  const TriangleMesh truth = face.truth_mesh(0.5, 5000);
  EXPECT_NEAR(truth.vertex_count(), 5000, 500);
  EXPECT_TRUE(truth.has_uvs());
  TempDir dir;
  SynthOptions o = small(1);
  o.vertices = 10;
  expect_error(ErrorCode::kInvalidArgument, "--vertices", [&] { write_synthetic_capture(dir.path(), o); });
  o = small(0);
  expect_error(ErrorCode::kInvalidArgument, "--frames", [&] { write_synthetic_capture(dir.path(), o); });
  expect_error(ErrorCode::kInvalidArgument, "unknown expression 'grin'", [] { parse_expression("grin"); });
}

// fmsynth --head --holes (issue 47 part 2's input): one surface whose outer rim is the neck, with
// five holes (eyes, mouth, nostrils), manifold and consistently wound (the encoder's preparation
// changes nothing but fills the holes), the face part sampling the exact face and the rim markers
// on the neck.
TEST(Synth, WholeHeadIsOneSurfaceWithTheNeckAsRimAndFiveHoles) {
  TempDir dir;
  SynthOptions o = small(2);
  o.vertices = 2000;
  o.holes = true;
  o.whole_head = true;
  write_synthetic_capture(dir.path(), o);
  const Capture c = read_capture(dir.path());
  EXPECT_EQ(c.generator_value("surface"), "whole head to the neck");
  const SyntheticFace face(o.expression, o.seed);
  const HeadSampling head = sample_head(o.vertices, face, true, true);
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const TriangleMesh m = read_mesh(c.mesh_path(i));
    ASSERT_EQ(m.vertex_count(), head.face_vertices + static_cast<int>(head.back.size()));
    const MeshTopology topology(m.faces, m.vertex_count());
    EXPECT_TRUE(topology.is_manifold());
    EXPECT_EQ(topology.component_count(), 1);
    ASSERT_EQ(topology.boundary_loops().size(), 6u);
    // The face's vertices are the exact face; the neck reaches 0.09-0.13 m below the chin.
    for (size_t v = 0; v < head.face.points.size(); v += 97) {
      EXPECT_LT((m.positions[v] - face.position(head.face.points[v], c.frames[i].time)).norm(), 1e-6);
    }
    double lowest = 0;
    for (const Vec3& p : m.positions) lowest = std::min(lowest, p.y());
    EXPECT_GT(-lowest, 0.19);
    EXPECT_LT(-lowest, 0.24);
    const PreparedFrame p = prepare_frame(m, c.frames[i].mesh.string());
    EXPECT_EQ(p.report.holes.size(), 5u) << p.report.summary();
    EXPECT_EQ(p.report.faces_changed, 0) << p.report.summary();
    EXPECT_EQ(p.report.vertices_changed, 0) << p.report.summary();
    // The rim the encoder keeps is the neck: every neck vertex is on it, and so are the markers.
    EXPECT_EQ(p.rim.size(), static_cast<size_t>(head.neck_count));
    for (size_t l = 0; l < c.landmark_names.size(); ++l) {
      if (!c.landmark_names[l].starts_with("rim_")) continue;
      double nearest = 1e9;
      for (int v : p.rim) nearest = std::min(nearest, (p.mesh.positions[static_cast<size_t>(v)] - c.landmarks[i][l]).norm());
      EXPECT_LT(nearest, 1e-6) << c.landmark_names[l];
    }
  }
  o.remesh = true;
  expect_error(ErrorCode::kInvalidArgument, "--head", [&] { write_synthetic_capture(dir.path() / "x", o); });
}

// The head's connectivity is manifold at every density, with one neck rim and five holes: cutting the
// holes by centroid left a bow tie at 1500 and 2000 vertices (a nostril's two triangles meeting at a
// corner), which the generator now cuts through (close_bow_ties).
TEST(Synth, WholeHeadIsManifoldAtEveryVertexCount) {
  const SyntheticFace face(Expression::kMixed, 1);
  for (int vertices : {600, 1000, 1500, 2000, 2500, 3000, 4500, 6000}) {
    SCOPED_TRACE(vertices);
    for (bool whole_head : {false, true}) {
      const HeadSampling head = sample_head(vertices, face, true, whole_head);
      const MeshTopology topology(head.faces, head.face_vertices + static_cast<int>(head.back.size()));
      EXPECT_TRUE(topology.non_manifold_vertices().empty()) << "vertex " << topology.non_manifold_vertices().front();
      EXPECT_TRUE(topology.non_manifold_edges().empty());
      EXPECT_TRUE(topology.inconsistently_oriented_edges().empty());
      EXPECT_EQ(topology.referenced_vertex_count(), topology.vertex_count());
      EXPECT_EQ(topology.component_count(), 1);
      EXPECT_EQ(topology.boundary_loops().size(), 6u);  // the face's rim or the neck, and five holes
    }
  }
}

}  // namespace
}  // namespace facemorph
