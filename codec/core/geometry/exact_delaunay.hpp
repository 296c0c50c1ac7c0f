// Delaunay triangulation of integer points with exact predicates and a symbolic tie-break: the
// same faces on every platform and compiler, which is what makes the shared grid G normative
// (spec/method.md §4). No floating point anywhere.
//
// The in-circle test is the sign of the determinant of the lifted points. Ties (four points on one
// circle, such as the corners of every grid square) are broken by perturbing the lifting
// x² + y² to x² + y² − ε·x·y + ε²·(x² − y²) with ε infinitesimal: the signs of the three
// determinants decide in that order. The −ε·x·y term splits every axis-aligned square along its
// diagonal from (x, y) to (x + 1, y + 1).
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace facemorph {

struct IntPoint {
  int64_t x = 0, y = 0;
  bool operator==(const IntPoint&) const = default;
};

// Coordinates accepted by the exact predicates: |x|, |y| <= 2^30.
inline constexpr int64_t kExactCoordinateLimit = int64_t{1} << 30;

// Sign of the orientation of (a, b, c): +1 counter-clockwise, -1 clockwise, 0 collinear. Exact for
// |coordinates| < 2^62.
int exact_orientation(const IntPoint& a, const IntPoint& b, const IntPoint& c);

// +1 when d lies inside the circle through the counter-clockwise triangle (a, b, c) under the
// perturbed lifting above, -1 outside, 0 only when all three determinants vanish. Exact for
// |coordinates| <= 2^34.
int perturbed_incircle(const IntPoint& a, const IntPoint& b, const IntPoint& c, const IntPoint& d);

struct ExactDelaunayResult {
  std::vector<Face> faces;  // counter-clockwise, covering the convex hull; in no particular order
  // In-circle tests that no perturbation term decided (they were treated as "outside"). With none,
  // the triangulation is the unique one the perturbed lifting defines.
  int unresolved_ties = 0;
};

// Bowyer-Watson with exact predicates. Throws kInvalidArgument for coordinates beyond
// kExactCoordinateLimit or repeated points.
ExactDelaunayResult exact_delaunay(std::span<const IntPoint> points);

}  // namespace facemorph
