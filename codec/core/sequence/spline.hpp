// The spline homotopy over keyframes (method-notes §7, spec/method.md §7): the cardinal weights
// c_k(t) of a spline through keyframes at non-uniform times t_k. Every stored quantity is linear in
// its keyframes, so the decoder blends each array as Σ c_k(t) y_k with one set of weights per output
// time; the weights are those of the spline through the unit vectors e_k.
//
// Extrapolation before the first and after the last keyframe continues the end polynomial piece.
// It is sane for one keyframe interval beyond each end (sane_range). The encoder keeps the first
// and last frames as keyframes, so the capture itself never needs extrapolation. One interval is
// the margin for a player asking a little past either end. Further out the error of a cubic end
// piece grows like the fourth power of the distance. For the cubic through the last
// four knots, evenly spaced, the error bound (the node polynomial) is 6.6x its in-range maximum half
// an interval out, 24x one interval out, 120x two. Quantisation noise grows with it: Σ|c_k| is 6,
// 15 and 49 there. The paper's own extrapolation error doubles from t = 1.4 to 1.7 past its
// last knot at 1.3 (Table 4). The spline never refuses a finite t; the caller decides what to do
// beyond sane_range (the sequence decoder reports kOutOfRange or clamps).
#pragma once

#include "codec/core/util/enum_names.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace facemorph {

enum class SplineKind {
  // Local C¹ cubic Hermite. The tangent at t_k is the mean of the derivatives at t_k of the cubic
  // Lagrange interpolants through t_{k-2..k+1} and t_{k-1..k+2}. Near the ends, where only one
  // of the two fits, that one is used; at the end knots, the one-sided cubic through the four
  // nearest knots. Cubic data is reproduced exactly. A segment touches at most 6 keys,
  // t_{i-2..i+3}. With 3 keys it is the interpolating parabola, with 2 the line.
  kLocalCubic,
  // The notes' non-uniform Catmull-Rom: Hermite with the 3-point tangent, the derivative of the
  // parabola through t_{k-1}, t_k, t_{k+1} at t_k; at the end knots, the one-sided parabola through
  // the three nearest knots. Quadratics are reproduced exactly; C¹; at most 4 keys, t_{i-1..i+2}.
  kCatmullRom,
  // The global C² cubic spline with not-a-knot end conditions (MATLAB `spline`): the paper's Table 4.
  // Cubics are reproduced exactly; 2 knots give the line, 3 the interpolating parabola, 4 the
  // interpolating cubic. Every key has a weight in exact arithmetic. That weight decays at least
  // 2x per key away from t (the reduced system is strictly diagonally dominant), and only about
  // 3.7x for even spacing. Second-derivative coefficients below 2^-60 of their row's largest
  // are dropped, far below the blend's rounding. A query therefore touches a bounded window,
  // max_keys(). Measured: 63 to 66 keys for even spacing and for random intervals up to 1000x
  // apart, K = 10^3 to 10^5. The 2x bound allows about 130.
  kNotAKnot,
  // Piecewise linear: C⁰, lines reproduced; at most 2 keys, t_i and t_{i+1}.
  kLinear,
};
// Each kind's name (settings, command lines) and the number the header stores (spec/container.md §5).
inline constexpr CodedEnumName<SplineKind, uint8_t> kSplineKinds[] = {{SplineKind::kLocalCubic, "local", 0},
                                                                      {SplineKind::kCatmullRom, "catmull-rom", 1},
                                                                      {SplineKind::kNotAKnot, "not-a-knot", 2},
                                                                      {SplineKind::kLinear, "linear", 3}};
static_assert(is_one_to_one(kSplineKinds));
const char* spline_kind_name(SplineKind kind);          // "local", "catmull-rom", "not-a-knot", "linear"
SplineKind parse_spline_kind(const std::string& name);  // throws kInvalidArgument naming the choices

// Sparse cardinal weights at one time: s(t) = Σ_i weights[i] · y[keys[i]]. Keys are strictly
// increasing and consecutive except where a weight is exactly zero: such keys are left out, so at a
// keyframe's own time only that keyframe remains, with weight exactly 1. Never empty for a spline's
// values (they sum to 1). For derivatives, the weights sum to 0 and may all be zero (then keys is
// empty).
struct SplineWeights {
  std::vector<int32_t> keys;
  std::vector<double> weights;
};

// [begin, end] in the keyframes' time unit: where extrapolation is sane (see the file comment).
struct TimeRange {
  double begin = 0;
  double end = 0;
};

// A spline over fixed keyframe times: validates them once and precomputes what every query needs.
// For the local kinds that is the tangent weights of each key. For not-a-knot it is the rows of the
// cardinal second-derivative matrix, in O(K · window) time and memory (10^5 keys: about 0.1 s).
// Immutable after construction: queries are const and thread-safe.
class KeyframeSpline {
 public:
  // `times`: the keyframes' times in any unit (the sequence uses seconds), finite and strictly
  // increasing, at least one (one keyframe: the constant, weight 1 everywhere). Throws
  // kInvalidArgument naming the first bad entry, or an unknown kind.
  KeyframeSpline(std::vector<double> times, SplineKind kind);

  SplineKind kind() const { return kind_; }
  int key_count() const { return static_cast<int>(times_.size()); }
  const std::vector<double>& times() const { return times_; }

  // The cardinal weights c_k(t) at any finite t, extrapolating past the ends by the end piece.
  // Unitless, summing to 1 to rounding. Throws kInvalidArgument for a non-finite t.
  SplineWeights weights(double t) const;

  // dc_k/dt at t, in 1 / (time unit), summing to 0 to rounding. The linear spline's derivative
  // jumps at the knots; there the right-hand segment's (the left one's at the last knot) is used.
  // Throws kInvalidArgument for a non-finite t.
  SplineWeights derivative_weights(double t) const;

  // Where extrapolation is sane: one keyframe interval beyond each end,
  // [t_0 - (t_1 - t_0), t_{K-1} + (t_{K-1} - t_{K-2})]. With one keyframe the constant is sane
  // everywhere: [-inf, +inf].
  TimeRange sane_range() const { return sane_; }

  // The most keys any weights() or derivative_weights() call returns for these times: at most 2
  // (linear), 4 (Catmull-Rom), 6 (local cubic), never more than key_count(). For not-a-knot,
  // the widest window left after dropping coefficients.
  int max_keys() const { return max_keys_; }

  // What this spline holds, in bytes: its times and rows (a decoder's, for its memory budget; a
  // not-a-knot row keeps up to 124 weights, so this grows with the keyframes far past the index).
  uint64_t memory_bytes() const;

  // The segment [t_i, t_{i+1}] whose polynomial piece serves t: 0 before t_1, K - 2 from t_{K-2}
  // on (0 when K = 1). Assumes a finite t.
  int segment(double t) const;

 private:
  // A row of sparse weights over consecutive keys first, first + 1, ...
  struct Row {
    int32_t first = 0;
    std::vector<double> values;
  };
  SplineWeights evaluate(double t, bool derivative) const;
  static std::vector<Row> hermite_tangents(const std::vector<double>& times, SplineKind kind);
  static std::vector<Row> not_a_knot_second_derivatives(const std::vector<double>& times);

  std::vector<double> times_;
  SplineKind kind_;
  // Local kinds: the tangent m_k as weights on the keys. Not-a-knot: the second derivative M_k.
  std::vector<Row> rows_;
  TimeRange sane_;
  int max_keys_ = 1;
};

}  // namespace facemorph
