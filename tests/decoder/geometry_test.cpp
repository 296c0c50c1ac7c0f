#include "codec/core/geometry/differential.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

using testing::kPi;

std::vector<bool> boundary_flags(const TriangleMesh& m) {
  const MeshTopology topo(m.faces, m.vertex_count());
  std::vector<bool> flags(m.positions.size());
  for (int v = 0; v < m.vertex_count(); ++v) flags[static_cast<size_t>(v)] = topo.is_boundary_vertex(v);
  return flags;
}

// Flat square with interior vertices jittered: an irregular planar mesh.
TriangleMesh jittered_plane(int n, unsigned seed) {
  TriangleMesh m = testing::grid_mesh(n, [](double u, double v) { return Vec3(u, v, 0); });
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3 / n, 0.3 / n);
  const auto flags = boundary_flags(m);
  for (size_t i = 0; i < m.positions.size(); ++i) {
    if (!flags[i]) m.positions[i] += Vec3(jitter(rng), jitter(rng), 0);
  }
  return m;
}

TEST(Laplacian, IsSymmetricPositiveSemidefiniteWithZeroRowSums) {
  const TriangleMesh m = testing::icosphere(1.3, 2);
  const SparseMatrix K = cotangent_laplacian(m.positions, m.faces);
  EXPECT_LT((SparseMatrix(K.transpose()) - K).norm(), 1e-12);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(K.rows());
  EXPECT_LT((K * ones).norm(), 1e-10);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd x(K.rows());
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = normal(rng);
    EXPECT_GE(x.dot(K * x), -1e-10);
  }
}

TEST(Laplacian, AnnihilatesLinearFunctionsInTheInteriorOfAFlatMesh) {
  const TriangleMesh m = jittered_plane(12, 3);
  const SparseMatrix K = cotangent_laplacian(m.positions, m.faces);
  const auto flags = boundary_flags(m);
  Eigen::VectorXd f(K.rows());
  for (Eigen::Index i = 0; i < f.size(); ++i) {
    f[i] = 2.0 * m.positions[static_cast<size_t>(i)].x() - 3.0 * m.positions[static_cast<size_t>(i)].y() + 0.5;
  }
  const Eigen::VectorXd Kf = K * f;
  for (Eigen::Index i = 0; i < f.size(); ++i) {
    if (!flags[static_cast<size_t>(i)]) {
      EXPECT_NEAR(Kf[i], 0.0, 1e-12);
    }
  }
}

TEST(Laplacian, CotangentsFromEdgeLengthsMatchEmbeddedOnes) {
  const TriangleMesh m = jittered_plane(6, 11);
  std::vector<CornerValues> lengths(m.faces.size());
  for (size_t f = 0; f < m.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      lengths[f][k] =
          (m.positions[static_cast<size_t>(m.faces[f][(k + 1) % 3])] - m.positions[static_cast<size_t>(m.faces[f][(k + 2) % 3])]).norm();
    }
  }
  const auto intrinsic = corner_cotangents_from_lengths(lengths);
  const auto embedded = corner_cotangents(m.positions, m.faces);
  for (size_t f = 0; f < m.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(intrinsic[f][k], embedded[f][k], 1e-9);
  }
}

TEST(Angles, SumToPiAndDegenerateTrianglesStayFinite) {
  const TriangleMesh m = jittered_plane(5, 1);
  for (const auto& a : corner_angles(m.positions, m.faces)) EXPECT_NEAR(a[0] + a[1] + a[2], kPi, 1e-12);
  const std::vector<Vec3> sliver = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  const std::vector<Face> face = {{0, 1, 2}};
  for (const auto& c : corner_cotangents(sliver, face)) {
    for (double value : c) EXPECT_TRUE(std::isfinite(value));
  }
}

TEST(Areas, MixedVoronoiAreasPartitionTheSurface) {
  const TriangleMesh m = jittered_plane(9, 5);
  EXPECT_NEAR(mixed_voronoi_areas(m.positions, m.faces).sum(), 1.0, 1e-12);
  EXPECT_NEAR(barycentric_areas(m.positions, m.faces).sum(), 1.0, 1e-12);
  const TriangleMesh s = testing::icosphere(2.0, 3);
  EXPECT_NEAR(mixed_voronoi_areas(s.positions, s.faces).sum(), total_area(s.positions, s.faces), 1e-10);
}

TEST(Areas, SphereAreaAndVolumeConvergeToTheAnalyticValues) {
  const double r = 2.0;
  double previous_area_error = 1e9, previous_volume_error = 1e9;
  for (int level = 2; level <= 5; ++level) {
    const TriangleMesh s = testing::icosphere(r, level);
    const double area_error = std::abs(total_area(s.positions, s.faces) - 4 * kPi * r * r);
    const double volume_error = std::abs(signed_volume(s.positions, s.faces) - 4.0 / 3.0 * kPi * r * r * r);
    EXPECT_GT(signed_volume(s.positions, s.faces), 0);  // outward orientation
    EXPECT_LT(area_error, previous_area_error / 3.5);   // second order: /4 per level
    EXPECT_LT(volume_error, previous_volume_error / 3.5);
    previous_area_error = area_error;
    previous_volume_error = volume_error;
  }
  EXPECT_LT(previous_area_error / (4 * kPi * r * r), 1e-3);
}

TEST(MeanCurvature, PlaneHasZeroCurvature) {
  const TriangleMesh m = jittered_plane(10, 9);
  const Eigen::VectorXd H = mean_curvature(m.positions, m.faces, boundary_flags(m));
  EXPECT_LT(H.cwiseAbs().maxCoeff(), 1e-10);
}

TEST(MeanCurvature, SphereWithOutwardNormalsHasMinusOneOverR) {
  const double r = 1.7;
  double previous = 1e9;
  for (int level = 2; level <= 5; ++level) {
    const TriangleMesh s = testing::icosphere(r, level);
    const Eigen::VectorXd H = mean_curvature(s.positions, s.faces, std::vector<bool>(s.positions.size(), false));
    const double error = (H.array() + 1.0 / r).abs().maxCoeff() * r;
    EXPECT_LT(H.maxCoeff(), 0.0);      // bends away from the outward normal
    EXPECT_LT(error, previous / 3.0);  // second order
    previous = error;
  }
  EXPECT_LT(previous, 0.01);
  const auto normals = vertex_normals(testing::icosphere(r, 3).positions, testing::icosphere(r, 3).faces);
  const TriangleMesh s = testing::icosphere(r, 3);
  for (size_t i = 0; i < s.positions.size(); ++i) EXPECT_GT(normals[i].dot(s.positions[i]), 0.999 * r);
}

TEST(MeanCurvature, CylinderHasHalfTheCurvatureAndConverges) {
  const double r = 0.8;
  double previous = 1e9;
  for (int n : {16, 32, 64}) {
    // A triangular lattice (odd rows offset by half a cell) wrapped on a half cylinder; faces
    // counter-clockwise in (u around the axis, v along it), so normals point outward. On an
    // aligned square grid the formula happens to be exact, which would make the test vacuous.
    TriangleMesh c;
    const int rows = n, cols = n;
    for (int j = 0; j <= rows; ++j) {
      for (int i = 0; i <= cols; ++i) {
        const double a = kPi * (0.05 + 0.9 * (i + 0.5 * (j % 2)) / (cols + 0.5));
        c.positions.emplace_back(r * std::cos(a), r * std::sin(a), 2.0 * j / rows);
      }
    }
    auto id = [cols](int i, int j) { return static_cast<int32_t>(j * (cols + 1) + i); };
    for (int j = 0; j < rows; ++j) {
      for (int i = 0; i < cols; ++i) {
        if (j % 2 == 0) {
          c.faces.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
          c.faces.push_back({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
        } else {
          c.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
          c.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
      }
    }
    const auto flags = boundary_flags(c);
    const Eigen::VectorXd H = mean_curvature(c.positions, c.faces, flags);
    const auto normals = vertex_normals(c.positions, c.faces);
    double error = 0;
    for (size_t i = 0; i < c.positions.size(); ++i) {
      if (flags[i]) continue;
      EXPECT_GT(normals[i].dot(Vec3(c.positions[i].x(), c.positions[i].y(), 0)), 0);
      error = std::max(error, std::abs(H[static_cast<Eigen::Index>(i)] + 1.0 / (2 * r)));
    }
    EXPECT_LT(error, previous / 3.0);  // second order
    previous = error;
  }
  EXPECT_LT(previous * 2 * r, 0.01);
}

TEST(MeanCurvature, BoundaryVerticesTakeTheInteriorMean) {
  // On a sphere cap the boundary one-ring is incomplete; the interior mean keeps H near -1/R there.
  const double r = 1.0;
  TriangleMesh cap = testing::icosphere(r, 4);
  std::vector<Face> kept;
  for (const Face& f : cap.faces) {
    const Vec3 c =
        (cap.positions[static_cast<size_t>(f[0])] + cap.positions[static_cast<size_t>(f[1])] + cap.positions[static_cast<size_t>(f[2])]) /
        3.0;
    if (c.z() > 0.3) kept.push_back(f);
  }
  cap.faces = kept;
  const auto flags = boundary_flags(cap);
  const Eigen::VectorXd H = mean_curvature(cap.positions, cap.faces, flags);
  int boundary = 0;
  for (size_t i = 0; i < flags.size(); ++i) {
    if (!flags[i]) continue;
    ++boundary;
    EXPECT_NEAR(H[static_cast<Eigen::Index>(i)], -1.0 / r, 0.05);
  }
  EXPECT_GT(boundary, 20);
}

}  // namespace
}  // namespace facemorph
