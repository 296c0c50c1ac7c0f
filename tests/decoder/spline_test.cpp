// The keyframe splines (cardinal weights) and the rigid head pose: fit, SO(3) log/exp, pose spline.
#include "codec/core/sequence/spline.hpp"
#include "codec/core/sequence/pose.hpp"
#include "format/error.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

using testing::kPi;
constexpr SplineKind kAllKinds[] = {SplineKind::kLocalCubic, SplineKind::kCatmullRom, SplineKind::kNotAKnot, SplineKind::kLinear};

// Non-uniform, strictly increasing times starting at `start`, intervals in [lo, hi] (seconds).
std::vector<double> random_times(int count, unsigned seed, double start = 0.3, double lo = 0.05, double hi = 0.5) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> step(lo, hi);
  std::vector<double> times{start};
  while (static_cast<int>(times.size()) < count) times.push_back(times.back() + step(rng));
  return times;
}

double blend(const SplineWeights& w, const std::vector<double>& values) {
  double sum = 0;
  for (size_t i = 0; i < w.keys.size(); ++i) sum += w.weights[i] * values[static_cast<size_t>(w.keys[i])];
  return sum;
}

double sum_of(const SplineWeights& w) {
  double sum = 0;
  for (double v : w.weights) sum += v;
  return sum;
}

// Times to probe: the knots, points inside every segment, and a sweep from `reach` intervals before
// the first knot to `reach` after the last (reach 1: the sane range).
std::vector<double> probe_times(const std::vector<double>& times, double reach = 1.0) {
  std::vector<double> out(times);
  for (size_t k = 0; k + 1 < times.size(); ++k) {
    for (double f : {0.1, 0.37, 0.5, 0.81}) out.push_back(times[k] + f * (times[k + 1] - times[k]));
  }
  const double h0 = times.size() > 1 ? times[1] - times[0] : 1, h1 = times.size() > 1 ? times.back() - times[times.size() - 2] : 1;
  for (int j = 1; j <= 8; ++j) {
    out.push_back(times.front() - reach * h0 * j / 8);
    out.push_back(times.back() + reach * h1 * j / 8);
  }
  return out;
}

// Standard normal values, one per key.
std::vector<double> random_values(size_t count, std::mt19937& rng) {
  std::normal_distribution<double> value(0.0, 1.0);
  std::vector<double> y;
  while (y.size() < count) y.push_back(value(rng));
  return y;
}

// y(t) on the keys.
std::vector<double> sample(const std::vector<double>& times, const std::function<double(double)>& f) {
  std::vector<double> y;
  for (double t : times) y.push_back(f(t));
  return y;
}

TEST(Spline, KindNamesRoundTrip) {
  for (SplineKind kind : kAllKinds) EXPECT_EQ(parse_spline_kind(spline_kind_name(kind)), kind);
  EXPECT_STREQ(spline_kind_name(SplineKind::kLocalCubic), "local");
  EXPECT_STREQ(spline_kind_name(SplineKind::kNotAKnot), "not-a-knot");
  testing::expect_error(ErrorCode::kInvalidArgument, "catmull-rom", [] { parse_spline_kind("cubic"); });
}

// At a key's own time every kind returns that key alone with weight exactly 1, so a keyframe decodes
// to exactly what was stored.
TEST(Spline, EveryKindReproducesTheKeysExactlyAtTheirTimes) {
  for (SplineKind kind : kAllKinds) {
    for (int count : {1, 2, 3, 4, 5, 7, 20}) {
      const std::vector<double> times = random_times(count, 7 + static_cast<unsigned>(count));
      const KeyframeSpline spline(times, kind);
      for (int k = 0; k < count; ++k) {
        const SplineWeights w = spline.weights(times[static_cast<size_t>(k)]);
        ASSERT_EQ(w.keys.size(), 1u) << spline_kind_name(kind) << " K = " << count << " key " << k;
        EXPECT_EQ(w.keys[0], k);
        EXPECT_EQ(w.weights[0], 1.0);
      }
    }
  }
}

// Constants are reproduced: Σ c_k = 1 everywhere, extrapolation included (3 intervals out), and the
// derivative weights sum to 0.
TEST(Spline, WeightsSumToOneEverywhere) {
  for (SplineKind kind : kAllKinds) {
    for (int count : {1, 2, 3, 4, 6, 30}) {
      const std::vector<double> times = random_times(count, 100 + static_cast<unsigned>(count));
      const KeyframeSpline spline(times, kind);
      for (double t : probe_times(times, 3.0)) {
        const SplineWeights w = spline.weights(t), d = spline.derivative_weights(t);
        ASSERT_EQ(w.keys.size(), w.weights.size());
        EXPECT_NEAR(sum_of(w), 1.0, 1e-12) << spline_kind_name(kind) << " K = " << count << " t = " << t;
        EXPECT_NEAR(sum_of(d), 0.0, 1e-9) << spline_kind_name(kind) << " K = " << count << " t = " << t;
        EXPECT_TRUE(std::is_sorted(w.keys.begin(), w.keys.end()));
      }
    }
  }
}

// The polynomial degree each kind reproduces, between keys and out to one interval past the ends
// (the sane range), values and derivatives; and that it does not reproduce the next degree (so the
// test is not vacuous).
TEST(Spline, EachKindReproducesItsPolynomialDegree) {
  const std::vector<std::function<double(double)>> poly = {
      [](double t) { return 0.7 - 1.3 * t; },
      [](double t) { return 0.7 - 1.3 * t + 0.9 * t * t; },
      [](double t) { return 0.7 - 1.3 * t + 0.9 * t * t - 0.4 * t * t * t; },
  };
  const std::vector<std::function<double(double)>> slope = {
      [](double) { return -1.3; },
      [](double t) { return -1.3 + 1.8 * t; },
      [](double t) { return -1.3 + 1.8 * t - 1.2 * t * t; },
  };
  struct Case {
    SplineKind kind;
    int degree;
  };
  for (const Case c :
       {Case{SplineKind::kLinear, 1}, Case{SplineKind::kCatmullRom, 2}, Case{SplineKind::kLocalCubic, 3}, Case{SplineKind::kNotAKnot, 3}}) {
    for (int count : {4, 5, 6, 9, 25}) {
      const std::vector<double> times = random_times(count, 200 + static_cast<unsigned>(count));
      const KeyframeSpline spline(times, c.kind);
      const double scale = std::abs(poly[2](times.back() + 1)) + 1;
      const std::vector<double> y = sample(times, poly[static_cast<size_t>(c.degree) - 1]);
      double worst_next = 0;
      const std::vector<double> next = c.degree < 3 ? sample(times, poly[static_cast<size_t>(c.degree)]) : y;
      for (double t : probe_times(times)) {
        EXPECT_NEAR(blend(spline.weights(t), y), poly[static_cast<size_t>(c.degree) - 1](t), 1e-12 * scale)
            << spline_kind_name(c.kind) << " K = " << count << " t = " << t;
        EXPECT_NEAR(blend(spline.derivative_weights(t), y), slope[static_cast<size_t>(c.degree) - 1](t), 1e-10 * scale)
            << spline_kind_name(c.kind) << " K = " << count << " t = " << t;
        if (c.degree < 3)
          worst_next = std::max(worst_next, std::abs(blend(spline.weights(t), next) - poly[static_cast<size_t>(c.degree)](t)));
      }
      if (c.degree < 3) {
        EXPECT_GT(worst_next, 1e-4) << spline_kind_name(c.kind) << " reproduces degree " << c.degree + 1 << " too";
      }
    }
  }
}

// The Lagrange weights of the polynomial through all the knots.
std::vector<double> lagrange(const std::vector<double>& knots, double t) {
  std::vector<double> w;
  for (size_t j = 0; j < knots.size(); ++j) {
    double p = 1;
    for (size_t m = 0; m < knots.size(); ++m) {
      if (m != j) p *= (t - knots[m]) / (knots[j] - knots[m]);
    }
    w.push_back(p);
  }
  return w;
}

void expect_weights(const SplineWeights& w, const std::vector<double>& dense, double tolerance, const std::string& what) {
  std::vector<double> got(dense.size(), 0.0);
  for (size_t i = 0; i < w.keys.size(); ++i) got[static_cast<size_t>(w.keys[i])] = w.weights[i];
  for (size_t k = 0; k < dense.size(); ++k) EXPECT_NEAR(got[k], dense[k], tolerance) << what << " key " << k;
}

// MATLAB's `spline` with few knots: 1 the constant, 2 the line, 3 the parabola (the paper's Table 4:
// knots {0.6, 1, 1.3}, extrapolated to 1.4 .. 1.7), 4 the cubic. The local cubic agrees for 2 and 3
// knots, Catmull-Rom for 2 and 3, and the local cubic with Catmull-Rom and not-a-knot for 4.
TEST(Spline, FewKnotsGiveTheInterpolatingPolynomial) {
  const std::vector<std::vector<double>> knot_sets = {{0.4}, {0.2, 0.9}, {0.6, 1.0, 1.3}, {0.1, 0.25, 0.7, 0.8}};
  for (const std::vector<double>& knots : knot_sets) {
    std::vector<SplineKind> kinds = {SplineKind::kNotAKnot, SplineKind::kLocalCubic};
    if (knots.size() <= 3) kinds.push_back(SplineKind::kCatmullRom);
    if (knots.size() <= 2) kinds.push_back(SplineKind::kLinear);
    for (SplineKind kind : kinds) {
      const KeyframeSpline spline(knots, kind);
      for (double t : {-1.0, 0.0, 0.15, 0.4, 0.65, 0.75, 0.95, 1.15, 1.3, 1.4, 1.5, 1.6, 1.7, 2.5}) {
        expect_weights(spline.weights(t), lagrange(knots, t), 1e-12,
                       std::string(spline_kind_name(kind)) + " K = " + std::to_string(knots.size()) + " t = " + std::to_string(t));
      }
    }
  }
}

// The keys a local kind touches: linear t_i, t_{i+1}; Catmull-Rom t_{i-1} .. t_{i+2}; local cubic
// t_{i-2} .. t_{i+3}, for t in (or extrapolated from) segment i; never more than max_keys().
TEST(Spline, LocalKindsTouchABoundedWindow) {
  const std::vector<double> times = random_times(30, 300);
  struct Case {
    SplineKind kind;
    int before, after, most;
  };
  for (const Case c :
       {Case{SplineKind::kLinear, 0, 1, 2}, Case{SplineKind::kCatmullRom, 1, 2, 4}, Case{SplineKind::kLocalCubic, 2, 3, 6}}) {
    const KeyframeSpline spline(times, c.kind);
    EXPECT_EQ(spline.max_keys(), c.most) << spline_kind_name(c.kind);
    size_t widest = 0;
    for (double t : probe_times(times, 2.0)) {
      const int i = spline.segment(t);
      for (const SplineWeights& w : {spline.weights(t), spline.derivative_weights(t)}) {
        EXPECT_LE(w.keys.size(), static_cast<size_t>(c.most)) << spline_kind_name(c.kind) << " t = " << t;
        widest = std::max(widest, w.keys.size());
        for (int32_t k : w.keys) {
          EXPECT_GE(k, i - c.before) << spline_kind_name(c.kind) << " t = " << t;
          EXPECT_LE(k, i + c.after) << spline_kind_name(c.kind) << " t = " << t;
        }
      }
    }
    EXPECT_EQ(widest, static_cast<size_t>(c.most)) << spline_kind_name(c.kind);
  }
  // Segments: a knot belongs to the segment it starts; before t_1 and from t_{K-2} on, the end ones.
  const KeyframeSpline spline(times, SplineKind::kLocalCubic);
  EXPECT_EQ(spline.segment(times[0] - 5), 0);
  EXPECT_EQ(spline.segment(times[3]), 3);
  EXPECT_EQ(spline.segment(0.5 * (times[3] + times[4])), 3);
  EXPECT_EQ(spline.segment(times.back()), 28);
  EXPECT_EQ(spline.segment(times.back() + 5), 28);
}

// The notes' standard form solved directly: the full (K x K) system for M with the not-a-knot rows
// as written, M_0 .. M_{K-1} (sparse LU), then the notes' evaluation formula on the segment (or
// the end segment for extrapolation).
std::function<double(double)> notes_not_a_knot(const std::vector<double>& t, const std::vector<double>& y) {
  const int k_count = static_cast<int>(t.size()), n = k_count - 1;
  std::vector<double> h(static_cast<size_t>(n));
  for (int k = 0; k < n; ++k) h[static_cast<size_t>(k)] = t[static_cast<size_t>(k) + 1] - t[static_cast<size_t>(k)];
  auto hk = [&](int k) { return h[static_cast<size_t>(k)]; };
  auto yk = [&](int k) { return y[static_cast<size_t>(k)]; };
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(k_count);
  // (M1 - M0) / h0 = (M2 - M1) / h1, and the same at the right end.
  entries.emplace_back(0, 0, -1 / hk(0));
  entries.emplace_back(0, 1, 1 / hk(0) + 1 / hk(1));
  entries.emplace_back(0, 2, -1 / hk(1));
  entries.emplace_back(n, n, 1 / hk(n - 1));
  entries.emplace_back(n, n - 1, -1 / hk(n - 1) - 1 / hk(n - 2));
  entries.emplace_back(n, n - 2, 1 / hk(n - 2));
  for (int k = 1; k < n; ++k) {
    entries.emplace_back(k, k - 1, hk(k - 1));
    entries.emplace_back(k, k, 2 * (hk(k - 1) + hk(k)));
    entries.emplace_back(k, k + 1, hk(k));
    rhs[k] = 6 * ((yk(k + 1) - yk(k)) / hk(k) - (yk(k) - yk(k - 1)) / hk(k - 1));
  }
  Eigen::SparseMatrix<double> a(k_count, k_count);
  a.setFromTriplets(entries.begin(), entries.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(a);
  const Eigen::VectorXd m = lu.solve(rhs);
  return [t, y, h, m, n](double x) {
    const int k = std::clamp(static_cast<int>(std::upper_bound(t.begin(), t.end(), x) - t.begin()) - 1, 0, n - 1);
    const double hh = h[static_cast<size_t>(k)], a0 = t[static_cast<size_t>(k) + 1] - x, b0 = x - t[static_cast<size_t>(k)];
    return (m[k] * a0 * a0 * a0 + m[k + 1] * b0 * b0 * b0) / (6 * hh) + (y[static_cast<size_t>(k)] / hh - m[k] * hh / 6) * a0 +
           (y[static_cast<size_t>(k) + 1] / hh - m[k + 1] * hh / 6) * b0;
  };
}

TEST(Spline, NotAKnotAgreesWithTheNotesTridiagonalForm) {
  std::mt19937 rng(400);
  struct Case {
    int count;
    double lo, hi;  // interval range: up to 1000x apart in the last case
  };
  for (const Case c : {Case{4, 0.1, 0.5}, Case{5, 0.1, 0.5}, Case{12, 0.05, 0.5}, Case{40, 0.01, 0.5}, Case{60, 0.001, 1.0}}) {
    const std::vector<double> times = random_times(c.count, 401 + static_cast<unsigned>(c.count), 1.0, c.lo, c.hi);
    const std::vector<double> y = random_values(times.size(), rng);
    const KeyframeSpline spline(times, SplineKind::kNotAKnot);
    const auto reference = notes_not_a_knot(times, y);
    for (double t : probe_times(times)) EXPECT_NEAR(blend(spline.weights(t), y), reference(t), 1e-11) << "K = " << c.count << " t = " << t;
  }
}

// Thousands of keys: built in O(K · window), each query touches a bounded window (the dropped
// coefficients are below rounding), and the values still match the direct solve.
TEST(Spline, NotAKnotScalesToThousandsOfKeys) {
  const std::vector<double> times = random_times(5000, 500, 0.0, 0.02, 0.4);
  std::mt19937 rng(501);
  const std::vector<double> y = random_values(times.size(), rng);
  const KeyframeSpline spline(times, SplineKind::kNotAKnot);
  EXPECT_LE(spline.max_keys(), 140);
  EXPECT_GE(spline.max_keys(), 20);  // it is global: the window is not a local kind's
  const auto reference = notes_not_a_knot(times, y);
  std::uniform_real_distribution<double> when(times.front() - 0.01, times.back() + 0.01);
  for (int j = 0; j < 300; ++j) {
    const double t = when(rng);
    const SplineWeights w = spline.weights(t);
    EXPECT_LE(w.keys.size(), static_cast<size_t>(spline.max_keys()));
    EXPECT_NEAR(sum_of(w), 1.0, 1e-12);
    EXPECT_NEAR(blend(w, y), reference(t), 1e-11) << "t = " << t;
  }
}

// derivative_weights is the derivative of weights (central differences), and the C¹ kinds have no
// jump in it at the knots; the linear one does.
TEST(Spline, DerivativeWeightsAreTheDerivativeAndContinuousForC1Kinds) {
  const std::vector<double> times = random_times(12, 600);
  std::mt19937 rng(601);
  const std::vector<double> y = random_values(times.size(), rng);
  for (SplineKind kind : kAllKinds) {
    const KeyframeSpline spline(times, kind);
    for (double t : probe_times(times)) {
      const double e = 1e-6;
      const double fd = (blend(spline.weights(t + e), y) - blend(spline.weights(t - e), y)) / (2 * e);
      if (kind == SplineKind::kLinear && std::find(times.begin(), times.end(), t) != times.end()) continue;
      EXPECT_NEAR(blend(spline.derivative_weights(t), y), fd, 1e-5 * (1 + std::abs(fd))) << spline_kind_name(kind) << " t = " << t;
    }
    double worst_jump = 0;
    for (size_t k = 1; k + 1 < times.size(); ++k) {
      const double left = blend(spline.derivative_weights(times[k] - 1e-10), y),
                   right = blend(spline.derivative_weights(times[k] + 1e-10), y);
      worst_jump = std::max(worst_jump, std::abs(left - right));
    }
    if (kind == SplineKind::kLinear) {
      EXPECT_GT(worst_jump, 1e-2);
    } else {
      EXPECT_LT(worst_jump, 1e-6) << spline_kind_name(kind);
    }
  }
}

TEST(Spline, SaneRangeIsOneIntervalPastEachEnd) {
  const std::vector<double> times = {0.6, 1.0, 1.3};
  for (SplineKind kind : kAllKinds) {
    const TimeRange range = KeyframeSpline(times, kind).sane_range();
    EXPECT_NEAR(range.begin, 0.2, 1e-15);
    EXPECT_NEAR(range.end, 1.6, 1e-15);
  }
  const TimeRange one = KeyframeSpline({2.0}, SplineKind::kNotAKnot).sane_range();
  EXPECT_EQ(one.begin, -std::numeric_limits<double>::infinity());
  EXPECT_EQ(one.end, std::numeric_limits<double>::infinity());
  // Beyond it the spline still answers; the caller decides.
  EXPECT_NEAR(sum_of(KeyframeSpline(times, SplineKind::kLocalCubic).weights(10.0)), 1.0, 1e-9);
}

TEST(Spline, BadInputGivesNamedErrors) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  testing::expect_error(ErrorCode::kInvalidArgument, "no keyframes", [] { KeyframeSpline({}, SplineKind::kLinear); });
  testing::expect_error(ErrorCode::kInvalidArgument, "keyframe 1 is not finite", [&] {
    KeyframeSpline({0.0, nan, 2.0}, SplineKind::kNotAKnot);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "keyframe 2 is not finite", [&] {
    KeyframeSpline({0.0, 1.0, inf}, SplineKind::kLocalCubic);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "strictly increasing at keyframe 2", [] {
    KeyframeSpline({0.0, 1.0, 1.0}, SplineKind::kCatmullRom);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "strictly increasing at keyframe 1", [] {
    KeyframeSpline({1.0, 0.5}, SplineKind::kLinear);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "overflows", [] { KeyframeSpline({-1.5e308, 1.5e308}, SplineKind::kLinear); });
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown kind", [] { KeyframeSpline({0.0}, static_cast<SplineKind>(17)); });
  const KeyframeSpline spline({0.0, 1.0, 2.0}, SplineKind::kNotAKnot);
  testing::expect_error(ErrorCode::kInvalidArgument, "non-finite t", [&] { spline.weights(nan); });
  testing::expect_error(ErrorCode::kInvalidArgument, "non-finite t", [&] { spline.derivative_weights(-inf); });
}

// --- poses ---

Vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Vec3(g(rng), g(rng), g(rng)).normalized();
}

double max_abs(const Eigen::MatrixXd& m) { return m.cwiseAbs().maxCoeff(); }

void expect_proper(const Eigen::Matrix3d& r, double tolerance) {
  EXPECT_LT(max_abs(r.transpose() * r - Eigen::Matrix3d::Identity()), tolerance);
  EXPECT_NEAR(r.determinant(), 1.0, tolerance);
}

// Points of a face-sized cloud (metres) half a metre from the origin.
std::vector<Vec3> face_cloud(std::mt19937& rng, int count) {
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  std::vector<Vec3> points;
  for (int i = 0; i < count; ++i) points.push_back(Vec3(u(rng), 1.2 * u(rng), 0.5 + 0.4 * u(rng)));
  return points;
}

TEST(Pose, ApplyInverseAndCompose) {
  RigidPose a, b;
  a.rotation = rotation_exp(Vec3(0.3, -0.2, 1.1));
  a.translation = Vec3(0.1, 0.2, -0.3);
  b.rotation = rotation_exp(Vec3(-1.0, 0.5, 0.2));
  b.translation = Vec3(-0.4, 0.0, 0.7);
  const Vec3 x(0.05, -0.02, 0.5);
  EXPECT_LT((a.inverse().apply(a.apply(x)) - x).norm(), 1e-15);
  EXPECT_LT(((a * b).apply(x) - a.apply(b.apply(x))).norm(), 1e-15);
  EXPECT_EQ(RigidPose{}.apply(x), x);
}

// Noise-free points: the known pose comes back to 1e-12, with equal, random and partly zero weights.
TEST(Pose, KabschRecoversAKnownPose) {
  std::mt19937 rng(700);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const std::vector<Vec3> from = face_cloud(rng, 3 + 10 * trial);
    RigidPose truth;
    truth.rotation = rotation_exp(random_unit(rng) * (3.1 * u(rng)));
    truth.translation = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng));
    std::vector<Vec3> to;
    for (const Vec3& p : from) to.push_back(truth.apply(p));
    std::vector<double> weights;
    for (size_t i = 0; i < from.size(); ++i) weights.push_back(trial % 3 == 2 && i >= 3 && i % 2 ? 0.0 : u(rng) + 0.1);
    const RigidPose fit = trial % 3 == 0 ? fit_rigid_pose(from, to) : fit_rigid_pose(from, to, weights);
    EXPECT_LT(max_abs(fit.rotation - truth.rotation), 1e-12) << "trial " << trial;
    EXPECT_LT((fit.translation - truth.translation).norm(), 1e-12) << "trial " << trial;
    expect_proper(fit.rotation, 1e-14);
  }
}

// A mirror image has no rotation onto it: the fit is still a proper rotation, and the best one
// (no nearby rotation does better). Flat and collinear input also give proper rotations.
TEST(Pose, KabschGivesAProperRotationForMirroredAndDegenerateInput) {
  std::mt19937 rng(710);
  const std::vector<Vec3> from = face_cloud(rng, 40);
  std::vector<Vec3> mirrored;
  for (const Vec3& p : from) mirrored.push_back(Vec3(-p.x(), p.y(), p.z()));
  const RigidPose fit = fit_rigid_pose(from, mirrored);
  expect_proper(fit.rotation, 1e-12);
  auto residual = [&](const RigidPose& pose) {
    double sum = 0;
    for (size_t i = 0; i < from.size(); ++i) sum += (pose.apply(from[i]) - mirrored[i]).squaredNorm();
    return sum;
  };
  const double best = residual(fit);
  for (int j = 0; j < 50; ++j) {
    RigidPose nearby = fit;
    nearby.rotation = rotation_exp(random_unit(rng) * 1e-3) * fit.rotation;
    nearby.translation += random_unit(rng) * 1e-4;
    EXPECT_GE(residual(nearby), best);
  }
  // Flat: still exact. Collinear: proper, and the line lands on the line.
  RigidPose truth;
  truth.rotation = rotation_exp(Vec3(0.4, -1.2, 0.3));
  truth.translation = Vec3(0.1, 0.0, 0.2);
  std::vector<Vec3> flat, line, flat_to, line_to;
  for (int i = 0; i < 12; ++i) {
    flat.push_back(Vec3(0.01 * i, 0.03 * (i % 4), 0.0));
    line.push_back(Vec3(0.02 * i, -0.01 * i, 0.5));
    flat_to.push_back(truth.apply(flat.back()));
    line_to.push_back(truth.apply(line.back()));
  }
  const RigidPose flat_fit = fit_rigid_pose(flat, flat_to);
  EXPECT_LT(max_abs(flat_fit.rotation - truth.rotation), 1e-12);
  const RigidPose line_fit = fit_rigid_pose(line, line_to);
  expect_proper(line_fit.rotation, 1e-12);
  for (size_t i = 0; i < line.size(); ++i) EXPECT_LT((line_fit.apply(line[i]) - line_to[i]).norm(), 1e-12);
}

TEST(Pose, KabschBadInputGivesNamedErrors) {
  const std::vector<Vec3> three = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  testing::expect_error(ErrorCode::kInvalidArgument, "3 points to map onto 2", [&] { fit_rigid_pose(three, {three[0], three[1]}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "at least 3 points, got 2", [&] {
    fit_rigid_pose({three[0], three[1]}, {three[0], three[1]});
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "2 weights for 3 points", [&] { fit_rigid_pose(three, three, {1.0, 1.0}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "point 1 is not finite", [&] {
    fit_rigid_pose(three, {three[0], Vec3(nan, 0, 0), three[2]});
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "weight 2 must be finite and non-negative", [&] {
    fit_rigid_pose(three, three, {1.0, 1.0, nan});
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "weight 0 must be finite and non-negative", [&] {
    fit_rigid_pose(three, three, {-1.0, 1.0, 1.0});
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "weights sum to 0", [&] { fit_rigid_pose(three, three, {0.0, 0.0, 0.0}); });
}

// log(exp(w)) = w and exp(log(R)) = R, relative to the angle near 0 and absolutely near π; exp is a
// proper rotation.
TEST(Pose, LogAndExpRoundTripAtEveryAngle) {
  std::mt19937 rng(800);
  for (double angle :
       {0.0, 1e-12, 1e-9, 1e-6, 0.99e-4, 1.01e-4, 0.1, 1.0, kPi / 2 - 1e-9, kPi / 2 + 1e-9, 2.0, 3.0, kPi - 1e-6, kPi - 1e-9}) {
    for (int j = 0; j < 20; ++j) {
      const Vec3 w = random_unit(rng) * angle;
      const Eigen::Matrix3d r = rotation_exp(w);
      expect_proper(r, 4e-15);
      const Vec3 back = rotation_log(r);
      EXPECT_LT((back - w).norm(), 2e-15 * std::max(angle, 1e-300) + 4e-16 * (angle > 1 ? 1 : 0)) << "angle " << angle;
      EXPECT_LT(max_abs(rotation_exp(back) - r), 1e-15) << "angle " << angle;
    }
  }
  // Exactly π: either sign of the axis is the answer; the rotation comes back.
  for (const Vec3& axis : {Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(Vec3(1, 2, -2) / 3)}) {
    const Eigen::Matrix3d r = rotation_exp(axis * kPi);
    const Vec3 back = rotation_log(r);
    EXPECT_NEAR(back.norm(), kPi, 1e-15);
    EXPECT_LT(std::min((back - axis * kPi).norm(), (back + axis * kPi).norm()), 1e-14);
    EXPECT_LT(max_abs(rotation_exp(back) - r), 1e-15);
  }
  // Turns past π wrap round.
  EXPECT_LT((rotation_log(rotation_exp(Vec3(0, 0, 1.5 * kPi))) - Vec3(0, 0, -0.5 * kPi)).norm(), 1e-14);
}

TEST(Pose, LogAndExpRejectBadInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  testing::expect_error(ErrorCode::kInvalidArgument, "not a finite proper rotation",
                        [] { rotation_log(Eigen::Matrix3d::Identity() * 1.01); });
  testing::expect_error(ErrorCode::kInvalidArgument, "not a finite proper rotation",
                        [] { rotation_log(Eigen::Vector3d(1, 1, -1).asDiagonal().toDenseMatrix()); });
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r(0, 1) = nan;
  testing::expect_error(ErrorCode::kInvalidArgument, "not a finite proper rotation", [&] { rotation_log(r); });
  testing::expect_error(ErrorCode::kInvalidArgument, "not finite", [&] { rotation_exp(Vec3(0, nan, 0)); });
}

// A head turning at constant angular speed about a fixed axis through `centre`, from a tilted start,
// while `centre` drifts at constant velocity.
RigidPose head_turn(double t, const Vec3& axis, double speed, const Vec3& centre) {
  const Eigen::Matrix3d start = rotation_exp(Vec3(0.3, -0.2, 0.5));
  RigidPose pose;
  pose.rotation = rotation_exp(axis * (speed * t)) * start;
  const Vec3 path = Vec3(0.01, 0.02, 0.6) + t * Vec3(0.03, -0.01, 0.02);
  pose.translation = path - pose.rotation * centre;
  return pose;
}

// Every kind that reproduces lines reproduces the turn to 1e-12 at any t in the sane range: a slow
// one (within π of the first key) and a spin through 10 rad (unwrapped), about the origin and about a
// centre in the head.
TEST(Pose, PoseSplineReproducesAConstantSpeedHeadTurn) {
  const std::vector<double> times = random_times(9, 900, 0.2, 0.15, 0.5);
  const Vec3 axis = Vec3(0.2, 1.0, -0.3).normalized();
  for (double speed : {0.8, 2.5}) {
    for (const Vec3& centre : {Vec3(0, 0, 0), Vec3(0.0, -0.08, 0.05)}) {
      std::vector<RigidPose> keys;
      for (double t : times) keys.push_back(head_turn(t, axis, speed, centre));
      for (SplineKind kind : kAllKinds) {
        const KeyframeSpline spline(times, kind);
        for (double t : probe_times(times)) {
          const RigidPose got = blend_poses(keys, spline.weights(t), centre);
          const RigidPose want = head_turn(t, axis, speed, centre);
          EXPECT_LT(max_abs(got.rotation - want.rotation), 1e-12) << spline_kind_name(kind) << " speed " << speed << " t = " << t;
          EXPECT_LT((got.translation - want.translation).norm(), 1e-12) << spline_kind_name(kind) << " speed " << speed << " t = " << t;
        }
      }
    }
  }
  // Blending the origin's path instead of the head's is not exact for a head turning about itself:
  // why `centre` exists.
  const Vec3 centre(0.0, -0.08, 0.05);
  std::vector<RigidPose> keys;
  for (double t : times) keys.push_back(head_turn(t, axis, 0.8, centre));
  const KeyframeSpline linear(times, SplineKind::kLinear);
  const double t = 0.5 * (times[3] + times[4]);
  EXPECT_GT((blend_poses(keys, linear.weights(t)).translation - head_turn(t, axis, 0.8, centre).translation).norm(), 1e-5);
}

TEST(Pose, UnwrappedRotationsAreContinuousAndBlendHitsTheKeys) {
  std::vector<RigidPose> keys;
  for (int k = 0; k < 8; ++k) {
    RigidPose pose;
    pose.rotation = rotation_exp(Vec3(0, 0, 2.0 * k)) * rotation_exp(Vec3(0.2, 0.1, 0.0));
    pose.translation = Vec3(0.1 * k, 0, 0);
    keys.push_back(pose);
  }
  const std::vector<Vec3> xi = unwrap_rotations(keys);
  const Vec3 axis = rotation_exp(Vec3(0.2, 0.1, 0.0)).transpose() * Vec3(0, 0, 1);
  for (size_t k = 0; k < keys.size(); ++k) EXPECT_LT((xi[k] - 2.0 * static_cast<double>(k) * axis).norm(), 1e-13) << "key " << k;
  // A key a whole turn from the first (the identity to rounding, its axis noise) stays on the turn.
  std::vector<RigidPose> turn(5);
  for (size_t k = 0; k < turn.size(); ++k)
    turn[k].rotation = rotation_exp(Vec3(0.6, 0.0, 0.8) * (k == 3 ? 2 * kPi : 2.1 * static_cast<double>(k)));
  const std::vector<Vec3> turn_xi = unwrap_rotations(turn);
  EXPECT_LT((turn_xi[3] - Vec3(0.6, 0.0, 0.8) * (2 * kPi)).norm(), 1e-9);
  EXPECT_LT((turn_xi[4] - Vec3(0.6, 0.0, 0.8) * 8.4).norm(), 1e-13);
  // At a key's own time the key comes back; the overload with precomputed vectors agrees exactly.
  const KeyframeSpline spline(random_times(8, 910), SplineKind::kNotAKnot);
  for (int k = 0; k < 8; ++k) {
    const SplineWeights w = spline.weights(spline.times()[static_cast<size_t>(k)]);
    const RigidPose got = blend_poses(keys, w);
    EXPECT_LT(max_abs(got.rotation - keys[static_cast<size_t>(k)].rotation), 1e-14);
    EXPECT_LT((got.translation - keys[static_cast<size_t>(k)].translation).norm(), 1e-14);
    const RigidPose same = blend_poses(keys, xi, w);
    EXPECT_EQ(same.rotation, got.rotation);
    EXPECT_EQ(same.translation, got.translation);
  }
}

TEST(Pose, BlendBadInputGivesNamedErrors) {
  std::vector<RigidPose> keys(3);
  const SplineWeights w{{0, 1}, {0.5, 0.5}};
  testing::expect_error(ErrorCode::kInvalidArgument, "no keys", [&] { blend_poses({}, w); });
  testing::expect_error(ErrorCode::kInvalidArgument, "key 3 of 3", [&] { blend_poses(keys, SplineWeights{{3}, {1.0}}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "2 keys with 1 weights", [&] { blend_poses(keys, SplineWeights{{0, 1}, {1.0}}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "no weights", [&] { blend_poses(keys, SplineWeights{}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "not finite", [&] { blend_poses(keys, SplineWeights{{0}, {std::nan("")}}); });
  testing::expect_error(ErrorCode::kInvalidArgument, "2 rotation vectors for 3 keys", [&] {
    blend_poses(keys, {Vec3::Zero(), Vec3::Zero()}, w);
  });
  keys[1].rotation(0, 0) = 2;
  testing::expect_error(ErrorCode::kInvalidArgument, "key 1: not a finite proper rotation", [&] { blend_poses(keys, w); });
  testing::expect_error(ErrorCode::kInvalidArgument, "key 1: not a finite proper rotation", [&] { unwrap_rotations(keys); });
}

}  // namespace
}  // namespace facemorph
