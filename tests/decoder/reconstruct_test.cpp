#include "facemorph/reconstruct.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <numbers>

namespace facemorph {
namespace {


// A surface given on the disk, sampled at every node of G (rim nodes included).
template <typename Surface>
std::vector<Vec3> sample(const DiskGrid& grid, Surface&& surface) {
  std::vector<Vec3> out;
  for (const Vec2& w : grid.nodes) out.push_back(surface(w));
  return out;
}

// A spherical cap of radius R and polar angle θ0 in its conformal (stereographic) parametrisation:
// λ(w) = 2 R t0 / (1 + t0² |w|²), H = -1/R with the outward normal S_u × S_v.
Vec3 cap(const Vec2& w, double R = 1.0, double theta0 = 1.0) {
  const double t0 = std::tan(theta0 / 2), rho = t0 * w.norm();
  const double theta = 2 * std::atan(rho), phi = std::atan2(w.y(), w.x());
  return Vec3(R * std::sin(theta) * std::cos(phi), R * std::sin(theta) * std::sin(phi), R * std::cos(theta));
}

double max_error(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double e = 0;
  for (size_t i = 0; i < a.size(); ++i) e = std::max(e, (a[i] - b[i]).norm());
  return e;
}

TEST(Reconstruct, AFlatDiskHasZeroCurvatureAndReconstructsThePlane) {
  Reconstructor reconstructor(33);
  const auto& grid = reconstructor.geometry().grid();
  const auto plane = sample(grid, [](const Vec2& w) { return Vec3(2 * w.x() + 1, 2 * w.y(), 0.5); });
  for (Representation rep : {Representation::kHL, Representation::kHLT}) {
    const GridFields fields = compute_fields(reconstructor.geometry(), plane, rep);
    for (double H : fields.mean_curvature) EXPECT_NEAR(H, 0.0, 1e-12);
    for (double l : fields.log_conformal_factor) EXPECT_NEAR(l, std::log(2.0), 1e-12);
    reconstructor.forget_warm_start();
    const ReconstructResult r = reconstructor.reconstruct(fields, {.tolerance = 1e-10});
    EXPECT_TRUE(r.converged);
    EXPECT_LT(max_error(r.positions, plane), 1e-9);
  }
}

TEST(Reconstruct, SphericalCapFromHAndLambdaConvergesUnderRefinement) {
  double previous = 1e9;
  for (int n : {17, 33, 65, 129}) {
    Reconstructor reconstructor(n);
    const auto truth = sample(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w); });
    const GridFields fields = compute_fields(reconstructor.geometry(), truth, Representation::kHL);
    // H = -1/R away from the rim (where the rim's one-sided frame is coarser).
    for (int v = 0; v < reconstructor.geometry().interior_count(); ++v) {
      if (reconstructor.geometry().grid().nodes[static_cast<size_t>(v)].norm() < 0.7) {
        EXPECT_NEAR(fields.mean_curvature[static_cast<size_t>(v)], -1.0, 0.05);
      }
    }
    const ReconstructResult r = reconstructor.reconstruct(fields, {.tolerance = 1e-9});
    const double error = max_error(r.positions, truth);
    EXPECT_LT(error, previous / 2.5) << "N = " << n;  // about second order
    previous = error;
  }
  EXPECT_LT(previous, 2e-3);
}

TEST(Reconstruct, TangentialFieldsMakeTheSampledSurfaceTheFixedPointOnAnyGrid) {
  // Paraboloid and saddle over the disk, parametrised by (x, y), not conformally: with the
  // tangential part of Δ_h S the sampled surface is the fixed point at every N.
  const auto paraboloid = [](const Vec2& w) { return Vec3(w.x(), w.y(), 0.4 * w.squaredNorm()); };
  const auto saddle = [](const Vec2& w) { return Vec3(w.x(), w.y(), 0.4 * (w.x() * w.x() - w.y() * w.y())); };
  for (int n : {33, 65}) {
    Reconstructor reconstructor(n);
    const auto& grid = reconstructor.geometry().grid();
    for (const auto& truth : {sample(grid, paraboloid), sample(grid, saddle)}) {
      reconstructor.forget_warm_start();
      const ReconstructResult r = reconstructor.reconstruct(compute_fields(reconstructor.geometry(), truth, Representation::kHLT), {.tolerance = 1e-10});
      EXPECT_LT(max_error(r.positions, truth), 1e-7) << "N = " << n;
    }
    // The paraboloid's Δ S = (0, 0, 1.6) is vertical, not normal: the paper's (H, λ) loses its
    // tangential part and lands on another surface. (The saddle is harmonic, Δ S = 0: nothing lost.)
    const auto truth = sample(grid, paraboloid);
    reconstructor.forget_warm_start();
    const ReconstructResult normal_only = reconstructor.reconstruct(compute_fields(reconstructor.geometry(), truth, Representation::kHL),
                                                                    {.tolerance = 1e-10, .throw_on_failure = false});
    EXPECT_GT(max_error(normal_only.positions, truth), 5e-5) << "N = " << n;
  }
}

TEST(Reconstruct, ARigidMotionOfTheBoundaryMovesTheSurfaceRigidly) {
  Reconstructor reconstructor(65);
  const auto truth = sample(reconstructor.geometry().grid(), [](const Vec2& w) {
    return Vec3(w.x(), w.y(), 0.3 * std::exp(-3 * w.squaredNorm()) + 0.1 * w.x() * w.y());
  });
  const Eigen::Matrix3d R = Eigen::AngleAxisd(1.1, Vec3(0.3, -1, 0.5).normalized()).toRotationMatrix();
  const Vec3 t(0.5, 2, -1);
  for (Representation rep : {Representation::kHL, Representation::kHLT}) {
    const GridFields fields = compute_fields(reconstructor.geometry(), truth, rep);
    reconstructor.forget_warm_start();
    const ReconstructResult a = reconstructor.reconstruct(fields, {.tolerance = 1e-10, .throw_on_failure = false});
    GridFields moved = fields;  // every stored field is rotation-invariant; only the boundary moves
    for (Vec3& p : moved.rim) p = R * p + t;
    reconstructor.forget_warm_start();
    const ReconstructResult b = reconstructor.reconstruct(moved, {.tolerance = 1e-10, .throw_on_failure = false});
    double error = 0;
    for (size_t i = 0; i < a.positions.size(); ++i) error = std::max(error, (R * a.positions[i] + t - b.positions[i]).norm());
    EXPECT_LT(error, 1e-7) << representation_name(rep);
  }
}

TEST(Reconstruct, SixteenBitFieldsStayWithinHalfAStep) {
  Reconstructor reconstructor(33);
  const auto truth = sample(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w, 2.0, 1.2); });
  const GridFields f = compute_fields(reconstructor.geometry(), truth, Representation::kHLT);
  const GridFields q = quantize_fields(f);
  auto check = [](const std::vector<double>& a, const std::vector<double>& b) {
    const auto [lo, hi] = std::minmax_element(a.begin(), a.end());
    const double half_step = (*hi - *lo) / 65535.0 / 2;
    for (size_t i = 0; i < a.size(); ++i) EXPECT_LE(std::abs(a[i] - b[i]), half_step * (1 + 1e-9) + 1e-300);
  };
  check(f.mean_curvature, q.mean_curvature);
  check(f.log_conformal_factor, q.log_conformal_factor);
  check(f.tangential_u, q.tangential_u);
  const ReconstructResult r = reconstructor.reconstruct(q);
  EXPECT_LT(max_error(r.positions, truth), 1e-4);
}

TEST(Reconstruct, FieldsCombineLinearlyAndRefuseMismatches) {
  Reconstructor reconstructor(33);
  const auto& grid = reconstructor.geometry().grid();
  const GridFields a = compute_fields(reconstructor.geometry(), sample(grid, [](const Vec2& w) { return cap(w, 1.0, 0.8); }), Representation::kHLT);
  const GridFields b = compute_fields(reconstructor.geometry(), sample(grid, [](const Vec2& w) { return cap(w, 2.0, 1.2); }), Representation::kHLT);
  const GridFields half = combine_fields({&a, &b}, {0.5, 0.5});
  const GridFields extrapolated = combine_fields({&a, &b}, {2.0, -1.0});
  for (size_t i = 0; i < a.mean_curvature.size(); ++i) {
    EXPECT_DOUBLE_EQ(half.mean_curvature[i], 0.5 * (a.mean_curvature[i] + b.mean_curvature[i]));
    EXPECT_NEAR(extrapolated.log_conformal_factor[i], 2 * a.log_conformal_factor[i] - b.log_conformal_factor[i], 1e-12);
  }
  for (size_t i = 0; i < a.rim.size(); ++i) EXPECT_LT((half.rim[i] - 0.5 * (a.rim[i] + b.rim[i])).norm(), 1e-15);
  const GridFields xyz = compute_fields(reconstructor.geometry(), sample(grid, [](const Vec2& w) { return cap(w); }), Representation::kXYZ);
  testing::expect_error(ErrorCode::kInvalidArgument, "different representations", [&] { combine_fields({&a, &xyz}, {0.5, 0.5}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "one weight per key", [&] { combine_fields({&a, &b}, {1.0}); });
}

TEST(Reconstruct, FoldsAtGridResolutionAreFoundWithTwoRingsAroundThem) {
  Reconstructor reconstructor(33);
  const GridGeometry& geometry = reconstructor.geometry();
  const auto& grid = geometry.grid();
  EXPECT_TRUE(folded_nodes(geometry, sample(grid, [](const Vec2& w) { return cap(w); })).empty());
  // (x, y) -> (|x|, y, 0) folds the disk over along x = 0: the normals flip there.
  const auto folds = folded_nodes(geometry, sample(grid, [](const Vec2& w) { return Vec3(std::abs(w.x()) + 0.01 * w.y(), w.y(), 0.1 * w.x()); }));
  ASSERT_FALSE(folds.empty());
  for (int32_t v : folds) EXPECT_LE(std::abs(grid.nodes[static_cast<size_t>(v)].x()), 3.01 * grid.h);
  int near_fold = 0;
  for (int v = 0; v < grid.interior_count; ++v) near_fold += std::abs(grid.nodes[static_cast<size_t>(v)].x()) < 0.5 * grid.h;
  EXPECT_GT(static_cast<int>(folds.size()), 3 * near_fold);  // the fold column and two rings each side
}

TEST(Reconstruct, NonConvergenceIsDetectedNeverReturnedSilently) {
  Reconstructor reconstructor(33);
  const auto truth = sample(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w); });
  GridFields wild = compute_fields(reconstructor.geometry(), truth, Representation::kHL);
  for (double& H : wild.mean_curvature) H *= 40;  // no surface with this boundary has it
  try {
    reconstructor.reconstruct(wild, {.max_iterations = 60});
    ADD_FAILURE() << "inconsistent H was accepted";
  } catch (const Error& e) {
    EXPECT_TRUE(e.code() == ErrorCode::kNotConverged || e.code() == ErrorCode::kNumerical) << e.what();
  }
  reconstructor.forget_warm_start();
  const ReconstructResult r = reconstructor.reconstruct(wild, {.max_iterations = 60, .throw_on_failure = false});
  EXPECT_FALSE(r.converged);
  EXPECT_GT(r.change, 1e-5);
  // Fields of another grid are refused.
  testing::expect_error(ErrorCode::kInvalidArgument, "N = 33", [&] {
    Reconstructor other(17);
    other.reconstruct(wild);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown representation 'xyzw'", [] { parse_representation("xyzw"); });
}

}  // namespace
}  // namespace facemorph
