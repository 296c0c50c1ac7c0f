#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "codec/encoder/conformal/double_cover.hpp"
#include "codec/encoder/conformal/untangle.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

using testing::kPi;

TriangleMesh flat_disk(int rings, int sectors) {
  return testing::polar_disk(rings, sectors, [](const Vec2& p) { return Vec3(p.x(), p.y(), 0); });
}

// Spherical cap of radius R over polar angle [0, θ0], parametrised by stereographic disk
// coordinates so the polar grid is nearly uniform on the cap.
TriangleMesh spherical_cap(int rings, int sectors, double R, double theta0) {
  const double t0 = std::tan(theta0 / 2);
  return testing::polar_disk(rings, sectors, [R, t0](const Vec2& p) {
    const double rho = p.norm() * t0;  // tan(θ/2)
    const double theta = 2 * std::atan(rho), phi = std::atan2(p.y(), p.x());
    return Vec3(R * std::sin(theta) * std::cos(phi), R * std::sin(theta) * std::sin(phi), R * std::cos(theta));
  });
}

double max_rim_radius_error(const DiskMap& map) {
  double error = 0;
  for (int v : map.rim) error = std::max(error, std::abs(map.disk[static_cast<size_t>(v)].norm() - 1));
  return error;
}

TEST(DoubleCover, IsClosedGenusZeroWithTheRightCounts) {
  const TriangleMesh disk = flat_disk(6, 18);
  const MeshTopology topology(disk.faces, disk.vertex_count());
  std::vector<uint8_t> on_boundary(disk.positions.size(), 0);
  int boundary = 0;
  for (int v = 0; v < disk.vertex_count(); ++v) {
    on_boundary[static_cast<size_t>(v)] = topology.is_boundary_vertex(v);
    boundary += topology.is_boundary_vertex(v);
  }
  const DoubleCover cover = build_double_cover(disk.faces, face_edge_lengths(disk), on_boundary);
  const MeshTopology closed(cover.faces, cover.vertex_count());
  EXPECT_TRUE(closed.is_manifold());
  EXPECT_TRUE(closed.boundary_loops().empty());
  EXPECT_EQ(closed.euler_characteristic(), 2);
  EXPECT_EQ(cover.vertex_count(), 2 * (disk.vertex_count() - boundary) + boundary);
  EXPECT_EQ(closed.edge_count(), 2 * topology.edge_count() - boundary);
  EXPECT_EQ(cover.faces.size(), 2 * disk.faces.size());
  for (int v = 0; v < cover.vertex_count(); ++v) EXPECT_EQ(cover.mirror[static_cast<size_t>(cover.mirror[static_cast<size_t>(v)])], v);
}

TEST(IntrinsicDelaunay, FlipsMakeEveryWeightNonNegativeAndKeepTheArea) {
  // A jittered flat mesh has many non-Delaunay edges.
  TriangleMesh m = flat_disk(8, 24);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.04, 0.04);
  for (size_t i = 1; i < m.positions.size() - 24; ++i) m.positions[i] += Vec3(jitter(rng), jitter(rng), 0);
  std::vector<Face> faces = m.faces;
  std::vector<CornerValues> lengths = face_edge_lengths(m);
  const double area_before = total_area(m.positions, m.faces);
  EXPECT_GT(flip_to_intrinsic_delaunay(faces, lengths), 0);
  const SparseMatrix K = laplacian_from_cotangents(faces, corner_cotangents_from_lengths(lengths), m.vertex_count());
  const MeshTopology topology(m.faces, m.vertex_count());
  for (int c = 0; c < K.outerSize(); ++c) {
    for (SparseMatrix::InnerIterator it(K, c); it; ++it) {
      if (it.row() == it.col()) continue;
      const bool boundary_pair =
          topology.is_boundary_vertex(static_cast<int>(it.row())) && topology.is_boundary_vertex(static_cast<int>(it.col()));
      if (!boundary_pair) {
        EXPECT_LE(it.value(), 1e-12);  // K_ij = -w_ij <= 0
      }
    }
  }
  double area_after = 0;
  for (const auto& l : lengths) {
    const double s = 0.5 * (l[0] + l[1] + l[2]);
    area_after += std::sqrt(std::max(s * (s - l[0]) * (s - l[1]) * (s - l[2]), 0.0));
  }
  EXPECT_NEAR(area_after, area_before, 1e-12);
}

// The largest corner angle of a mesh, in degrees.
double largest_angle_degrees(const TriangleMesh& mesh) {
  double largest = 0;
  for (const Face& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      const Vec3 a = mesh.positions[static_cast<size_t>(f[(k + 1) % 3])] - mesh.positions[static_cast<size_t>(f[k])];
      const Vec3 b = mesh.positions[static_cast<size_t>(f[(k + 2) % 3])] - mesh.positions[static_cast<size_t>(f[k])];
      largest = std::max(largest, std::acos(std::clamp(a.dot(b) / (a.norm() * b.norm()), -1.0, 1.0)) * 180 / kPi);
    }
  }
  return largest;
}

// A flat polar disk (6 rings of 18) with the ring-3 vertex 40 moved towards the edge 22-23 of ring
// 2 across its face: onto the point `along` of the way from 22 to 23, lifted `height` times the
// edge's length back towards where it was. Every face stays counter-clockwise.
TriangleMesh disk_with_a_cap(double along, double height) {
  TriangleMesh disk = flat_disk(6, 18);
  const int apex = 40, a = 22, b = 23;
  const Vec3 pa = disk.positions[a], pb = disk.positions[b];
  const Vec3 edge = pb - pa;
  Vec3 normal = Vec3(-edge.y(), edge.x(), 0).normalized();
  if (normal.dot(disk.positions[apex] - pa) < 0) normal = -normal;
  disk.positions[apex] = pa + along * edge + height * edge.norm() * normal;
  return disk;
}

bool every_face_counter_clockwise(const TriangleMesh& mesh) {
  for (const Face& f : mesh.faces) {
    const Vec3 &a = mesh.positions[static_cast<size_t>(f[0])], &b = mesh.positions[static_cast<size_t>(f[1])],
               &c = mesh.positions[static_cast<size_t>(f[2])];
    if ((b - a).cross(c - a).z() <= 0) return false;
  }
  return true;
}

// Preconditioning splits a cap at the foot of its altitude: two right angles, no angle above 150°
// left. A 160° cap is split (a threshold raised to 166° would leave it).
TEST(Preconditioning, ACapIsSplitAtTheFootOfItsAltitude) {
  TriangleMesh mesh = disk_with_a_cap(0.3, 0.0733);  // atan(h / 0.3) + atan(h / 0.7) = 20°: a 160° corner
  ASSERT_TRUE(every_face_counter_clockwise(mesh));
  const double before = largest_angle_degrees(mesh);
  ASSERT_GT(before, 155.0);
  ASSERT_LT(before, 165.0);
  std::vector<int> source(mesh.positions.size());
  const int vertices = mesh.vertex_count();
  const DiskPreconditioning report = precondition_disk(mesh, source);
  EXPECT_GE(report.split_caps, 1);
  EXPECT_EQ(report.caps_left, 0);
  EXPECT_LE(largest_angle_degrees(mesh), 150.0);
  EXPECT_GT(mesh.vertex_count(), vertices);
  EXPECT_EQ(source.size(), mesh.positions.size());
  for (size_t v = static_cast<size_t>(vertices); v < source.size(); ++v) EXPECT_EQ(source[v], -1);
}

// A cap whose apex nearly touches one end of its edge (the foot within a thousandth of it) is left
// standing and counted, not chased with a split beside the foot that would leave it standing and
// copy it into the neighbour (what stopped a real ICT frame after 64 rounds).
TEST(Preconditioning, ACapWhoseFootNearlyTouchesAnEndIsCountedNotChased) {
  TriangleMesh mesh = disk_with_a_cap(0.0004, 1e-6);
  ASSERT_TRUE(every_face_counter_clockwise(mesh));
  std::vector<int> source(mesh.positions.size());
  const DiskPreconditioning report = precondition_disk(mesh, source);
  EXPECT_GE(report.caps_left, 1);
  DiskMap map = conformal_disk_map(disk_with_a_cap(0.0004, 1e-6));
  EXPECT_EQ(count_flipped(map.disk, map.surface.faces), 0);
  EXPECT_GE(map.report.caps_left, 1);
}

// Needles everywhere: a grid squashed 100:1 with its columns jittered, so nearly every triangle is
// a cap. Preconditioning stops within its bounded rounds, and the map is an embedding.
TEST(Preconditioning, ANeedleMeshTerminatesAndMaps) {
  TriangleMesh mesh;
  const int columns = 40, rows = 8;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.45, 0.45);
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < columns; ++i) mesh.positions.emplace_back(i + (i > 0 && i < columns - 1 ? jitter(rng) : 0.0), 0.01 * j, 0);
  }
  for (int j = 0; j + 1 < rows; ++j) {
    for (int i = 0; i + 1 < columns; ++i) {
      const int a = j * columns + i, b = a + 1, c = a + columns, d = c + 1;
      mesh.faces.push_back({a, b, d});
      mesh.faces.push_back({a, d, c});
    }
  }
  ASSERT_GT(largest_angle_degrees(mesh), 170.0);
  TriangleMesh copy = mesh;
  std::vector<int> source(copy.positions.size());
  const DiskPreconditioning report = precondition_disk(copy, source);
  EXPECT_LE(report.rounds, 2 + 24 + 24);
  const DiskMap map = conformal_disk_map(mesh);
  for (const Vec2& w : map.disk) ASSERT_TRUE(w.allFinite());
  EXPECT_EQ(count_flipped(map.disk, map.surface.faces), 0)
      << conformal_method_name(map.report.method) << ": " << map.report.fallback_reason;
}

// Tutte's map, the last resort, needs nothing of the triangles' shapes: on a disk it is an
// embedding with the rim on the circle, and conformal_disk_map names it.
TEST(ConformalMap, TutteMapIsAnEmbedding) {
  TriangleMesh disk = flat_disk(10, 40);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> lift(-0.2, 0.2);
  for (Vec3& p : disk.positions) p.z() = lift(rng);
  const DiskMap map = conformal_disk_map(disk, {.method = ConformalMethod::kTutte});
  EXPECT_EQ(map.report.method, ConformalMethod::kTutte);
  EXPECT_EQ(count_flipped(map.disk, map.surface.faces), 0);
  EXPECT_LT(max_rim_radius_error(map), 1e-12);
  EXPECT_EQ(parse_conformal_method("tutte"), ConformalMethod::kTutte);
}

// The ICT frame that stopped fmenc (20 s, frame 42 at 30 fps: 21.4 s): it maps, by QIEM.
TEST(ConformalMap, TheIctFrameThatOnceStoppedTheEncoderMaps) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  testing::TempDir dir;
  const std::filesystem::path ict = testing::ict_speech_capture("21.4", "0.02", "30", dir / "ict");
  if (ict.empty()) GTEST_SKIP() << "make_capture.py did not run (python3?)";
  const TriangleMesh mesh = read_mesh(ict / "frame_00000.obj", {.allow_missing_texture = true});
  const PreparedFrame prepared = prepare_frame(mesh, "ict 21.4 s");
  std::vector<int> source(prepared.mesh.positions.size());
  TriangleMesh copy = prepared.mesh;
  const DiskPreconditioning report = precondition_disk(copy, source);
  EXPECT_LE(report.rounds, 16);
  const DiskMap map = conformal_disk_map(prepared.mesh);
  EXPECT_EQ(map.report.method, ConformalMethod::kQiem) << map.report.fallback_reason;
  EXPECT_EQ(measure_distortion(map).flipped, 0);
}

TEST(ConformalMap, AFlatDiskMapsToItself) {
  const TriangleMesh disk = flat_disk(24, 96);
  for (ConformalMethod method : {ConformalMethod::kLinear, ConformalMethod::kQiem}) {
    DiskMap map = conformal_disk_map(disk, {.method = method});
    EXPECT_EQ(map.report.method, method);
    normalize(map, Vec3(0, 0, 0), Vec3(0, 0.5, 0));
    double error = 0;
    for (size_t v = 0; v < map.disk.size(); ++v) {
      const Vec2 original = map.surface.positions[v].head<2>();
      // The normalisation puts (0, 0.5) on the positive imaginary axis: the identity.
      error = std::max(error, (map.disk[v] - original).norm());
    }
    // The linear map is exact here (the identity is harmonic and the rim is at arc length); QIEM
    // reaches the identity up to its discretisation.
    EXPECT_LT(error, method == ConformalMethod::kLinear ? 1e-9 : 2e-3) << conformal_method_name(method);
    EXPECT_LT(max_rim_radius_error(map), 1e-12);
  }
}

// QIEM runs to its tolerance. On a flat 2:1 ellipse the linear map (QIEM's start) is harmonic but
// not conformal; the converged map's angle error is the discretisation's. At the defaults the map is
// as good as a much tighter tolerance makes it, while stopping after the first step, or at a
// tolerance 10⁴ times looser, leaves it measurably worse.
TEST(ConformalMap, QiemRunsToItsToleranceNotItsFirstStep) {
  const TriangleMesh ellipse = testing::polar_disk(16, 64, [](const Vec2& p) { return Vec3(2 * p.x(), p.y(), 0); });
  auto mean_angle_error = [&](const ConformalOptions& options, int* steps) {
    const DiskMap map = conformal_disk_map(ellipse, options);
    if (steps) *steps = map.report.iterations;
    return measure_distortion(map).mean_degrees;
  };
  int steps = 0, tight_steps = 0, loose_steps = 0;
  const double defaults = mean_angle_error({}, &steps);
  const double tight = mean_angle_error({.max_iterations = 400, .energy_tolerance = 1e-11}, &tight_steps);
  const double loose = mean_angle_error({.energy_tolerance = 1e-3}, &loose_steps);
  const double one_step = mean_angle_error({.energy_tolerance = 1e9}, nullptr);
  const double linear = mean_angle_error({.method = ConformalMethod::kLinear}, nullptr);
  std::printf(
      "ellipse mean angle error: linear %.4f°, one step %.4f°, 1e-3 %.4f° (%d steps), defaults %.4f° (%d steps), 1e-11 %.4f° (%d steps)\n",
      linear, one_step, loose, loose_steps, defaults, steps, tight, tight_steps);
  EXPECT_LT(defaults, tight * 1.02 + 1e-3);
  EXPECT_GT(one_step, defaults * 1.5);
  EXPECT_GT(loose, defaults * 1.03);
  EXPECT_GT(linear, defaults * 3);
}

TEST(ConformalMap, SphericalCapHasTheAnalyticConformalFactor) {
  // Stereographic projection from the antipode: λ(w) = 2 R t0 / (1 + t0² |w|²), t0 = tan(θ0/2).
  const double R = 1.5, theta0 = 1.2, t0 = std::tan(theta0 / 2);
  double previous = 1e9;
  for (int rings : {8, 16, 32}) {
    DiskMap map = conformal_disk_map(spherical_cap(rings, 4 * rings, R, theta0));
    EXPECT_EQ(map.report.method, ConformalMethod::kQiem);
    normalize(map, Vec3(0, 0, R), map.surface.positions[1]);
    const Eigen::VectorXd lambda = conformal_factor(map);
    double error = 0;
    for (size_t v = 0; v < map.disk.size(); ++v) {
      const double exact = 2 * R * t0 / (1 + t0 * t0 * map.disk[v].squaredNorm());
      error = std::max(error, std::abs(lambda[static_cast<Eigen::Index>(v)] - exact) / exact);
    }
    EXPECT_LT(error, previous);
    previous = error;
  }
  EXPECT_LT(previous, 0.02);
}

TEST(ConformalMap, NormalisationUndoesAnyMoebiusPrecomposition) {
  const SyntheticFace face(Expression::kMixed, 2);
  const TriangleMesh mesh = face.truth_mesh(0.4, 3000);
  const Vec3 nose = face.position({0, -0.014}, 0.4), bridge = face.position({0, 0.012}, 0.4);
  DiskMap reference = conformal_disk_map(mesh);
  DiskMap moved = reference;
  normalize(reference, nose, bridge);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int trial = 0; trial < 3; ++trial) {
    DiskMap copy = moved;
    const DiskMoebius random{Complex(u(rng), u(rng)), 6 * u(rng)};
    for (Vec2& w : copy.disk) w = random(w);
    normalize(copy, nose, bridge);
    double error = 0;
    for (size_t v = 0; v < copy.disk.size(); ++v) error = std::max(error, (copy.disk[v] - reference.disk[v]).norm());
    EXPECT_LT(error, 1e-9);
  }
}

TEST(ConformalMap, IsIntrinsicRigidMotionsDoNotChangeTheNormalisedMap) {
  const SyntheticFace face(Expression::kSmile, 4);
  TriangleMesh mesh = face.truth_mesh(1.0, 2500);
  const Vec3 nose = face.position({0, -0.014}, 1.0), bridge = face.position({0, 0.012}, 1.0);
  DiskMap a = conformal_disk_map(mesh);
  normalize(a, nose, bridge);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 t(0.3, -1, 2);
  for (Vec3& p : mesh.positions) p = R * p + t;
  DiskMap b = conformal_disk_map(mesh);
  normalize(b, R * nose + t, R * bridge + t);
  double error = 0;
  for (size_t v = 0; v < a.disk.size(); ++v) error = std::max(error, (a.disk[v] - b.disk[v]).norm());
  EXPECT_LT(error, 1e-6);
}

TEST(ConformalMap, SyntheticFaceIsAngleConformalAndBijective) {
  const SyntheticFace face(Expression::kMixed, 1);
  const TriangleMesh mesh = face.truth_mesh(0.7, 8000);
  DiskMap qiem = conformal_disk_map(mesh);
  const DiskMap linear = conformal_disk_map(mesh, {.method = ConformalMethod::kLinear});
  const Distortion q = measure_distortion(qiem), l = measure_distortion(linear);
  EXPECT_EQ(q.flipped, 0);
  EXPECT_EQ(l.flipped, 0);
  EXPECT_LT(q.mean_degrees, 0.5);
  EXPECT_LT(q.p95_degrees, 1.5);
  EXPECT_LT(q.mean_degrees, l.mean_degrees / 5);  // the harmonic map is not conformal
  EXPECT_LT(q.mu_mean, 0.01);
  EXPECT_NEAR(qiem.report.energy, 4 * kPi, 0.02);  // a conformal degree-1 map has E = Area(S²)
  EXPECT_GE(qiem.report.energy_excess, 0.0);
  EXPECT_LT(max_rim_radius_error(qiem), 1e-12);
  EXPECT_GT(q.checkerboard_within_1_degree, 0.8);
  // Counter-clockwise rim on the disk, with the surface on its left.
  double twice_area = 0;
  for (size_t i = 0; i < qiem.rim.size(); ++i) {
    const Vec2& a = qiem.disk[static_cast<size_t>(qiem.rim[i])];
    const Vec2& b = qiem.disk[static_cast<size_t>(qiem.rim[(i + 1) % qiem.rim.size()])];
    twice_area += a.x() * b.y() - a.y() * b.x();
  }
  EXPECT_GT(twice_area, 0);
}

TEST(InverseDiskMap, RoundTripsSurfacePointsAndIsExactOnTheRim) {
  const SyntheticFace face(Expression::kMouth, 1);
  TriangleMesh mesh = face.truth_mesh(1.0, 4000);
  DiskMap map = conformal_disk_map(mesh);
  const InverseDiskMap inverse(map);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 2000; ++trial) {
    const int f = static_cast<int>(rng() % map.surface.faces.size());
    double a = u(rng), b = u(rng);
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    const Vec3 bary(1 - a - b, a, b);
    const Face& t = map.surface.faces[static_cast<size_t>(f)];
    const Vec2 w = bary[0] * map.disk[static_cast<size_t>(t[0])] + bary[1] * map.disk[static_cast<size_t>(t[1])] +
                   bary[2] * map.disk[static_cast<size_t>(t[2])];
    const Vec3 p = bary[0] * map.surface.positions[static_cast<size_t>(t[0])] + bary[1] * map.surface.positions[static_cast<size_t>(t[1])] +
                   bary[2] * map.surface.positions[static_cast<size_t>(t[2])];
    const auto hit = inverse.locate(w);
    ASSERT_TRUE(hit.has_value());
    EXPECT_LT((inverse.position(*hit) - p).norm(), 1e-9);
    EXPECT_LT((inverse.texture_uv(*hit) - (bary[0] * map.surface.uvs[static_cast<size_t>(map.surface.uv_faces[static_cast<size_t>(f)][0])] +
                                           bary[1] * map.surface.uvs[static_cast<size_t>(map.surface.uv_faces[static_cast<size_t>(f)][1])] +
                                           bary[2] * map.surface.uvs[static_cast<size_t>(map.surface.uv_faces[static_cast<size_t>(f)][2])]))
                  .norm(),
              1e-9);
  }
  // Every point of the unit circle lands on the boundary curve: at a rim vertex's angle, on it.
  for (int v : map.rim) {
    const Vec2 w = map.disk[static_cast<size_t>(v)].normalized();
    const auto hit = inverse.locate(w);
    ASSERT_TRUE(hit.has_value());
    EXPECT_LT((inverse.position(*hit) - map.surface.positions[static_cast<size_t>(v)]).norm(), 1e-9);
  }
  // Between two rim vertices on the circle: on the boundary edge joining them.
  const Vec2 a = map.disk[static_cast<size_t>(map.rim[0])], b = map.disk[static_cast<size_t>(map.rim[1])];
  const double angle = 0.5 * (std::atan2(a.y(), a.x()) + std::atan2(b.y(), b.x()));
  const auto mid = inverse.locate(Vec2(std::cos(angle), std::sin(angle)));
  ASSERT_TRUE(mid.has_value());
  const Vec3 pa = map.surface.positions[static_cast<size_t>(map.rim[0])], pb = map.surface.positions[static_cast<size_t>(map.rim[1])];
  const Vec3 q = inverse.position(*mid);
  EXPECT_LT(((q - pa).cross(pb - pa)).norm() / (pb - pa).squaredNorm(), 1e-9);  // on the segment's line
  EXPECT_FALSE(inverse.locate(Vec2(1.01, 0)).has_value());
}

TEST(ConformalMap, SplitsKeepTextureCoordinatesAndGeometry) {
  // A cap (an angle above 150°) and an obtuse boundary edge force splits; UVs must follow.
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {2, 0, 0}, {1, 0.1, 0.2}, {1, 1.5, 0.4}, {1, -1.2, 0.1}};
  m.faces = {{0, 2, 3}, {2, 1, 3}, {0, 4, 1}, {0, 1, 2}};
  m.uvs = {{0, 0}, {1, 0}, {0.5, 0.05}, {0.5, 0.75}, {0.5, -0.6}};
  m.uv_faces = m.faces;
  const PreparedFrame p = prepare_frame(m, "caps.obj");
  const DiskMap map = conformal_disk_map(p.mesh);
  EXPECT_GT(map.report.split_caps + map.report.split_obtuse_boundary + map.report.split_ears, 0);
  ASSERT_TRUE(map.surface.has_uvs());
  EXPECT_NEAR(total_area(map.surface.positions, map.surface.faces), total_area(p.mesh.positions, p.mesh.faces), 1e-12);
  // Splits subdivide the UV triangles with the faces: the total signed UV area is unchanged.
  auto uv_area = [](const TriangleMesh& mesh) {
    double sum = 0;
    for (const Face& t : mesh.uv_faces) {
      const Vec2 &a = mesh.uvs[static_cast<size_t>(t[0])], &b = mesh.uvs[static_cast<size_t>(t[1])],
                 &c = mesh.uvs[static_cast<size_t>(t[2])];
      sum += 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
    }
    return sum;
  };
  EXPECT_NEAR(uv_area(map.surface), uv_area(p.mesh), 1e-12);
  for (size_t v = static_cast<size_t>(p.mesh.vertex_count()); v < map.surface.positions.size(); ++v) EXPECT_EQ(map.source_vertex[v], -1);
}

TEST(ConformalMap, SplitsInterpolateVertexColours) {
  // The mesh of the test above, coloured by a linear function of position: every vertex a split
  // adds (on an edge, at a centroid) must carry exactly its position's colour.
  auto colour_of = [](const Vec3& p) { return Vec3(0.25 * p.x(), 0.2 * p.y() + 0.5, p.z()); };  // in [0, 1] on the mesh
  TriangleMesh m;
  m.positions = {{0, 0, 0}, {2, 0, 0}, {1, 0.1, 0.2}, {1, 1.5, 0.4}, {1, -1.2, 0.1}};
  m.faces = {{0, 2, 3}, {2, 1, 3}, {0, 4, 1}, {0, 1, 2}};
  for (const Vec3& p : m.positions) m.colours.push_back(colour_of(p));
  const PreparedFrame p = prepare_frame(m, "caps.ply");
  const DiskMap map = conformal_disk_map(p.mesh);
  EXPECT_GT(map.surface.vertex_count(), p.mesh.vertex_count());  // it did split
  ASSERT_TRUE(map.surface.has_colours());
  for (size_t v = 0; v < map.surface.positions.size(); ++v) {
    EXPECT_LT((map.surface.colours[v] - colour_of(map.surface.positions[v])).norm(), 1e-12) << "vertex " << v;
  }
  // And the inverse map interpolates them across the triangles.
  const InverseDiskMap inverse(map);
  for (const Vec2& w : {Vec2(0, 0), Vec2(0.3, -0.2), Vec2(-0.5, 0.4)}) {
    const auto hit = inverse.locate(w);
    ASSERT_TRUE(hit.has_value());
    EXPECT_LT((inverse.colour(*hit) - colour_of(inverse.position(*hit))).norm(), 1e-12);
  }
}

TEST(ConformalMap, HardInputIsHandledOrNamedNeverNaN) {
  // An ear (a boundary vertex of valence 1), very thin triangles and a needle: all handled.
  TriangleMesh disk = flat_disk(6, 24);
  const int32_t tip = disk.vertex_count();
  const auto& rim_vertex = disk.positions[static_cast<size_t>(disk.vertex_count() - 1)];
  disk.positions.push_back(rim_vertex * 1.2);  // a vertex outside, used by a single face
  const int32_t left = disk.vertex_count() - 2, right = disk.vertex_count() - 1;
  (void)left;
  // Find the boundary edge ending at `right` and hang an ear on it.
  const MeshTopology topology(disk.faces, disk.vertex_count() - 1);
  for (const auto& loop : topology.boundary_loops()) {
    for (size_t i = 0; i < loop.size(); ++i) {
      if (loop[(i + 1) % loop.size()] != right) continue;
      disk.faces.push_back({loop[(i + 1) % loop.size()], loop[i], tip});  // reversed: outside the loop
      break;
    }
  }
  // Squash one interior ring towards its neighbour: very thin triangles.
  for (int s = 0; s < 24; ++s) disk.positions[static_cast<size_t>(1 + 2 * 24 + s)] *= 0.5001 / 0.5;
  const PreparedFrame prepared = prepare_frame(disk, "hard.obj");
  for (ConformalMethod method : {ConformalMethod::kLinear, ConformalMethod::kQiem}) {
    const DiskMap map = conformal_disk_map(prepared.mesh, {.method = method});
    for (const Vec2& w : map.disk) ASSERT_TRUE(w.allFinite());
    EXPECT_EQ(measure_distortion(map).flipped, 0);
  }
  // Not a disk: a named error.
  testing::expect_error(ErrorCode::kNotADisk, "needs a disk", [] { conformal_disk_map(testing::icosphere(1, 1)); });
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown conformal method 'lscm'", [] { parse_conformal_method("lscm"); });
}

// QIEM can return without an error and still collapse the disk (measured on a 20k-vertex frame with
// 1 mm of noise: its whole disk within 1e-16, which untangling cannot repair). The finishing stage
// then starts again from the linear map, says why, and returns an embedding.
TEST(ConformalMap, ACollapsedDiskFallsBackToTheLinearMap) {
  const TriangleMesh disk = testing::polar_disk(8, 32, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0.3 * w.squaredNorm()); });
  DiskMap map = conformal_disk_map(disk, {.method = ConformalMethod::kLinear});
  const std::vector<Vec2> linear = map.disk;
  for (Vec2& w : map.disk) w = Vec2::Zero();  // what QIEM returned, rim included
  map.report.method = ConformalMethod::kQiem;
  DiskMap without = map;
  testing::expect_error(ErrorCode::kNumerical, "untangling the disk map failed", [&] { finish_disk_map(without, {}); });
  finish_disk_map(map, linear);
  EXPECT_EQ(map.report.method, ConformalMethod::kLinear);
  EXPECT_NE(map.report.fallback_reason.find("could not be untangled"), std::string::npos) << map.report.fallback_reason;
  EXPECT_EQ(count_flipped(map.disk, map.surface.faces), 0);
  for (size_t v = 0; v < linear.size(); ++v) EXPECT_LT((map.disk[v] - linear[v]).norm(), 1e-12);
}

// A scan whose noise is as large as its edges (3000 vertices, 4 mm) still maps to an embedding,
// by QIEM or by the linear map: on this frame the g++ build's QIEM collapsed the disk, which
// stopped the encoder before the fallback above.
TEST(ConformalMap, NoiseAsLargeAsTheEdgesStillMapsToAnEmbedding) {
  testing::TempDir dir;
  write_synthetic_capture(
      dir.path(),
      {.frames = 12, .expression = Expression::kTalk, .vertices = 3000, .remesh = true, .noise = 0.004, .seed = 7, .texture_size = 64});
  const PreparedFrame p = prepare_frame(read_mesh(dir.path() / "frame_0002.obj"), "frame_0002.obj");
  const DiskMap map = conformal_disk_map(p.mesh);
  for (const Vec2& w : map.disk) ASSERT_TRUE(w.allFinite());
  EXPECT_EQ(measure_distortion(map).flipped, 0) << map.report.fallback_reason;
}

TEST(ConformalMap, RealFaces) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  for (const char* name : {"medusa-mediapipe-4d/capture/frame_0000.obj", "medusa-mediapipe-4d/capture/frame_0150.obj"}) {
    const PreparedFrame p = prepare_frame(read_mesh(data / name), name);
    const DiskMap map = conformal_disk_map(p.mesh);
    const Distortion d = measure_distortion(map);
    EXPECT_EQ(map.report.method, ConformalMethod::kQiem) << map.report.fallback_reason;
    EXPECT_EQ(d.flipped, 0) << name;
    EXPECT_LE(d.mean_degrees, 2.6) << name;  // the issue targets 2.5; this PL mesh's floor is 2.3-2.6
    EXPECT_LE(d.p95_degrees, 8.0) << name;
  }
  const TriangleMesh ict = read_mesh(data / "ict-facekit/derived/face_area_neutral.obj", {.allow_missing_texture = true});
  const DiskMap map = conformal_disk_map(prepare_frame(ict, "ict").mesh);
  EXPECT_EQ(measure_distortion(map).flipped, 0);
  EXPECT_EQ(map.report.method, ConformalMethod::kQiem);
}

}  // namespace
}  // namespace facemorph
