// Elementary plane and space geometry shared across the codec, internal: the 2D cross product, the
// signed area of a plane triangle, angles between vectors, a point inside a polygon, the smoothstep
// blend. Inline, so each caller computes exactly
// what its own copy did (same operations, same order).
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace facemorph {

// u x v in the plane: |u| |v| sin of the angle from u to v (positive counter-clockwise).
inline double cross2(const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); }

// Signed area of the plane triangle abc: positive when counter-clockwise.
inline double signed_area(const Vec2& a, const Vec2& b, const Vec2& c) { return 0.5 * cross2(b - a, c - a); }

// The angle between u and v in radians, in [0, π] (0 when either is zero); atan2 of |u x v| and
// u · v stays accurate near 0 and π, where acos of the normalised dot product does not. Two names,
// not overloads: an Eigen expression argument would make overloads ambiguous.
inline double angle_between(const Vec3& u, const Vec3& v) { return std::atan2(u.cross(v).norm(), u.dot(v)); }
inline double plane_angle(const Vec2& u, const Vec2& v) { return std::atan2(std::abs(cross2(u, v)), u.dot(v)); }

// The signed angle that turns u onto v in radians, in [-π, π]: positive counter-clockwise.
inline double turning_angle(const Vec2& u, const Vec2& v) { return std::atan2(cross2(u, v), u.dot(v)); }

// Crossing-number test of a point against a closed polygon (its vertices in order, the last joined
// to the first).
inline bool inside_polygon(const Vec2& p, const std::vector<Vec2>& polygon) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vec2 &a = polygon[i], &b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) inside = !inside;
  }
  return inside;
}

// 0 below 0, 1 above 1, and between them 3t² - 2t³: a blend whose slope is 0 at both ends.
inline double smoothstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

}  // namespace facemorph
