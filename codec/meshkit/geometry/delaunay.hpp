// Planar Delaunay triangulation (Bowyer-Watson) of a point set, covering its convex hull.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <span>
#include <vector>

namespace facemorph {

// Sign of the orientation of (a, b, c): > 0 counter-clockwise, < 0 clockwise, 0 collinear.
// Double precision with a long-double recheck near zero.
double orient2d(const Vec2& a, const Vec2& b, const Vec2& c);
// > 0 when d lies inside the circle through the counter-clockwise triangle (a, b, c).
double incircle(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d);

// Counter-clockwise triangles over `points` covering their convex hull. Exact duplicates are left
// out of the triangulation (they appear in no face). Throws kNumerical if a numerically degenerate
// configuration breaks the cavity (does not happen for jittered inputs; callers perturb and retry).
std::vector<Face> delaunay_triangulation(std::span<const Vec2> points);

}  // namespace facemorph
