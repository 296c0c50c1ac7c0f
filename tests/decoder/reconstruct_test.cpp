#include "codec/core/reconstruct/reconstructor.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <memory>
#include <numbers>

namespace facemorph {
namespace {

using testing::sample_nodes;

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

// shared_grid_geometry (the encoder's candidates at one N, spec/method.md §7.14): one geometry an N
// while anything holds it, of that N (a cache that ignored N would hand a decoder another grid),
// none kept past its last holder, and a new one the same to the bit as the one before it.
TEST(GridGeometry, OneSharedGeometryAnNWhileHeldAndNoneKeptPastItsHolders) {
  const std::shared_ptr<const GridGeometry> a = shared_grid_geometry(33), b = shared_grid_geometry(33);
  EXPECT_EQ(a.get(), b.get());
  std::shared_ptr<const GridGeometry> c = shared_grid_geometry(49);
  ASSERT_NE(c.get(), a.get());
  EXPECT_EQ(a->grid().n, 33);
  EXPECT_EQ(c->grid().n, 49);
  const std::vector<Vec2> nodes = c->grid().nodes;
  const SparseMatrix stiffness = c->stiffness();
  const Eigen::VectorXd mass = c->mass();
  const std::weak_ptr<const GridGeometry> held = c;
  c.reset();
  EXPECT_TRUE(held.expired()) << "the cache kept a geometry nobody holds";
  const std::shared_ptr<const GridGeometry> again = shared_grid_geometry(49);
  EXPECT_EQ(again->grid().nodes, nodes);
  EXPECT_EQ((again->stiffness() - stiffness).norm(), 0.0);
  EXPECT_EQ(again->mass(), mass);
  EXPECT_EQ(again.get(), shared_grid_geometry(49).get());
}

TEST(Reconstruct, AFlatDiskHasZeroCurvatureAndReconstructsThePlane) {
  Reconstructor reconstructor(33);
  const auto& grid = reconstructor.geometry().grid();
  const auto plane = sample_nodes(grid, [](const Vec2& w) { return Vec3(2 * w.x() + 1, 2 * w.y(), 0.5); });
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
    const auto truth = sample_nodes(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w); });
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
    for (const auto& truth : {sample_nodes(grid, paraboloid), sample_nodes(grid, saddle)}) {
      reconstructor.forget_warm_start();
      const ReconstructResult r =
          reconstructor.reconstruct(compute_fields(reconstructor.geometry(), truth, Representation::kHLT), {.tolerance = 1e-10});
      EXPECT_LT(max_error(r.positions, truth), 1e-7) << "N = " << n;
    }
    // The paraboloid's Δ S = (0, 0, 1.6) is vertical, not normal: the paper's (H, λ) loses its
    // tangential part and lands on another surface. (The saddle is harmonic, Δ S = 0: nothing lost.)
    const auto truth = sample_nodes(grid, paraboloid);
    reconstructor.forget_warm_start();
    const ReconstructResult normal_only = reconstructor.reconstruct(compute_fields(reconstructor.geometry(), truth, Representation::kHL),
                                                                    {.tolerance = 1e-10, .throw_on_failure = false});
    EXPECT_GT(max_error(normal_only.positions, truth), 5e-5) << "N = " << n;
  }
}

TEST(Reconstruct, ARigidMotionOfTheBoundaryMovesTheSurfaceRigidly) {
  Reconstructor reconstructor(65);
  const auto truth = sample_nodes(reconstructor.geometry().grid(), [](const Vec2& w) {
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
  const auto truth = sample_nodes(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w, 2.0, 1.2); });
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

TEST(Reconstruct, FieldsCombineLinearlyInEveryArrayAndRefuseMismatches) {
  Reconstructor reconstructor(33);
  const GridGeometry& geometry = reconstructor.geometry();
  const auto& grid = geometry.grid();
  const auto one = sample_nodes(grid, [](const Vec2& w) { return cap(w, 1.0, 0.8); });
  const auto two = sample_nodes(grid, [](const Vec2& w) { return Vec3(cap(w, 2.0, 1.2) + Vec3(0.1 * w.x() * w.y(), 0, 0.3)); });
  const std::vector<int32_t> extra = {0, 17, 200};  // fixed-frame nodes beyond the band: their vectors blend too
  for (Representation rep : {Representation::kHL, Representation::kHLT, Representation::kXYZ}) {
    const GridFields a = compute_fields(geometry, one, rep, rep == Representation::kHLT ? extra : std::vector<int32_t>{});
    const GridFields b = compute_fields(geometry, two, rep, rep == Representation::kHLT ? extra : std::vector<int32_t>{});
    const GridFields mixed = combine_fields({&a, &b}, {2.0, -1.0});  // extrapolation: weights need not sum to 1
    const auto out = scalar_arrays(mixed), xa = scalar_arrays(a), xb = scalar_arrays(b);
    ASSERT_EQ(out.size(), xa.size());
    int used = 0;
    for (size_t k = 0; k < out.size(); ++k) {
      ASSERT_EQ(out[k].size(), xa[k].size());
      used += !out[k].empty();
      double error = 0, spread = 0;
      for (size_t i = 0; i < out[k].size(); ++i) {
        error = std::max(error, std::abs(out[k][i] - (2 * xa[k][i] - xb[k][i])));
        spread = std::max(spread, std::abs(xa[k][i] - xb[k][i]));
      }
      EXPECT_LT(error, 1e-12 * (1 + spread)) << representation_name(rep) << ", array " << k;
      if (!out[k].empty() && k < out.size() - 3) {
        EXPECT_GT(spread, 0) << "array " << k << " does not tell the keys apart";
      }
    }
    EXPECT_EQ(used, rep == Representation::kHLT ? 10 : rep == Representation::kHL ? 5 : 6) << representation_name(rep);
  }
  const GridFields a = compute_fields(geometry, one, Representation::kHLT);
  const GridFields folded = compute_fields(geometry, two, Representation::kHLT, extra);
  const GridFields xyz = compute_fields(geometry, one, Representation::kXYZ);
  testing::expect_error(ErrorCode::kInvalidArgument, "different representations", [&] { combine_fields({&a, &xyz}, {0.5, 0.5}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "fixed-frame nodes", [&] { combine_fields({&a, &folded}, {0.5, 0.5}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "one weight per key", [&] { combine_fields({&a, &a}, {1.0}); });
  // Keys of inconsistent sizes (a heap overflow before validation): named, never read past the end.
  GridFields short_key = a;
  short_key.tangential_v.pop_back();
  testing::expect_error(ErrorCode::kInvalidArgument, "tangential_v has", [&] { combine_fields({&a, &short_key}, {0.5, 0.5}); });
  GridFields short_fixed = a;
  short_fixed.fixed_laplacian.pop_back();
  testing::expect_error(ErrorCode::kInvalidArgument, "fixed_laplacian has", [&] { combine_fields({&short_fixed, &a}, {0.5, 0.5}); });
}

TEST(Reconstruct, MalformedFieldsAreNamedByEveryConsumer) {
  Reconstructor reconstructor(17);
  const GridFields good =
      compute_fields(reconstructor.geometry(), sample_nodes(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w); }),
                     Representation::kHLT, {3});
  EXPECT_NO_THROW(validate_fields(good));
  struct Case {
    const char* fragment;
    std::function<void(GridFields&)> damage;
  };
  const std::vector<Case> cases = {
      {"rim has", [](GridFields& f) { f.rim.pop_back(); }},
      {"mean_curvature has", [](GridFields& f) { f.mean_curvature.push_back(0); }},
      {"log_conformal_factor has", [](GridFields& f) { f.log_conformal_factor.clear(); }},
      {"tangential_u has", [](GridFields& f) { f.tangential_u.resize(3); }},
      {"positions has", [](GridFields& f) { f.positions.assign(f.mean_curvature.size(), Vec3::Zero()); }},
      {"not strictly increasing", [](GridFields& f) { std::swap(f.fixed_nodes[0], f.fixed_nodes[1]); }},
      {"outside the interior", [](GridFields& f) { f.fixed_nodes.back() = static_cast<int32_t>(f.mean_curvature.size()); }},
      {"outside the interior", [](GridFields& f) { f.fixed_nodes.front() = -1; }},
      {"fixed_laplacian has", [](GridFields& f) { f.fixed_laplacian.pop_back(); }},
      {"mean_curvature is not finite at entry 5", [](GridFields& f) { f.mean_curvature[5] = std::nan(""); }},
      {"rim is not finite", [](GridFields& f) { f.rim[2].y() = INFINITY; }},
      {"fixed_laplacian is not finite", [](GridFields& f) { f.fixed_laplacian[1].z() = -INFINITY; }},
      {"grid size N = 3", [](GridFields& f) { f.grid_n = 3; }},
      {"unknown representation", [](GridFields& f) { f.representation = static_cast<Representation>(7); }},
      {"fixed_nodes has",
       [](GridFields& f) {
         f.representation = Representation::kHL;
         f.tangential_u.clear();
         f.tangential_v.clear();
       }},
  };
  for (const Case& c : cases) {
    GridFields bad = good;
    c.damage(bad);
    testing::expect_error(ErrorCode::kInvalidArgument, c.fragment, [&] { validate_fields(bad); });
    testing::expect_error(ErrorCode::kInvalidArgument, c.fragment, [&] { reconstructor.reconstruct(bad); });
    testing::expect_error(ErrorCode::kInvalidArgument, c.fragment, [&] { quantize_fields(bad); });
    testing::expect_error(ErrorCode::kInvalidArgument, c.fragment, [&] { combine_fields({&bad}, {1.0}); });
  }
}

TEST(Reconstruct, AndersonAccelerationCutsTheIterationsAndNeverLosesConvergence) {
  // Bumps of height h and sharpness s on an elongated disk (a nose on a face, roughly).
  Reconstructor reconstructor(65);
  auto decode = [&](double h, double s, int depth) {
    const auto truth = sample_nodes(reconstructor.geometry().grid(), [h, s](const Vec2& w) {
      return Vec3(w.x(), 1.2 * w.y(), h * std::exp(-s * w.squaredNorm()) + 0.2 * w.x() * w.x());
    });
    reconstructor.forget_warm_start();
    const ReconstructResult r = reconstructor.reconstruct(compute_fields(reconstructor.geometry(), truth, Representation::kHLT),
                                                          {.tolerance = 1e-9, .anderson_depth = depth, .throw_on_failure = false});
    EXPECT_TRUE(r.converged) << "h = " << h << ", s = " << s << ", depth " << depth;
    EXPECT_LT(max_error(r.positions, truth), 1e-6) << "h = " << h << ", s = " << s << ", depth " << depth;
    return r.iterations;
  };
  // Where the plain iteration crawls, Anderson needs fewer steps (measured with one V-cycle per
  // step: 75 against 87; with an exact inner solve 37 against 56)...
  const int plain = decode(2.0, 4.0, 0), accelerated = decode(2.0, 4.0, 5);
  EXPECT_LE(accelerated * 10, plain * 9) << accelerated << " against " << plain;
  // ...and where its linear model misleads, the restart keeps it converging to the surface
  // (unguarded, it wandered for 200 steps and stopped 0.43 away). On (1.0, 8.0) the plain
  // iteration itself converges, but to another surface 1.8 away: the equations have a second
  // fixed point, and only the accelerated iteration finds the right one from the harmonic start.
  decode(0.5, 16.0, 5);
  decode(1.0, 8.0, 5);
}

TEST(Reconstruct, OneReconstructorDecodesEachCallAsAFreshOneWould) {
  // The reconstructor keeps its work arrays and Anderson history between calls: nothing of one call
  // may reach the next (after forget_warm_start), whatever the representation or depth before.
  Reconstructor shared(33);
  const GridGeometry& geometry = shared.geometry();
  const auto truth =
      sample_nodes(geometry.grid(), [](const Vec2& w) { return Vec3(w.x(), 1.1 * w.y(), 0.5 * std::exp(-3 * w.squaredNorm())); });
  const struct {
    Representation representation;
    int depth;
  } calls[] = {{Representation::kHLT, 5},
               {Representation::kHL, 0},
               {Representation::kXYZ, 5},
               {Representation::kHLT, 16},
               {Representation::kHLT, 5}};
  for (const auto& call : calls) {
    const GridFields fields = compute_fields(geometry, truth, call.representation);
    const ReconstructOptions options{.tolerance = 1e-9, .anderson_depth = call.depth, .throw_on_failure = false};
    shared.forget_warm_start();
    const ReconstructResult again = shared.reconstruct(fields, options);
    Reconstructor fresh(33);
    const ReconstructResult first = fresh.reconstruct(fields, options);
    EXPECT_EQ(again.iterations, first.iterations) << "depth " << call.depth;
    ASSERT_EQ(again.positions.size(), first.positions.size());
    for (size_t v = 0; v < first.positions.size(); ++v)
      ASSERT_EQ(again.positions[v], first.positions[v]) << "node " << v << ", depth " << call.depth;
  }
}

TEST(Reconstruct, WarmStartedSequenceDecodesEveryFrameLikeAColdStart) {
  // A bump growing and sliding over 8 frames, decoded as a player would (warm, extrapolated from
  // the last two frames) and each frame again from scratch: the same surfaces, in fewer steps.
  Reconstructor reconstructor(65);
  const GridGeometry& geometry = reconstructor.geometry();
  auto frame = [&](int i) {
    const double s = i / 7.0;
    return sample_nodes(geometry.grid(), [s](const Vec2& w) {
      const Vec2 c(0.2 * s - 0.1, 0.05 * s);
      return Vec3(w.x(), w.y(), (0.3 + 0.2 * s) * std::exp(-5 * (w - c).squaredNorm()) + 0.1 * s * w.x());
    });
  };
  int warm_iterations = 0, cold_iterations = 0;
  for (int i = 0; i < 8; ++i) {
    const auto truth = frame(i);
    const GridFields fields = compute_fields(geometry, truth, Representation::kHLT);
    const ReconstructResult warm = reconstructor.reconstruct(fields, {.tolerance = 1e-9});
    Reconstructor fresh(65);
    const ReconstructResult cold = fresh.reconstruct(fields, {.tolerance = 1e-9});
    EXPECT_LT(max_error(warm.positions, cold.positions), 1e-7) << "frame " << i;
    EXPECT_LT(max_error(warm.positions, truth), 1e-6) << "frame " << i;
    if (i >= 2) {  // from the third frame on the start is extrapolated from two
      warm_iterations += warm.iterations;
      cold_iterations += cold.iterations;
    }
  }
  EXPECT_LT(warm_iterations, cold_iterations) << "the warm start saves nothing";
}

TEST(Reconstruct, FoldsAtGridResolutionAreFoundWithTwoRingsAroundThem) {
  Reconstructor reconstructor(33);
  const GridGeometry& geometry = reconstructor.geometry();
  const auto& grid = geometry.grid();
  EXPECT_TRUE(folded_nodes(geometry, sample_nodes(grid, [](const Vec2& w) { return cap(w); })).empty());
  // (x, y) -> (|x|, y, 0) folds the disk over along x = 0: the normals flip there.
  const auto folds =
      folded_nodes(geometry, sample_nodes(grid, [](const Vec2& w) { return Vec3(std::abs(w.x()) + 0.01 * w.y(), w.y(), 0.1 * w.x()); }));
  ASSERT_FALSE(folds.empty());
  for (int32_t v : folds) EXPECT_LE(std::abs(grid.nodes[static_cast<size_t>(v)].x()), 3.01 * grid.h);
  int near_fold = 0;
  for (int v = 0; v < grid.interior_count; ++v) near_fold += std::abs(grid.nodes[static_cast<size_t>(v)].x()) < 0.5 * grid.h;
  EXPECT_GT(static_cast<int>(folds.size()), 3 * near_fold);  // the fold column and two rings each side
}

TEST(Reconstruct, NonConvergenceAndNonFiniteIteratesAreNamedNeverReturnedSilently) {
  Reconstructor reconstructor(33);
  const auto truth = sample_nodes(reconstructor.geometry().grid(), [](const Vec2& w) { return cap(w); });
  GridFields wild = compute_fields(reconstructor.geometry(), truth, Representation::kHL);
  for (double& H : wild.mean_curvature) H *= 40;  // no surface with this boundary has it
  testing::expect_error(ErrorCode::kNotConverged, "did not converge in 60 iterations",
                        [&] { reconstructor.reconstruct(wild, {.max_iterations = 60}); });
  reconstructor.forget_warm_start();
  const ReconstructResult r = reconstructor.reconstruct(wild, {.max_iterations = 60, .throw_on_failure = false});
  EXPECT_FALSE(r.converged);
  EXPECT_GT(r.change, 1e-5);
  EXPECT_TRUE(std::all_of(r.positions.begin(), r.positions.end(), [](const Vec3& p) { return p.allFinite(); }));
  // Finite fields whose right-hand side overflows (λ² = e^800): no best effort exists.
  GridFields overflowing = compute_fields(reconstructor.geometry(), truth, Representation::kHL);
  for (double& l : overflowing.log_conformal_factor) l = 400;
  for (bool throw_on_failure : {true, false}) {
    reconstructor.forget_warm_start();
    testing::expect_error(ErrorCode::kNumerical, "non-finite",
                          [&] { reconstructor.reconstruct(overflowing, {.throw_on_failure = throw_on_failure}); });
  }
  // A failed frame leaves the warm start alone: the next frame decodes as if it had not happened.
  reconstructor.forget_warm_start();
  const GridFields good = compute_fields(reconstructor.geometry(), truth, Representation::kHLT);
  const ReconstructResult first = reconstructor.reconstruct(good, {.tolerance = 1e-9});
  EXPECT_THROW(reconstructor.reconstruct(overflowing), Error);
  const ReconstructResult again = reconstructor.reconstruct(good, {.tolerance = 1e-9});
  EXPECT_LE(again.iterations, 2);
  EXPECT_LT(max_error(again.positions, first.positions), 1e-9);
  // So does one that did not converge (it had an iterate, which must not become the next start).
  EXPECT_THROW(reconstructor.reconstruct(wild, {.max_iterations = 60}), Error);
  const ReconstructResult after = reconstructor.reconstruct(good, {.tolerance = 1e-9});
  EXPECT_LE(after.iterations, 2);
  EXPECT_LT(max_error(after.positions, first.positions), 1e-9);
  // Fields of another grid are refused.
  testing::expect_error(ErrorCode::kInvalidArgument, "N = 33", [&] {
    Reconstructor other(17);
    other.reconstruct(wild);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown representation 'xyzw'", [] { parse_representation("xyzw"); });
}

}  // namespace
}  // namespace facemorph
