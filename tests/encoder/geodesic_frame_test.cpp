// The geodesic frame (paper §4, method-notes §6): surface geodesics between disk points, the frame of
// a face's landmarks and its partition mesh, and Φ, the piecewise-affine registration through it.
#include "codec/encoder/encode/registration_store.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/registration/registration.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "format/error.hpp"

#include "codec/encoder/registration/partition_map.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"
#include "tests/encoder/disk_face_landmarks.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

namespace facemorph {
namespace {

using testing::expect_circle_onto_circle;
using testing::face;
using testing::face_points;
using testing::kPi;
using testing::max_landmark_error;
using testing::on_circle;

// A disk map whose disk is the polar grid itself and whose surface is `lift` of it: the surface is
// parametrised over the disk exactly (no conformal map involved), so its geodesics are known.
template <typename Lift>
DiskMap polar_map(int rings, int sectors, Lift&& lift) {
  DiskMap map;
  const TriangleMesh flat = testing::polar_disk(rings, sectors, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); });
  map.surface = flat;
  for (size_t v = 0; v < flat.positions.size(); ++v) {
    const Vec2 w = flat.positions[v].head<2>();
    map.disk.push_back(w);
    map.surface.positions[v] = lift(w);
  }
  for (int s = 0; s < sectors; ++s) map.rim.push_back(1 + (rings - 1) * sectors + s);  // outer ring, counter-clockwise
  return map;
}

double polyline_length(const std::vector<Vec3>& points) {
  double length = 0;
  for (size_t i = 1; i < points.size(); ++i) length += (points[i] - points[i - 1]).norm();
  return length;
}

// Whether two polylines of the disk meet anywhere but at an end they share (then only if they
// overlap along a piece). Independent of the frame's own crossing test.
bool curves_meet(const std::vector<Vec2>& c1, const std::vector<Vec2>& c2) {
  auto is_end = [](const std::vector<Vec2>& c, const Vec2& p) { return p == c.front() || p == c.back(); };
  for (size_t i = 0; i + 1 < c1.size(); ++i) {
    const Vec2 &p1 = c1[i], &q1 = c1[i + 1];
    const Vec2 lo1 = p1.cwiseMin(q1), hi1 = p1.cwiseMax(q1);
    for (size_t j = 0; j + 1 < c2.size(); ++j) {
      const Vec2 &p2 = c2[j], &q2 = c2[j + 1];
      if ((p2.cwiseMax(q2) - lo1).minCoeff() < 0 || (hi1 - p2.cwiseMin(q2)).minCoeff() < 0) continue;
      const double d1 = orient2d(p2, q2, p1), d2 = orient2d(p2, q2, q1), d3 = orient2d(p1, q1, p2), d4 = orient2d(p1, q1, q2);
      if (d1 * d2 < 0 && d3 * d4 < 0) return true;  // a proper crossing
      // Touching: allowed only at a shared curve end, and not along a collinear piece.
      for (const Vec2* p : {&p1, &q1}) {
        const double d = orient2d(p2, q2, *p);
        const bool on = d == 0 && (*p - p2).dot(*p - q2) <= 0;
        if (on && !(is_end(c1, *p) && is_end(c2, *p) && (*p == p2 || *p == q2))) return true;
      }
      for (const Vec2* p : {&p2, &q2}) {
        const double d = orient2d(p1, q1, *p);
        const bool on = d == 0 && (*p - p1).dot(*p - q1) <= 0;
        if (on && !(is_end(c1, *p) && is_end(c2, *p) && (*p == p1 || *p == q1))) return true;
      }
    }
  }
  return false;
}

TEST(CurvesMeet, TheTestsOwnCrossingCheck) {
  EXPECT_TRUE(curves_meet({{-1, 0}, {1, 0}}, {{0, -1}, {0, 1}}));                       // a crossing
  EXPECT_TRUE(curves_meet({{-1, 0}, {1, 0}}, {{0, 0}, {0, 1}}));                        // an end inside the other curve
  EXPECT_TRUE(curves_meet({{0, 0}, {1, 0}}, {{0, 0}, {0.5, 0}, {0.5, 1}}));             // a shared end, then overlapping
  EXPECT_FALSE(curves_meet({{0, 0}, {1, 0}}, {{0, 0}, {0, 1}}));                        // a shared end only
  EXPECT_FALSE(curves_meet({{0, 0}, {1, 0}, {2, 1}}, {{0, 0.1}, {1, 0.1}, {2, 1.1}}));  // parallel
}

// ---- geodesic_path ----

TEST(GeodesicPath, OnAPlanarDiskIsTheStraightSegment) {
  const DiskMap map = polar_map(24, 96, [](const Vec2& w) { return Vec3(2 * w.x(), 2 * w.y(), 0); });  // a disk of radius 2
  const Vec2 ends[][2] = {{{-0.7, 0.2}, {0.6, -0.35}}, {{0.05, 0.9}, {0.1, -0.92}}, {{-0.3, -0.3}, {0.31, 0.28}}, {{0, 0}, {0.5, 0.5}}};
  for (const auto& e : ends) {
    SCOPED_TRACE(::testing::Message() << "from (" << e[0].transpose() << ") to (" << e[1].transpose() << ")");
    const FramePath path = geodesic_path(map, e[0], e[1]);
    const double exact = 2 * (e[1] - e[0]).norm();
    ASSERT_GE(path.lengths.size(), 1u);
    EXPECT_NEAR(path.lengths.front(), exact, 1e-9);  // the pulled-back segment is already straight
    EXPECT_NEAR(path.lengths.back(), exact, 1e-9);
    EXPECT_NEAR(polyline_length(path.surface), exact, 1e-9);
    EXPECT_LT((path.surface.front() - Vec3(2 * e[0].x(), 2 * e[0].y(), 0)).norm(), 1e-12);
    EXPECT_LT((path.surface.back() - Vec3(2 * e[1].x(), 2 * e[1].y(), 0)).norm(), 1e-12);
    EXPECT_EQ(path.disk.front(), e[0]);
    EXPECT_EQ(path.disk.back(), e[1]);
    EXPECT_TRUE(path.converged);
    EXPECT_FALSE(path.straight);
    EXPECT_LT(path.angle_error, 1e-6);
    // Every disk point lies on the segment.
    for (const Vec2& w : path.disk) {
      const Vec2 d = e[1] - e[0];
      EXPECT_LT(std::abs(d.x() * (w - e[0]).y() - d.y() * (w - e[0]).x()) / d.norm(), 1e-12);
    }
  }
}

// The unit sphere's cap over the disk by inverse stereographic projection of s·w (s = 0.8: a cap of
// half-angle 2 atan 0.8 ≈ 77°). Straight disk segments off the centre are not great circles.
Vec3 sphere_cap(const Vec2& w) {
  const Vec2 z = 0.8 * w;
  const double r2 = z.squaredNorm();
  return Vec3(2 * z.x(), 2 * z.y(), 1 - r2) / (1 + r2);
}

TEST(GeodesicPath, OnASphericalCapIsTheGreatCircleArc) {
  const DiskMap coarse = polar_map(24, 96, sphere_cap), fine = polar_map(48, 192, sphere_cap);
  // Pairs whose straight disk segment pulls back 2.2%, 2.5% and 3.9% longer than the arc.
  const Vec2 ends[][2] = {{{-0.75, 0.35}, {0.75, 0.35}}, {{0.8, -0.1}, {-0.2, -0.8}}, {{-0.9, 0.3}, {0.3, 0.9}}};
  for (const auto& e : ends) {
    SCOPED_TRACE(::testing::Message() << "from (" << e[0].transpose() << ") to (" << e[1].transpose() << ")");
    const double arc = std::acos(std::clamp(sphere_cap(e[0]).dot(sphere_cap(e[1])), -1.0, 1.0));
    double previous_error = std::numeric_limits<double>::infinity();
    for (const DiskMap* map : {&coarse, &fine}) {
      const FramePath path = geodesic_path(*map, e[0], e[1]);
      const double corrected = path.lengths.back(), straight = path.lengths.front();
      EXPECT_NEAR(polyline_length(path.surface), corrected, 1e-12);
      EXPECT_TRUE(path.converged) << "angle error " << path.angle_error;
      EXPECT_LE(path.sweeps, 10);
      // An inscribed polyhedron's geodesics are a little shorter than the sphere's: its faces are
      // chords. Measured: 0.9-3.4e-4 at 24 rings, 0.8-1.0e-4 at 48; it shrinks with the mesh.
      const double error = std::abs(corrected - arc) / arc;
      EXPECT_LT(error, 5e-4) << "corrected " << corrected << ", arc " << arc;
      EXPECT_LT(error, previous_error);
      previous_error = error;
      // The straight disk segment pulled back is visibly longer: the correction did something.
      EXPECT_GT(straight, arc * 1.015) << "straight " << straight << ", arc " << arc;
      EXPECT_LT(corrected, straight);
      // The corrected path lies on the great circle's plane (through the centre) within mesh sag.
      const Vec3 normal = sphere_cap(e[0]).cross(sphere_cap(e[1])).normalized();
      for (const Vec3& x : path.surface) EXPECT_LT(std::abs(x.dot(normal)), map == &coarse ? 5e-3 : 1.5e-3);
    }
  }
}

TEST(GeodesicPath, OnACylinderIsTheUnrolledStraightLine) {
  // A cylinder of radius 0.7 about the y axis, parametrised over the disk through a radial
  // distortion φ(w) = w (0.25 + 0.75 |w|²) of the plane it unrolls onto (less than half way round):
  // geodesics are straight lines in φ's coordinates, of length |φ(a) - φ(b)|, and not straight on
  // the disk. These pairs' straight disk segments pull back 3.8%, 5.2% and 6.0% longer.
  const double R = 0.7;
  auto phi = [](const Vec2& w) -> Vec2 { return w * (0.25 + 0.75 * w.squaredNorm()); };
  auto cylinder = [&](const Vec2& w) {
    const Vec2 u = phi(w);
    return Vec3(R * std::sin(u.x() / R), u.y(), R * std::cos(u.x() / R));
  };
  const DiskMap map = polar_map(32, 128, cylinder);
  const Vec2 ends[][2] = {{{-0.8, 0.3}, {0.7, 0.45}}, {{-0.7, -0.5}, {0.7, -0.45}}, {{0.85, -0.3}, {0.2, 0.8}}};
  for (const auto& e : ends) {
    SCOPED_TRACE(::testing::Message() << "from (" << e[0].transpose() << ") to (" << e[1].transpose() << ")");
    const double exact = (phi(e[1]) - phi(e[0])).norm();
    const FramePath path = geodesic_path(map, e[0], e[1]);
    EXPECT_TRUE(path.converged) << "angle error " << path.angle_error;
    // The inscribed facets sag inside the cylinder: measured 7e-4 at 32 rings.
    EXPECT_LT(std::abs(path.lengths.back() - exact) / exact, 1.5e-3) << "corrected " << path.lengths.back() << ", exact " << exact;
    EXPECT_GT(path.lengths.front(), exact * 1.03) << "straight " << path.lengths.front();
    EXPECT_LT(path.lengths.back(), path.lengths.front());
  }
}

TEST(GeodesicPath, UncorrectedIsThePulledBackSegment) {
  const DiskMap map = polar_map(24, 96, sphere_cap);
  GeodesicFrameOptions options;
  options.correct_paths = false;
  const FramePath straight = geodesic_path(map, {-0.75, 0.35}, {0.75, 0.35}, options);
  EXPECT_EQ(straight.lengths.size(), 1u);
  EXPECT_EQ(straight.sweeps, 0);
  for (const Vec2& w : straight.disk) EXPECT_NEAR(w.y(), 0.35, 1e-12);  // the disk segment itself
  const FramePath corrected = geodesic_path(map, {-0.75, 0.35}, {0.75, 0.35});
  EXPECT_NEAR(corrected.lengths.front(), straight.lengths.front(), 1e-12);
  // The great circle through these two points is, in stereographic coordinates z = 0.8 w, the circle
  // |z - c|² = 1 + |c|² with c = (0, -1.003): it bows away from the centre (where the metric is
  // largest), to w_y = 0.517 on the axis.
  double highest = 0;
  for (const Vec2& w : corrected.disk) highest = std::max(highest, w.y());
  EXPECT_NEAR(highest, 0.517, 0.01);
}

TEST(GeodesicPath, BadInputIsANamedError) {
  const DiskMap map = polar_map(8, 32, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); });
  using testing::expect_error;
  expect_error(ErrorCode::kInvalidArgument, "coincide", [&] { geodesic_path(map, {0.1, 0.1}, {0.1, 0.1}); });
  expect_error(ErrorCode::kInvalidArgument, "outside the unit disk", [&] { geodesic_path(map, {0.1, 0.1}, {1.1, 0}); });
  expect_error(ErrorCode::kInvalidArgument, "not finite", [&] { geodesic_path(map, {std::nan(""), 0.1}, {0.5, 0}); });
  expect_error(ErrorCode::kInvalidArgument, "sample spacing", [&] { geodesic_path(map, {0, 0}, {0.5, 0}, {.sample_spacing = 0}); });
  expect_error(ErrorCode::kInvalidArgument, "max sweeps", [&] { geodesic_path(map, {0, 0}, {0.5, 0}, {.max_sweeps = -1}); });
  expect_error(ErrorCode::kInvalidArgument, "angle tolerance", [&] {
    geodesic_path(map, {0, 0}, {0.5, 0}, {.angle_tolerance = std::numeric_limits<double>::infinity()});
  });
  DiskMap broken = map;
  broken.disk.pop_back();
  expect_error(ErrorCode::kInvalidArgument, "disk points", [&] { geodesic_path(broken, {0, 0}, {0.5, 0}); });
  broken = map;
  broken.rim.clear();
  expect_error(ErrorCode::kInvalidArgument, "no rim", [&] { geodesic_path(broken, {0, 0}, {0.5, 0}); });
}

// ---- The frame of a flat disk, with the face's landmarks (registration_test.cpp's layout) ----

// The flat disk's frame for the face's landmarks: built once (the tests only read it).
const GeodesicFrame& flat_frame() {
  static const GeodesicFrame frame = [] {
    static const DiskMap map = polar_map(24, 96, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); });
    const DiskLandmarks l = face(true);
    return make_geodesic_frame(map, l.reference, l.on_rim);
  }();
  return frame;
}

TEST(GeodesicFrame, OnAFlatDiskEveryCurveIsItsStraightSegment) {
  const GeodesicFrame& frame = flat_frame();
  const DiskLandmarks l = face(true);
  ASSERT_EQ(frame.landmark_count, static_cast<int>(l.reference.size()));
  for (size_t j = 0; j < l.reference.size(); ++j) EXPECT_LT((frame.graph_points[j] - l.reference[j]).norm(), 1e-15);
  EXPECT_GT(frame.paths.size(), l.reference.size());
  EXPECT_EQ(frame.straight_paths, 0);
  EXPECT_EQ(frame.unconverged_paths, 0);
  for (const FramePath& path : frame.paths) {
    const Vec2 &a = frame.graph_points[static_cast<size_t>(path.from)], &b = frame.graph_points[static_cast<size_t>(path.to)];
    EXPECT_LT(path.from, path.to);
    EXPECT_EQ(path.disk.front(), a);
    EXPECT_EQ(path.disk.back(), b);
    for (const Vec2& w : path.disk) {
      const Vec2 d = b - a;
      EXPECT_LT(std::abs(d.x() * (w - a).y() - d.y() * (w - a).x()) / d.norm(), 1e-12);
    }
  }
}

TEST(FrameRegistration, AFrameRegisteredToItselfIsTheIdentity) {
  const GeodesicFrame& frame = flat_frame();
  const DiskLandmarks l = face(true);
  const DiskRegistration f = register_disks(l, {.method = RegistrationMethod::kFrame}, &frame);
  EXPECT_EQ(f.method, RegistrationMethod::kFrame);
  EXPECT_EQ(f.fallback, RegistrationFallback::kNone) << f.fallback_reason;
  ASSERT_NE(f.partition_map, nullptr);
  EXPECT_TRUE(f.check.ok());
  EXPECT_EQ(f.check.grid_points, static_cast<int>(frame.partition->faces().size()));
  EXPECT_LT(f.energy, 1e-24);
  EXPECT_LT(max_landmark_error(f, l), 1e-12);
  for (int j = -25; j <= 25; ++j) {
    for (int i = -25; i <= 25; ++i) {
      const Vec2 w(i / 25.0, j / 25.0);
      if (w.norm() > 1) continue;
      EXPECT_LT((f(w) - w).norm(), 1e-9) << "at (" << w.transpose() << ")";
      EXPECT_LT((f.jacobian(w) - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff(), 1e-9) << "at (" << w.transpose() << ")";
    }
  }
  expect_circle_onto_circle(f, 720, 1e-12);
}

TEST(FrameRegistration, MatchesTheLandmarksExactlyAndFollowsTheGmf) {
  // An opening mouth after a Möbius motion: Φ interpolates f̄ on the partition, so it hits every
  // landmark (all are partition vertices) as exactly as f̄ does and stays near f̄ between them.
  const DiskMoebius M{Complex(0.15, -0.1), 0.2};
  DiskLandmarks l = face(true);
  for (size_t j = 0; j < l.frame.size(); ++j) {
    Vec2 p = l.reference[j];
    if (j == 7 || j == 8 || j == 4) p.y() -= 0.08;  // lower lip and chin down
    if (j == 9 || j == 10) p.y() -= 0.04;           // mouth corners half as far
    l.frame[j] = M(p);
  }
  const GeodesicFrame& frame = flat_frame();
  const DiskRegistration gmf = register_disks(l);
  const DiskRegistration f = register_disks(l, {.method = RegistrationMethod::kFrame}, &frame);
  ASSERT_EQ(gmf.fallback, RegistrationFallback::kNone) << gmf.fallback_reason;
  ASSERT_EQ(f.fallback, RegistrationFallback::kNone) << f.fallback_reason;
  ASSERT_NE(f.partition_map, nullptr);
  EXPECT_TRUE(f.check.ok());
  EXPECT_GT(f.check.min_jacobian, 0);
  EXPECT_LT(max_landmark_error(f, l), 1e-9);
  EXPECT_LT(f.energy, 1e-18);
  EXPECT_GT(f.energy_moebius, 1e-3);
  // Φ at the partition vertices is f̄ there; elsewhere it is its piecewise-linear interpolant.
  const std::vector<Vec2>& V = frame.partition->vertices();
  double at_vertices = 0, between = 0;
  for (size_t i = 0; i < V.size(); ++i) at_vertices = std::max(at_vertices, (f(V[i]) - gmf(V[i])).norm());
  for (int j = -20; j <= 20; ++j) {
    for (int i = -20; i <= 20; ++i) {
      const Vec2 w(i / 20.0, j / 20.0);
      if (w.norm() > 1) continue;
      between = std::max(between, (f(w) - gmf(w)).norm());
      EXPECT_LT((f.smooth_base(w) - gmf.smooth(w)).norm(), 1e-15);  // smooth_base is f̄ (before the circle's projection)
    }
  }
  EXPECT_LT(at_vertices, 1e-12);
  EXPECT_GT(between, 1e-6);  // Φ is not f̄ itself
  EXPECT_LT(between, 0.02);  // but close to it: the partition is fine where f̄ bends
  // Inside a triangle the Jacobian is the triangle's constant one: the derivative of Φ there.
  for (const Face& t : frame.partition->faces()) {
    if (&t - frame.partition->faces().data() > 200) break;
    const Vec2 c = (V[static_cast<size_t>(t[0])] + V[static_cast<size_t>(t[1])] + V[static_cast<size_t>(t[2])]) / 3;
    const double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (f(c + Vec2(h, 0)) - f(c - Vec2(h, 0))) / (2 * h);
    J.col(1) = (f(c + Vec2(0, h)) - f(c - Vec2(0, h))) / (2 * h);
    EXPECT_LT((f.jacobian(c) - J).cwiseAbs().maxCoeff(), 1e-6);
  }
  expect_circle_onto_circle(f, 720, 1e-12);
}

TEST(FrameRegistration, AForcedFoldFallsBackToTheGmfWithAReason) {
  const GeodesicFrame& frame = flat_frame();
  const DiskLandmarks l = face(true);
  const DiskRegistration gmf = register_disks(l);
  const PartitionMesh& mesh = *frame.partition;
  std::vector<Vec2> images = mesh.vertices();
  // Swap the images of the two ends of an interior edge, the nose tip (landmark 0) and a neighbour:
  // the edge's triangles turn over.
  const auto t = std::find_if(mesh.faces().begin(), mesh.faces().end(), [](const Face& face) { return face[0] == 0; });
  ASSERT_NE(t, mesh.faces().end());
  std::swap(images[0], images[static_cast<size_t>((*t)[1])]);

  const DiskRegistration f = register_through_partition(frame, gmf, images, l);
  EXPECT_EQ(f.fallback, RegistrationFallback::kGmfInsteadOfFrame);
  EXPECT_EQ(f.partition_map, nullptr);
  EXPECT_NE(f.fallback_reason.find("folds"), std::string::npos) << f.fallback_reason;
  EXPECT_NE(f.fallback_reason.find("partition triangles are not positive"), std::string::npos) << f.fallback_reason;
  EXPECT_NE(f.fallback_reason.find("the GMF itself"), std::string::npos) << f.fallback_reason;
  EXPECT_STREQ(registration_fallback_name(f.fallback), "gmf-instead-of-frame");
  for (const Vec2& w : {Vec2(0.1, 0.2), Vec2(-0.5, 0.3), Vec2(0.0, -0.95)}) EXPECT_EQ(f(w), gmf(w));  // f̄ itself

  const DiskRegistration kept = register_through_partition(frame, gmf, images, l, false);
  EXPECT_EQ(kept.fallback, RegistrationFallback::kNone);
  ASSERT_NE(kept.partition_map, nullptr);
  EXPECT_FALSE(kept.check.ok());
  EXPECT_GE(kept.check.folded_points, 1);
  EXPECT_LT(kept.check.min_jacobian, 0);
  EXPECT_NE(kept.fallback_reason.find("fallback disabled"), std::string::npos) << kept.fallback_reason;
  EXPECT_GT(kept.energy, 1e-4);  // the nose tip now lands on its neighbour's image

  // The circle's images out of order: two neighbouring boundary vertices swapped.
  images = mesh.vertices();
  std::swap(images[static_cast<size_t>(mesh.boundary()[3])], images[static_cast<size_t>(mesh.boundary()[4])]);
  const DiskRegistration rim = register_through_partition(frame, gmf, images, l);
  EXPECT_EQ(rim.fallback, RegistrationFallback::kGmfInsteadOfFrame);
  EXPECT_NE(rim.fallback_reason.find("out of order"), std::string::npos) << rim.fallback_reason;
}

TEST(FrameRegistration, BadInputIsANamedError) {
  using testing::expect_error;
  const GeodesicFrame& frame = flat_frame();
  const DiskLandmarks l = face(true);
  const DiskRegistration gmf = register_disks(l);
  expect_error(ErrorCode::kInvalidArgument, "geodesic frame", [&] { register_disks(l, {.method = RegistrationMethod::kFrame}); });
  expect_error(ErrorCode::kInvalidArgument, "geodesic frame", [&] { register_disks(l, {.method = RegistrationMethod::kFrame}, nullptr); });
  GeodesicFrame empty;
  expect_error(ErrorCode::kInvalidArgument, "geodesic frame", [&] { register_disks(l, {.method = RegistrationMethod::kFrame}, &empty); });
  expect_error(ErrorCode::kInvalidArgument, "no partition mesh", [&] { register_through_partition(empty, gmf, {}, l); });
  std::vector<Vec2> images = frame.partition->vertices();
  images.pop_back();
  expect_error(ErrorCode::kInvalidArgument, "partition vertices", [&] { register_through_partition(frame, gmf, images, l); });
  images = frame.partition->vertices();
  images[5].y() = std::numeric_limits<double>::quiet_NaN();
  expect_error(ErrorCode::kInvalidArgument, "partition vertex 5 is not finite", [&] { register_through_partition(frame, gmf, images, l); });
  DiskLandmarks bad = l;
  bad.frame.pop_back();
  expect_error(ErrorCode::kInvalidArgument, "frame landmarks",
               [&] { register_through_partition(frame, gmf, frame.partition->vertices(), bad); });
  expect_error(ErrorCode::kInvalidArgument, "frame landmarks",
               [&] { register_disks(bad, {.method = RegistrationMethod::kFrame}, &frame); });
}

TEST(GeodesicFrame, BadInputIsANamedError) {
  using testing::expect_error;
  const DiskMap map = polar_map(12, 48, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); });
  const DiskLandmarks good = face(true);
  auto expect_bad = [&](const std::vector<Vec2>& points, const std::vector<uint8_t>& rim, const std::string& fragment) {
    expect_error(ErrorCode::kInvalidArgument, fragment, [&] { make_geodesic_frame(map, points, rim); });
  };
  expect_bad({{0, 0}, {0.1, 0}}, {}, "at least 3 landmarks");
  std::vector<uint8_t> rim = good.on_rim;
  rim.pop_back();
  expect_bad(good.reference, rim, "rim flags");
  std::vector<Vec2> points = good.reference;
  points[3].x() = std::numeric_limits<double>::infinity();
  expect_bad(points, good.on_rim, "landmark 3 is not finite");
  points = good.reference;
  points[2] = Vec2(0.9, 0.9);
  expect_bad(points, good.on_rim, "landmark 2 lies outside the unit disk");
  points = good.reference;
  points.back() *= 0.99;
  expect_bad(points, good.on_rim, "rim marker but does not lie on the circle");
  points = good.reference;
  points[5] = points[4];
  expect_bad(points, good.on_rim, "landmarks 4 and 5 coincide");
  expect_error(ErrorCode::kInvalidArgument, "graph boundary spacing",
               [&] { make_geodesic_frame(map, good.reference, good.on_rim, {.graph_boundary_spacing_degrees = 0}); });
  expect_error(ErrorCode::kInvalidArgument, "partition boundary spacing",
               [&] { make_geodesic_frame(map, good.reference, good.on_rim, {.partition_boundary_spacing_degrees = 45}); });
  DiskMap broken = map;
  broken.disk.resize(10);
  expect_error(ErrorCode::kInvalidArgument, "disk points", [&] { make_geodesic_frame(broken, good.reference, good.on_rim); });
}

TEST(PartitionMesh, BadTrianglesAreNamed) {
  using testing::expect_error;
  const std::vector<Vec2> square = {{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}};
  const PartitionMesh ok(square, {{0, 1, 2}, {0, 2, 3}});
  EXPECT_EQ(ok.boundary().size(), 4u);
  EXPECT_TRUE(ok.locate(Vec2(0.1, 0.2)).has_value());
  EXPECT_FALSE(ok.locate(Vec2(0.6, 0.6)).has_value());
  expect_error(ErrorCode::kInvalidArgument, "face 1 is not counter-clockwise", [&] { PartitionMesh(square, {{0, 1, 2}, {0, 3, 2}}); });
  expect_error(ErrorCode::kInvalidArgument, "face 0 has a vertex index out of range", [&] { PartitionMesh(square, {{0, 1, 7}}); });
  expect_error(ErrorCode::kInvalidArgument, "outside the unit disk", [&] { PartitionMesh({{0, 0}, {2, 0}, {0, 1}}, {{0, 1, 2}}); });
  // A triangle beside the origin: the boundary does not go round it.
  expect_error(ErrorCode::kInvalidArgument, "go round the origin", [&] {
    PartitionMesh({{0.1, 0.1}, {0.5, 0.1}, {0.1, 0.5}}, {{0, 1, 2}});
  });
}

// ---- The frame of a synthetic face, mapped as the encoder maps it ----

class FaceFrame : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new testing::TempDir;
    SynthOptions synth;
    synth.frames = 3;
    synth.vertices = 4000;
    synth.remesh = true;
    synth.noise = 0;
    synth.texture_size = 32;
    write_synthetic_capture(dir_->path(), synth);
    capture_ = new Capture(read_capture(dir_->path()));
    EncodeOptions options;
    options.texture = false;
    options.grid = 65;
    encoder_ = new SequenceEncoder(*capture_, options);
    map_frames(*encoder_);
    const std::shared_ptr<const MappedFrame> reference = encoder_->frame(0);
    landmarks_ = new DiskLandmarks(disk_landmarks(*capture_, 0, reference->map, 0, reference->map));
    frame_ = new GeodesicFrame(make_geodesic_frame(reference->map, landmarks_->reference, landmarks_->on_rim));
  }
  static void TearDownTestSuite() {
    delete frame_;
    delete landmarks_;
    delete encoder_;
    delete capture_;
    delete dir_;
  }
  static testing::TempDir* dir_;
  static Capture* capture_;
  static SequenceEncoder* encoder_;
  static DiskLandmarks* landmarks_;
  static GeodesicFrame* frame_;
};
testing::TempDir* FaceFrame::dir_ = nullptr;
Capture* FaceFrame::capture_ = nullptr;
SequenceEncoder* FaceFrame::encoder_ = nullptr;
DiskLandmarks* FaceFrame::landmarks_ = nullptr;
GeodesicFrame* FaceFrame::frame_ = nullptr;

TEST_F(FaceFrame, PartitionStartsWithTheGraphAndIsPositive) {
  const GeodesicFrame& frame = *frame_;
  const DiskLandmarks& l = *landmarks_;
  ASSERT_GE(l.reference.size(), 20u);
  ASSERT_NE(frame.partition, nullptr);
  EXPECT_EQ(frame.landmark_count, static_cast<int>(l.reference.size()));
  for (size_t j = 0; j < l.reference.size(); ++j) {
    const Vec2 expected = l.on_rim[j] ? Vec2(l.reference[j].normalized()) : l.reference[j];
    EXPECT_LT((frame.graph_points[j] - expected).norm(), 1e-15) << "landmark " << j;
  }
  const std::vector<Vec2>& V = frame.partition->vertices();
  ASSERT_GT(V.size(), frame.graph_points.size());
  for (size_t i = 0; i < frame.graph_points.size(); ++i) EXPECT_EQ(V[i], frame.graph_points[i]) << "graph point " << i;
  double area = 0;
  for (const Face& t : frame.partition->faces()) {
    const double a = orient2d(V[static_cast<size_t>(t[0])], V[static_cast<size_t>(t[1])], V[static_cast<size_t>(t[2])]);
    EXPECT_GT(a, 0);
    area += a / 2;
  }
  // The triangles tile a polygon inscribed in the circle with 2° spacing or finer: nearly π.
  EXPECT_NEAR(area, kPi, kPi * (1 - std::sin(kPi / 90) / (kPi / 90)) + 1e-9);
  for (int b : frame.partition->boundary()) EXPECT_NEAR(V[static_cast<size_t>(b)].norm(), 1.0, 1e-12);
  EXPECT_EQ(frame.unconforming_segments, 0);
}

TEST_F(FaceFrame, CurvesAreShorterGeodesicsThatDoNotCross) {
  const GeodesicFrame& frame = *frame_;
  ASSERT_GT(frame.paths.size(), 50u);
  int corrected = 0, shorter = 0;
  for (const FramePath& path : frame.paths) {
    EXPECT_EQ(path.disk.front(), frame.graph_points[static_cast<size_t>(path.from)]);
    EXPECT_EQ(path.disk.back(), frame.graph_points[static_cast<size_t>(path.to)]);
    ASSERT_FALSE(path.lengths.empty());
    EXPECT_NEAR(polyline_length(path.surface), path.lengths.back(), 1e-9 * path.lengths.back());
    if (path.straight) {
      EXPECT_FALSE(path.reason.empty());
      continue;
    }
    EXPECT_TRUE(path.reason.empty());
    ++corrected;
    EXPECT_LE(path.lengths.back(), path.lengths.front() * (1 + 1e-12));
    shorter += path.lengths.back() < path.lengths.front() * (1 - 1e-6);
  }
  EXPECT_EQ(corrected + frame.straight_paths, static_cast<int>(frame.paths.size()));
  // Measured on this face: all 112 curves corrected, converged and shorter than their pulled-back
  // segments (by up to 0.9%: a conformal map's straight segments are not geodesics where the face
  // is curved).
  EXPECT_GE(corrected, static_cast<int>(0.9 * frame.paths.size()));
  EXPECT_GE(shorter, static_cast<int>(0.8 * corrected));
  EXPECT_LE(frame.unconverged_paths, 2);
  for (size_t i = 0; i < frame.paths.size(); ++i) {
    for (size_t j = i + 1; j < frame.paths.size(); ++j) {
      EXPECT_FALSE(curves_meet(frame.paths[i].disk, frame.paths[j].disk))
          << "curves " << frame.paths[i].from << "-" << frame.paths[i].to << " and " << frame.paths[j].from << "-" << frame.paths[j].to;
    }
  }
}

TEST_F(FaceFrame, RegisteringTheReferenceToItselfIsTheIdentity) {
  const DiskRegistration f = register_disks(*landmarks_, {.method = RegistrationMethod::kFrame}, frame_);
  EXPECT_EQ(f.fallback, RegistrationFallback::kNone) << f.fallback_reason;
  ASSERT_NE(f.partition_map, nullptr);
  EXPECT_LT(max_landmark_error(f, *landmarks_), 1e-12);
  for (int j = -20; j <= 20; ++j) {
    for (int i = -20; i <= 20; ++i) {
      const Vec2 w(i / 20.0, j / 20.0);
      if (w.norm() > 1) continue;
      EXPECT_LT((f(w) - w).norm(), 1e-9) << "at (" << w.transpose() << ")";
    }
  }
}

TEST_F(FaceFrame, TheEncoderRegistersThroughTheFrame) {
  encoder_->options().registration.method = RegistrationMethod::kFrame;
  register_frames(*encoder_);
  ASSERT_NE(encoder_->geodesic_frame(), nullptr);
  EXPECT_EQ(encoder_->geodesic_frame()->graph_points, frame_->graph_points);  // the reference's frame, built once
  for (int i = 0; i < encoder_->frame_count(); ++i) {
    const std::shared_ptr<const DiskRegistration> registration = encoder_->registration(i);
    const DiskRegistration& f = *registration;
    EXPECT_EQ(f.method, RegistrationMethod::kFrame);
    if (f.fallback == RegistrationFallback::kNone) {
      ASSERT_NE(f.partition_map, nullptr) << "frame " << i;
      EXPECT_EQ(f.partition_map->partition, encoder_->geodesic_frame()->partition) << "frame " << i;  // one frame for all
    } else {
      EXPECT_FALSE(f.fallback_reason.empty());
    }
    const DiskLandmarks landmarks = encoder_->frame_disk_landmarks(i);
    EXPECT_LT(max_landmark_error(f, landmarks), f.fallback == RegistrationFallback::kNone ? 1e-9 : 1.0) << "frame " << i;
  }
  EXPECT_LT(((*encoder_->registration(0))(Vec2(0.3, -0.2)) - Vec2(0.3, -0.2)).norm(), 1e-9);
  // Other methods do not build a frame.
  encoder_->options().registration.method = RegistrationMethod::kGmf;
  register_frames(*encoder_);
  EXPECT_EQ(encoder_->geodesic_frame(), nullptr);
  EXPECT_EQ(encoder_->registration(1)->method, RegistrationMethod::kGmf);
}

// ---- The encoder's registration store ----

// Every field RegistrationStore writes, compared exactly, and the map itself at points over the disk
// and its circle: the same doubles, whether a Möbius map, a GMF or Φ.
void expect_same_registration(const DiskRegistration& a, const DiskRegistration& b) {
  EXPECT_EQ(a.method, b.method);
  EXPECT_EQ(a.form, b.form);
  EXPECT_EQ(a.moebius.a, b.moebius.a);
  EXPECT_EQ(a.moebius.theta, b.moebius.theta);
  ASSERT_EQ(a.steps.size(), b.steps.size());
  for (size_t k = 0; k < a.steps.size(); ++k) {
    EXPECT_EQ(a.steps[k].centres, b.steps[k].centres);
    EXPECT_EQ(a.steps[k].weights, b.steps[k].weights);
    EXPECT_EQ(a.steps[k].offset, b.steps[k].offset);
    EXPECT_EQ(a.steps[k].linear, b.steps[k].linear);
  }
  EXPECT_EQ(a.energy_moebius, b.energy_moebius);
  EXPECT_EQ(a.energy, b.energy);
  EXPECT_EQ(a.moebius_iterations, b.moebius_iterations);
  EXPECT_EQ(a.moebius_start, b.moebius_start);
  EXPECT_EQ(a.fallback, b.fallback);
  EXPECT_EQ(a.fallback_reason, b.fallback_reason);
  EXPECT_EQ(a.smoothing, b.smoothing);
  EXPECT_EQ(a.boundary_samples, b.boundary_samples);
  const BijectionCheck &ca = a.check, &cb = b.check;
  EXPECT_EQ(ca.grid_points, cb.grid_points);
  EXPECT_EQ(ca.refined_points, cb.refined_points);
  EXPECT_EQ(ca.folded_points, cb.folded_points);
  EXPECT_EQ(ca.min_jacobian, cb.min_jacobian);
  EXPECT_EQ(ca.min_area_ratio, cb.min_area_ratio);
  EXPECT_EQ(ca.worst_point, cb.worst_point);
  EXPECT_EQ(ca.stopped, cb.stopped);
  EXPECT_EQ(ca.boundary_samples, cb.boundary_samples);
  EXPECT_EQ(ca.boundary_order_breaks, cb.boundary_order_breaks);
  EXPECT_EQ(ca.max_boundary_radius_error, cb.max_boundary_radius_error);
  EXPECT_EQ(ca.clamped_points, cb.clamped_points);
  ASSERT_EQ(a.partition_map == nullptr, b.partition_map == nullptr);
  if (a.partition_map) {
    EXPECT_EQ(a.partition_map->partition, b.partition_map->partition);  // re-attached, not copied
    EXPECT_EQ(a.partition_map->images, b.partition_map->images);
    EXPECT_EQ(a.partition_map->jacobians, b.partition_map->jacobians);
  }
  for (int i = -20; i <= 20; ++i) {
    for (int j = -20; j <= 20; ++j) {
      const Vec2 w(i / 20.0, j / 20.0);
      if (w.norm() > 1) continue;
      ASSERT_EQ(a(w), b(w)) << "at (" << w.transpose() << ")";
      ASSERT_EQ(a.jacobian(w), b.jacobian(w)) << "at (" << w.transpose() << ")";
    }
  }
  for (int k = 0; k < 90; ++k) ASSERT_EQ(a(on_circle(2 * kPi * k / 90)), b(on_circle(2 * kPi * k / 90))) << "circle point " << k;
}

// Registrations of every kind: the OMT alone, a GMF, Φ, and the GMF that a folded Φ fell back to
// (with its reason), for an opening mouth after a Möbius motion.
std::vector<DiskRegistration> registrations_of_every_kind() {
  const DiskMoebius M{Complex(0.15, -0.1), 0.2};
  DiskLandmarks l = face(true);
  for (size_t j = 0; j < l.frame.size(); ++j) {
    Vec2 p = l.reference[j];
    if (j == 7 || j == 8 || j == 4) p.y() -= 0.08;
    l.frame[j] = M(p);
  }
  const GeodesicFrame& frame = flat_frame();
  std::vector<DiskRegistration> out;
  out.push_back(register_disks(l, {.method = RegistrationMethod::kMoebius}));
  out.push_back(register_disks(l));
  out.push_back(register_disks(l, {.method = RegistrationMethod::kFrame}, &frame));
  std::vector<Vec2> images = frame.partition->vertices();
  const auto t =
      std::find_if(frame.partition->faces().begin(), frame.partition->faces().end(), [](const Face& face) { return face[0] == 0; });
  std::swap(images[0], images[static_cast<size_t>((*t)[1])]);
  out.push_back(register_through_partition(frame, out[1], images, l));
  // Φ with every number it carries away from its default, so that a field the store forgot to
  // write and read shows.
  DiskRegistration odd = out[2];
  odd.form = GmfForm::kPaperGrid;
  odd.energy_moebius = 1.5, odd.energy = 2.5, odd.smoothing = 3.5;
  odd.moebius_iterations = 7;
  odd.moebius_start = MoebiusStart::kAlgebraic;
  odd.fallback = RegistrationFallback::kSubsteps;
  odd.fallback_reason = "a reason";
  odd.boundary_samples = 11;
  odd.check = {.grid_points = 1,
               .refined_points = 2,
               .folded_points = 3,
               .min_jacobian = 4.5,
               .min_area_ratio = 5.5,
               .worst_point = Vec2(0.1, 0.2),
               .stopped = true,
               .boundary_samples = 6,
               .boundary_order_breaks = 7,
               .max_boundary_radius_error = 8.5,
               .clamped_points = 9};
  out.push_back(odd);
  return out;
}

TEST(RegistrationStore, ASpilledRegistrationReadsBackAsTheSameMap) {
  using testing::expect_error;
  const std::vector<DiskRegistration> made = registrations_of_every_kind();
  ASSERT_EQ(made.size(), 5u);
  ASSERT_TRUE(made[0].steps.empty());
  ASSERT_FALSE(made[1].steps.empty());
  ASSERT_NE(made[2].partition_map, nullptr);
  ASSERT_EQ(made[3].fallback, RegistrationFallback::kGmfInsteadOfFrame);
  ASSERT_FALSE(made[3].fallback_reason.empty());
  const std::shared_ptr<const PartitionMesh> partition = flat_frame().partition;
  for (const SpillMode mode : {SpillMode::kSpill, SpillMode::kMemory}) {
    SCOPED_TRACE(mode == SpillMode::kSpill ? "spilled" : "in memory");
    RegistrationStore store(mode);
    store.reset(made.size() + 1, partition);
    for (size_t i = 0; i < made.size(); ++i) store.put(i, DiskRegistration(made[i]));
    EXPECT_EQ(store.spilled_bytes() > 0, mode == SpillMode::kSpill);
    for (size_t i = 0; i < made.size(); ++i) {
      SCOPED_TRACE("registration " + std::to_string(i));
      expect_same_registration(made[i], *store.get(i));
    }
    expect_error(ErrorCode::kInternal, "never stored", [&] { store.get(made.size()); });
    expect_error(ErrorCode::kInternal, "past its size", [&] { store.put(made.size() + 1, DiskRegistration(made[0])); });
    // Kept frames are renumbered in order.
    store.keep({1, 2});
    ASSERT_EQ(store.size(), 2u);
    expect_same_registration(made[1], *store.get(0));
    expect_same_registration(made[2], *store.get(1));
    // A store for registrations without a frame refuses Φ rather than lose its partition.
    store.reset(1, nullptr);
    expect_error(ErrorCode::kInternal, "another partition", [&] { store.put(0, DiskRegistration(made[2])); });
  }
  // The byte form: whole, it reads back; cut short or lengthened, or without the partition for Φ, it is refused.
  for (const DiskRegistration& f : made) {
    const std::vector<char> bytes = RegistrationStore::serialize(f);
    expect_same_registration(f, RegistrationStore::deserialize(bytes.data(), bytes.size(), partition));
    expect_error(ErrorCode::kInternal, "cut short", [&] { RegistrationStore::deserialize(bytes.data(), bytes.size() - 1, partition); });
    std::vector<char> longer = bytes;
    longer.push_back(0);
    expect_error(ErrorCode::kInternal, "left over", [&] { RegistrationStore::deserialize(longer.data(), longer.size(), partition); });
  }
  const std::vector<char> phi = RegistrationStore::serialize(made[2]);
  expect_error(ErrorCode::kInternal, "no partition", [&] { RegistrationStore::deserialize(phi.data(), phi.size(), nullptr); });
}

}  // namespace
}  // namespace facemorph
