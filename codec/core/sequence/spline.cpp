// Cardinal weights of the keyframe splines (method-notes §7). Every kind evaluates a cubic (or
// linear) piece per segment [t_i, t_{i+1}] from per-key rows of weights precomputed once: the
// tangents m_k for the Hermite kinds, the second derivatives M_k for not-a-knot. A query is then a
// handful of sparse row sums, and extrapolation is the same piece evaluated outside its segment.
#include "codec/core/sequence/spline.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace facemorph {

const char* spline_kind_name(SplineKind kind) { return name_of(kSplineKinds, kind); }

SplineKind parse_spline_kind(const std::string& name) { return parse_name(kSplineKinds, name, "spline"); }

namespace {

// Not-a-knot second-derivative coefficients smaller than this fraction of their row's largest are
// dropped. The rows decay at least 2x per key, so the dropped tail is below 2^-59 of the row: far
// under the rounding (2^-53) of the sums the blend forms with them.
constexpr double kDropBelow = 0x1p-60;

// The derivative at times[k] of the Lagrange interpolant through times[first .. first + n - 1], as
// weights on those keys: L_k'(t_k) = Σ_{m≠k} 1 / (t_k - t_m), and for j ≠ k
// L_j'(t_k) = Π_{m≠j,k} (t_k - t_m) / Π_{m≠j} (t_j - t_m). Differences of times only, so a large
// time offset costs no precision.
std::vector<double> lagrange_derivative(const std::vector<double>& t, int first, int n, int k) {
  std::vector<double> w(static_cast<size_t>(n), 0.0);
  const double tk = t[static_cast<size_t>(k)];
  for (int j = first; j < first + n; ++j) {
    const double tj = t[static_cast<size_t>(j)];
    double value;
    if (j == k) {
      value = 0;
      for (int m = first; m < first + n; ++m) {
        if (m != k) value += 1 / (tk - t[static_cast<size_t>(m)]);
      }
    } else {
      double numerator = 1, denominator = 1;
      for (int m = first; m < first + n; ++m) {
        if (m == j) continue;
        denominator *= tj - t[static_cast<size_t>(m)];
        if (m != k) numerator *= tk - t[static_cast<size_t>(m)];
      }
      value = numerator / denominator;
    }
    w[static_cast<size_t>(j - first)] = value;
  }
  return w;
}

}  // namespace

KeyframeSpline::KeyframeSpline(std::vector<double> times, SplineKind kind) : times_(std::move(times)), kind_(kind) {
  auto fail = [](const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "keyframe spline: " + what); };
  if (kind != SplineKind::kLocalCubic && kind != SplineKind::kCatmullRom && kind != SplineKind::kNotAKnot && kind != SplineKind::kLinear) {
    fail("unknown kind " + std::to_string(static_cast<int>(kind)));
  }
  if (times_.empty()) fail("no keyframes");
  if (times_.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max())) fail("too many keyframes");
  for (size_t k = 0; k < times_.size(); ++k) {
    if (!std::isfinite(times_[k])) fail("time of keyframe " + std::to_string(k) + " is not finite");
    if (k == 0) continue;
    // A finite, invertible interval: every kind divides by it.
    const double h = times_[k] - times_[k - 1];
    if (!(h > 0)) fail("times not strictly increasing at keyframe " + std::to_string(k));
    if (!std::isfinite(h) || !std::isfinite(1 / h)) fail("interval before keyframe " + std::to_string(k) + " overflows");
  }
  const int n_keys = key_count();
  if (n_keys == 1) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    sane_ = {-kInf, kInf};
    return;
  }
  sane_ = {times_[0] - (times_[1] - times_[0]), times_.back() + (times_.back() - times_[times_.size() - 2])};
  if (kind_ == SplineKind::kCatmullRom || kind_ == SplineKind::kLocalCubic) rows_ = hermite_tangents(times_, kind_);
  if (kind_ == SplineKind::kNotAKnot) rows_ = not_a_knot_second_derivatives(times_);

  // The widest window a segment's piece touches.
  max_keys_ = 2;
  if (kind_ != SplineKind::kLinear) {
    for (int i = 0; i + 1 < n_keys; ++i) {
      int first = i, end = i + 2;
      for (int k : {i, i + 1}) {
        const Row& row = rows_[static_cast<size_t>(k)];
        if (row.values.empty()) continue;
        first = std::min(first, row.first);
        end = std::max(end, row.first + static_cast<int>(row.values.size()));
      }
      max_keys_ = std::max(max_keys_, end - first);
    }
  }
}

std::vector<KeyframeSpline::Row> KeyframeSpline::hermite_tangents(const std::vector<double>& times, SplineKind kind) {
  const int n_keys = static_cast<int>(times.size());
  const int order = std::min(n_keys, kind == SplineKind::kCatmullRom ? 3 : 4);
  std::vector<Row> rows(times.size());
  for (int k = 0; k < n_keys; ++k) {
    Row& row = rows[static_cast<size_t>(k)];
    if (kind == SplineKind::kCatmullRom || order < 4) {
      // Centred where it fits, one-sided at the ends; with fewer keys than the order, all of them.
      row.first = std::clamp(k - (order - 1) / 2, 0, n_keys - order);
      row.values = lagrange_derivative(times, row.first, order, k);
      continue;
    }
    // The two cubics with t_k among their middle knots; at the end knots, the nearest one.
    std::vector<int32_t> windows;
    for (int first : {k - 2, k - 1}) {
      if (first >= 0 && first + 3 <= n_keys - 1) windows.push_back(first);
    }
    if (windows.empty()) windows.push_back(std::clamp(k - 1, 0, n_keys - 4));
    row.first = windows.front();
    row.values.assign(static_cast<size_t>(windows.back() - windows.front() + 4), 0.0);
    for (int32_t first : windows) {
      const std::vector<double> w = lagrange_derivative(times, first, 4, k);
      for (size_t j = 0; j < w.size(); ++j)
        row.values[static_cast<size_t>(first - row.first) + j] += w[j] / static_cast<double>(windows.size());
    }
  }
  return rows;
}

std::vector<KeyframeSpline::Row> KeyframeSpline::not_a_knot_second_derivatives(const std::vector<double>& times) {
  const size_t n_keys = times.size();
  std::vector<Row> rows(n_keys);  // 1 key: the constant; 2 keys: the line; M = 0
  auto h = [&](size_t k) { return times[k + 1] - times[k]; };
  if (n_keys == 3) {
    // Both not-a-knot conditions make the two pieces one parabola: M is its constant second
    // derivative, 2 [t0, t1, t2] y.
    const double h0 = h(0), h1 = h(1), c = 2 / (h0 + h1);
    for (Row& row : rows) row = {0, {c / h0, -c * (1 / h0 + 1 / h1), c / h1}};
  }
  if (n_keys < 4) return rows;
  // The notes' system with M_0 and M_N eliminated by the not-a-knot conditions: a tridiagonal system
  // A m = D y for m = (M_1 .. M_{N-1}), reduced row r ↔ key r + 1, row r of A being
  // (lo_r, mid_r, up_r) and row r of D scale_r · 6 (δ_{r+1} - δ_r). The first row,
  //   (h0 + 2 h1) M1 + (h1 - h0) M2 = h1 / (h0 + h1) · 6 (δ1 - δ0),
  // and its mirror at the other end stay strictly diagonally dominant like the interior ones.
  const size_t n = n_keys - 2, last = n_keys - 1;
  std::vector<double> lo(n), mid(n), up(n), scale(n, 1.0);
  for (size_t r = 0; r < n; ++r) {
    const double ha = h(r), hb = h(r + 1);
    lo[r] = ha;
    mid[r] = 2 * (ha + hb);
    up[r] = hb;
  }
  mid[0] = h(0) + 2 * h(1);
  up[0] = h(1) - h(0);
  scale[0] = h(1) / (h(0) + h(1));
  lo[n - 1] = h(n - 1) - h(n);
  mid[n - 1] = 2 * h(n - 1) + h(n);
  scale[n - 1] = h(n - 1) / (h(n - 1) + h(n));
  // Pivots of the top-down (d) and bottom-up (e) eliminations. Row r of A⁻¹ is 1 / γ_r on the
  // diagonal and decays outward by the ratios below (the twisted factorisation), so each row costs
  // only its own length: O(K · window) in all, not O(K²).
  std::vector<double> d(n), e(n), x(n);
  d[0] = mid[0];
  for (size_t r = 1; r < n; ++r) d[r] = mid[r] - lo[r] * up[r - 1] / d[r - 1];
  e[n - 1] = mid[n - 1];
  for (size_t r = n - 1; r-- > 0;) e[r] = mid[r] - up[r] * lo[r + 1] / e[r + 1];
  for (size_t r = 0; r < n; ++r) {
    double gamma = mid[r];
    if (r > 0) gamma -= lo[r] * up[r - 1] / d[r - 1];
    if (r + 1 < n) gamma -= up[r] * lo[r + 1] / e[r + 1];
    x[r] = 1 / gamma;
    double largest = std::abs(x[r]);
    size_t x_lo = r, x_hi = r;
    // Outward until negligible: every ratio is below 1/2 except the first step off an end row, so
    // a value under the threshold stays under it.
    for (size_t j = r + 1; j < n; ++j) {
      x[j] = -up[j - 1] / e[j] * x[j - 1];
      if (std::abs(x[j]) <= kDropBelow * largest) break;
      largest = std::max(largest, std::abs(x[j]));
      x_hi = j;
    }
    for (size_t j = r; j-- > 0;) {
      x[j] = -lo[j + 1] / d[j] * x[j + 1];
      if (std::abs(x[j]) <= kDropBelow * largest) break;
      largest = std::max(largest, std::abs(x[j]));
      x_lo = j;
    }
    // M_{r+1} = Σ_j x_j (D y)_j, where row j of D touches keys j .. j + 2.
    Row& row = rows[r + 1];
    row.first = static_cast<int32_t>(x_lo);
    row.values.assign(x_hi - x_lo + 3, 0.0);
    for (size_t j = x_lo; j <= x_hi; ++j) {
      const double c = 6 * scale[j] * x[j], ia = 1 / h(j), ib = 1 / h(j + 1);
      double* v = &row.values[j - x_lo];
      v[0] += c * ia;
      v[1] -= c * (ia + ib);
      v[2] += c * ib;
    }
  }
  // The end second derivatives from the not-a-knot conditions, (M_1 - M_0) / h_0 = (M_2 - M_1) / h_1
  // and its mirror: M_0 = (1 + ρ) M_1 - ρ M_2 with ρ = h_0 / h_1.
  auto extend = [&](size_t to, size_t near, size_t far, double ratio) {
    const Row& a = rows[near];
    const Row& b = rows[far];
    Row& out = rows[to];
    out.first = std::min(a.first, b.first);
    const int32_t end = std::max(a.first + static_cast<int32_t>(a.values.size()), b.first + static_cast<int32_t>(b.values.size()));
    out.values.assign(static_cast<size_t>(end - out.first), 0.0);
    for (size_t j = 0; j < a.values.size(); ++j) out.values[static_cast<size_t>(a.first - out.first) + j] += (1 + ratio) * a.values[j];
    for (size_t j = 0; j < b.values.size(); ++j) out.values[static_cast<size_t>(b.first - out.first) + j] -= ratio * b.values[j];
  };
  extend(0, 1, 2, h(0) / h(1));
  extend(last, last - 1, last - 2, h(last - 1) / h(last - 2));
  return rows;
}

int KeyframeSpline::segment(double t) const {
  if (times_.size() < 2) return 0;
  // The first interior knot strictly after t, so a knot belongs to the segment it starts.
  const auto it = std::upper_bound(times_.begin() + 1, times_.end() - 1, t);
  return static_cast<int>(it - times_.begin()) - 1;
}

SplineWeights KeyframeSpline::weights(double t) const { return evaluate(t, false); }

SplineWeights KeyframeSpline::derivative_weights(double t) const { return evaluate(t, true); }

uint64_t KeyframeSpline::memory_bytes() const {
  uint64_t bytes = sizeof(double) * times_.capacity() + sizeof(Row) * rows_.capacity();
  for (const Row& row : rows_) bytes += sizeof(double) * row.values.capacity();
  return bytes;
}

SplineWeights KeyframeSpline::evaluate(double t, bool derivative) const {
  if (!std::isfinite(t)) {
    throw Error(ErrorCode::kInvalidArgument,
                std::string("keyframe spline: ") + (derivative ? "derivative " : "") + "weights at a non-finite t");
  }
  SplineWeights out;
  if (times_.size() == 1) {
    if (!derivative) out = {{0}, {1.0}};
    return out;
  }
  const int i = segment(t);
  const double t0 = times_[static_cast<size_t>(i)], t1 = times_[static_cast<size_t>(i) + 1], h = t1 - t0;
  // Barycentric coordinates in the segment, exactly (1, 0) at t_i and (0, 1) at t_{i+1}, so a key's
  // own time gets weight exactly 1 for that key and exactly 0 for every other.
  const double a = (t1 - t) / h, b = (t - t0) / h;

  // Weights on the keys i, i + 1 themselves, and the factors of the rows of i and i + 1.
  double wi, wj, ri, rj;
  switch (kind_) {
    case SplineKind::kLinear:
      wi = derivative ? -1 / h : a;
      wj = derivative ? 1 / h : b;
      ri = rj = 0;
      break;
    case SplineKind::kNotAKnot:
      // s = a y_i + b y_{i+1} + h²/6 [(a³ - a) M_i + (b³ - b) M_{i+1}] (the notes' evaluation form).
      if (derivative) {
        wi = -1 / h;
        wj = 1 / h;
        ri = -h / 6 * (3 * a * a - 1);
        rj = h / 6 * (3 * b * b - 1);
      } else {
        wi = a;
        wj = b;
        ri = h * h / 6 * ((a - 1) * a * (a + 1));
        rj = h * h / 6 * ((b - 1) * b * (b + 1));
      }
      break;
    default: {
      // Cubic Hermite on s = b: h00 y_i + h10 h m_i + h01 y_{i+1} + h11 h m_{i+1}.
      const double s = b;
      if (derivative) {
        wi = 6 * s * (s - 1) / h;
        wj = -wi;
        ri = (3 * s - 1) * (s - 1);
        rj = s * (3 * s - 2);
      } else {
        wi = (2 * s + 1) * (s - 1) * (s - 1);
        wj = s * s * (3 - 2 * s);
        ri = h * s * (s - 1) * (s - 1);
        rj = h * s * s * (s - 1);
      }
      break;
    }
  }

  const Row* rows[2] = {nullptr, nullptr};
  if (kind_ != SplineKind::kLinear) {
    rows[0] = &rows_[static_cast<size_t>(i)];
    rows[1] = &rows_[static_cast<size_t>(i) + 1];
  }
  int first = i, end = i + 2;
  for (const Row* row : rows) {
    if (!row || row->values.empty()) continue;
    first = std::min(first, row->first);
    end = std::max(end, row->first + static_cast<int>(row->values.size()));
  }
  std::vector<double> sum(static_cast<size_t>(end - first), 0.0);
  sum[static_cast<size_t>(i - first)] += wi;
  sum[static_cast<size_t>(i + 1 - first)] += wj;
  const double factor[2] = {ri, rj};
  for (int r = 0; r < 2; ++r) {
    // At a knot the rows add nothing: skip them.
    if (!rows[r] || factor[r] == 0) continue;
    for (size_t j = 0; j < rows[r]->values.size(); ++j)
      sum[static_cast<size_t>(rows[r]->first - first) + j] += factor[r] * rows[r]->values[j];
  }
  for (size_t j = 0; j < sum.size(); ++j) {
    if (sum[j] == 0) continue;
    out.keys.push_back(first + static_cast<int32_t>(j));
    out.weights.push_back(sum[j]);
  }
  return out;
}

}  // namespace facemorph
