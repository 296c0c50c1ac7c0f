// Martínez-Velho-Carvalho path correction (method-notes §6 step 3): a pulled-back path moved, point
// by point and across strips of faces unfolded flat, toward a surface geodesic.
#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/registration/surface_path.hpp"

#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace facemorph {

using namespace path_points;

namespace {

// The third corner of a triangle laid flat with a and b placed, |ac| = la, |bc| = lb: left of
// a -> b for side +1, right for -1 (the notes' x = (|ac|² - |bc|² + |ab|²) / 2|ab|, y = ±√(|ac|² - x²)).
Vec2 third_corner(const Vec2& a, const Vec2& b, double la, double lb, double side) {
  const Vec2 e = b - a;
  const double l = e.norm();
  const Vec2 ex = e / l, ey(-ex.y(), ex.x());
  const double x = (la * la - lb * lb + l * l) / (2 * l);
  const double y = std::sqrt(std::max(la * la - x * x, 0.0));
  return a + x * ex + side * y * ey;
}

// A face laid isometrically in the plane: its corners, in the face's order.
struct Layout {
  int face = -1;
  std::array<Vec2, 3> p;
};

Layout lay_flat(const TriangleMesh& mesh, int face) {
  const Face& f = mesh.faces[static_cast<size_t>(face)];
  const Vec3& x0 = mesh.positions[static_cast<size_t>(f[0])];
  const Vec3& x1 = mesh.positions[static_cast<size_t>(f[1])];
  const Vec3& x2 = mesh.positions[static_cast<size_t>(f[2])];
  Layout layout{face, {Vec2::Zero(), Vec2((x1 - x0).norm(), 0), Vec2::Zero()}};
  layout.p[2] = third_corner(layout.p[0], layout.p[1], (x2 - x0).norm(), (x2 - x1).norm(), 1);
  return layout;
}

// Face `next`, which shares the edge {a, b} with `from`, laid on the other side of that edge.
Layout unfold_across(const TriangleMesh& mesh, const Layout& from, int a, int b, int next) {
  const Face& f = mesh.faces[static_cast<size_t>(from.face)];
  const int ka = corner_of(f, a), kb = corner_of(f, b), kc = 3 - ka - kb;
  const Vec2 pa = from.p[static_cast<size_t>(ka)], pb = from.p[static_cast<size_t>(kb)];
  const double side = cross2(pb - pa, from.p[static_cast<size_t>(kc)] - pa) > 0 ? -1 : 1;
  const Face& g = mesh.faces[static_cast<size_t>(next)];
  const Vec3& xa = mesh.positions[static_cast<size_t>(a)];
  const Vec3& xb = mesh.positions[static_cast<size_t>(b)];
  Layout layout{next, {}};
  for (size_t k = 0; k < 3; ++k) {
    if (g[k] == a) {
      layout.p[k] = pa;
    } else if (g[k] == b) {
      layout.p[k] = pb;
    } else {
      const Vec3& xc = mesh.positions[static_cast<size_t>(g[k])];
      layout.p[k] = third_corner(pa, pb, (xc - xa).norm(), (xc - xb).norm(), side);
    }
  }
  return layout;
}

// Barycentric coordinates of a path point in `face`, in the face's corner order; false when the
// point does not lie on that face.
bool bary_in(const TriangleMesh& mesh, const PathPoint& p, int face, Vec3& out) {
  const Face& f = mesh.faces[static_cast<size_t>(face)];
  out.setZero();
  switch (p.kind) {
    case PathPoint::kVertex: {
      const int k = corner_of(f, p.a);
      if (k < 0) return false;
      out[k] = 1;
      return true;
    }
    case PathPoint::kEdge: {
      const int ka = corner_of(f, p.a), kb = corner_of(f, p.b);
      if (ka < 0 || kb < 0) return false;
      out[ka] = 1 - p.t;
      out[kb] = p.t;
      return true;
    }
    case PathPoint::kFace:
      if (p.a != face) return false;
      out = p.bary;
      return true;
  }
  return false;
}

Vec2 place(const Layout& layout, const Vec3& bary) { return bary[0] * layout.p[0] + bary[1] * layout.p[1] + bary[2] * layout.p[2]; }

}  // namespace

// An edge point and its two neighbours in the plane of the edge's two faces, unfolded.
struct SurfacePaths::Unfolded {
  Vec2 prev, next, a, b;  // the edge runs from a (t = 0) to b (t = 1)
};

// The faces round a vertex in counter-clockwise order, with the unfolded angle of each edge out of
// it: edge k (to neighbours[k]) at angle theta[k], theta[0] = 0; theta.back() is the angle sum.
struct SurfacePaths::Fan {
  int v = -1;
  std::span<const int> faces;
  bool open = false;            // a boundary vertex: the fan runs from one boundary edge to the other
  std::vector<int> neighbours;  // one per face (closed), one more (open)
  std::vector<double> theta;    // one per face, plus the total
  double total() const { return theta.back(); }
};

// The unfolding of the edge point's two faces: prev in the one it touches, next in the other.
bool SurfacePaths::unfold_pair(const PathPoint& prev, const PathPoint& cur, const PathPoint& next, Unfolded& out) const {
  const int f1 = face_of(cur.a, cur.b), f2 = face_of(cur.b, cur.a);
  if (f1 < 0 || f2 < 0) return false;
  int g0 = -1, g1 = -1;
  if (touches(prev, f1) && touches(next, f2)) {
    g0 = f1;
    g1 = f2;
  } else if (touches(prev, f2) && touches(next, f1)) {
    g0 = f2;
    g1 = f1;
  } else {
    return false;  // both neighbours on one side: the point is redundant (cleanup removes it)
  }
  const TriangleMesh& mesh = map_.surface;
  const Layout l0 = lay_flat(mesh, g0), l1 = unfold_across(mesh, l0, cur.a, cur.b, g1);
  const Face& f = mesh.faces[static_cast<size_t>(g0)];
  out.a = l0.p[static_cast<size_t>(corner_of(f, cur.a))];
  out.b = l0.p[static_cast<size_t>(corner_of(f, cur.b))];
  Vec3 bp, bn;
  bary_in(mesh, prev, g0, bp);
  bary_in(mesh, next, g1, bn);
  out.prev = place(l0, bp);
  out.next = place(l1, bn);
  return true;
}

// The notes' edge step: the point moves to where the unfolded segment prev -> next meets its edge,
// or to the edge's end nearer that meeting when it falls outside. Never lengthens: along the edge's
// line |prev - x| + |x - next| is convex with its minimum at the meeting point.
bool SurfacePaths::local_step(const PathPoint& prev, PathPoint& cur, const PathPoint& next) const {
  Unfolded u;
  if (!unfold_pair(prev, cur, next, u)) return false;
  const Vec2 d = u.next - u.prev, e = u.b - u.a;
  const double den = cross2(d, e);
  if (den == 0) return false;
  const double t = cross2(u.a - u.prev, d) / den;
  if (!std::isfinite(t)) return false;
  if (t <= kSnap) {
    cur = vertex_point(cur.a);
  } else if (t >= 1 - kSnap) {
    cur = vertex_point(cur.b);
  } else {
    cur.t = t;
  }
  return true;
}

// The faces a run of edge points crosses: g[k] between run[k - 1] and run[k], g[0] before the first
// (touching prev) and g[m] after the last (touching next). False when the run does not read as a
// strip: a point on the same edge twice, or both neighbours of one point on the same side of it.
bool SurfacePaths::strip_faces(const PathPoint& prev, std::span<const PathPoint> run, const PathPoint& next, std::vector<int>& g) const {
  const size_t m = run.size();
  g.assign(m + 1, -1);
  for (size_t k = 1; k < m; ++k) {
    const PathPoint &e = run[k - 1], &e2 = run[k];
    if ((e.a == e2.a && e.b == e2.b) || (e.a == e2.b && e.b == e2.a)) return false;
    for (int f : {face_of(e.a, e.b), face_of(e.b, e.a)}) {
      if (f >= 0 && touches(e2, f)) g[k] = f;
    }
    if (g[k] < 0 || (k >= 2 && across(e.a, e.b, g[k - 1]) != g[k])) return false;
  }
  if (m == 1) {
    const int f1 = face_of(run[0].a, run[0].b), f2 = face_of(run[0].b, run[0].a);
    if (f1 < 0 || f2 < 0) return false;
    const bool forward = touches(prev, f1) && touches(next, f2);
    g[0] = forward ? f1 : f2;
    g[1] = forward ? f2 : f1;
  } else {
    g[0] = across(run[0].a, run[0].b, g[1]);
    g[m] = across(run[m - 1].a, run[m - 1].b, g[m - 1]);
  }
  return g[0] >= 0 && g[m] >= 0 && g[0] != g[1] && touches(prev, g[0]) && touches(next, g[m]);
}

// The edge step for a whole run of edge points between two anchors: the strip of faces the run
// crosses is unfolded and the run replaced by the shortest path inside it from prev to next (the
// funnel algorithm: straight pieces between strip vertices it bends round, which become vertex
// points for the vertex step). For one point this is the notes' two-triangle step exactly (the
// meeting point, or the nearer end of the edge); for a run it reaches in one step what the
// point-by-point relaxation approaches over O(n²) sweeps. Never lengthens: the old run is a path
// in the same strip.
bool SurfacePaths::pull_string(const PathPoint& prev, std::span<const PathPoint> run, const PathPoint& next,
                               std::vector<PathPoint>& out) const {
  const TriangleMesh& mesh = map_.surface;
  const size_t m = run.size();
  std::vector<int> g;
  if (!strip_faces(prev, run, next, g)) return false;
  // The portals: each run edge seen from the side the path comes from, (left, right) as one faces
  // across it; the ends are portals of one point.
  struct Portal {
    Vec2 left, right;
    int left_vertex = -1, right_vertex = -1;
  };
  std::vector<Portal> portals;
  std::vector<std::pair<Vec2, Vec2>> edges(m);  // each run edge from its a (t = 0) to its b
  Layout layout = lay_flat(mesh, g[0]);
  Vec3 bary;
  bary_in(mesh, prev, g[0], bary);
  const Vec2 P = place(layout, bary);
  portals.push_back({P, P});
  for (size_t k = 0; k < m; ++k) {
    const Face& f = mesh.faces[static_cast<size_t>(layout.face)];
    const int ka = corner_of(f, run[k].a), kb = corner_of(f, run[k].b);
    const Vec2 A = layout.p[static_cast<size_t>(ka)], B = layout.p[static_cast<size_t>(kb)];
    const Vec2 behind = layout.p[static_cast<size_t>(3 - ka - kb)];
    edges[k] = {A, B};
    if (orient2d(behind, A, B) > 0) {
      portals.push_back({B, A, run[k].b, run[k].a});
    } else {
      portals.push_back({A, B, run[k].a, run[k].b});
    }
    layout = unfold_across(mesh, layout, run[k].a, run[k].b, g[k + 1]);
  }
  bary_in(mesh, next, g[m], bary);
  const Vec2 N = place(layout, bary);
  portals.push_back({N, N});

  // The funnel: from the apex, the left and right bounds narrow portal by portal; when one side
  // crosses the other, the other's point is a corner of the path and the new apex.
  struct Corner {
    Vec2 at;
    int vertex;
    size_t portal;
  };
  std::vector<Corner> corners{{P, -1, 0}};
  Corner apex = corners.front(), left = apex, right = apex;
  for (size_t i = 1; i < portals.size(); ++i) {
    const Portal& q = portals[i];
    if (orient2d(apex.at, right.at, q.right) >= 0) {
      if (apex.at == right.at || orient2d(apex.at, left.at, q.right) < 0) {
        right = {q.right, q.right_vertex, i};
      } else {
        corners.push_back(left);
        apex = right = left;
        i = apex.portal;
        continue;
      }
    }
    if (orient2d(apex.at, left.at, q.left) <= 0) {
      if (apex.at == left.at || orient2d(apex.at, right.at, q.left) > 0) {
        left = {q.left, q.left_vertex, i};
      } else {
        corners.push_back(right);
        apex = left = right;
        i = apex.portal;
        continue;
      }
    }
  }
  corners.push_back({N, -1, m + 1});

  // Where the path crosses each run edge: at a corner, or inside the edge between two corners.
  out.clear();
  size_t j = 0;
  for (size_t k = 1; k <= m; ++k) {
    while (corners[j + 1].portal < k) ++j;
    PathPoint p;
    if (corners[j].portal == k || corners[j + 1].portal == k) {
      const Corner& c = corners[j].portal == k ? corners[j] : corners[j + 1];
      if (c.vertex < 0) return false;
      p = vertex_point(c.vertex);
    } else {
      const Vec2 d = corners[j + 1].at - corners[j].at, e = edges[k - 1].second - edges[k - 1].first;
      const double den = cross2(d, e);
      if (den == 0) return false;
      const double t = cross2(edges[k - 1].first - corners[j].at, d) / den;
      if (!std::isfinite(t)) return false;
      p = t <= kSnap ? vertex_point(run[k - 1].a)
                     : (t >= 1 - kSnap ? vertex_point(run[k - 1].b) : edge_point(run[k - 1].a, run[k - 1].b, t));
    }
    if (out.empty() || !same(out.back(), p)) out.push_back(p);
  }
  return true;
}

SurfacePaths::Fan SurfacePaths::fan_view(int v) const {
  const TriangleMesh& mesh = map_.surface;
  Fan view;
  view.v = v;
  view.faces = fan(v);
  view.open = open_fan_[static_cast<size_t>(v)] != 0;
  view.theta.push_back(0);
  const Vec3& xv = mesh.positions[static_cast<size_t>(v)];
  int second = -1;
  for (int f : view.faces) {
    const Face& face = mesh.faces[static_cast<size_t>(f)];
    const int k = corner_of(face, v);
    const int n1 = face[static_cast<size_t>((k + 1) % 3)];
    second = face[static_cast<size_t>((k + 2) % 3)];
    view.neighbours.push_back(n1);
    view.theta.push_back(view.theta.back() +
                         angle_between(mesh.positions[static_cast<size_t>(n1)] - xv, mesh.positions[static_cast<size_t>(second)] - xv));
  }
  if (view.open) view.neighbours.push_back(second);
  return view;
}

// The unfolded angle round the fan's vertex at which p lies (NaN when p is on none of its faces).
double SurfacePaths::direction(const Fan& fan, const PathPoint& p) const {
  const Vec3& xv = map_.surface.positions[static_cast<size_t>(fan.v)];
  for (size_t k = 0; k < fan.faces.size(); ++k) {
    if (!touches(p, fan.faces[k])) continue;
    const double phi = angle_between(map_.surface.positions[static_cast<size_t>(fan.neighbours[k])] - xv, position(p) - xv);
    return fan.theta[k] + std::clamp(phi, 0.0, fan.theta[k + 1] - fan.theta[k]);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

namespace {

// The angles on the two sides of a path through a vertex, from prev's direction to next's: counter-
// clockwise and clockwise. A boundary vertex's side through the outside is infinite: no shortcut
// crosses the boundary.
void side_angles(bool open, double total, double from, double to, double& ccw, double& cw) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  if (open) {
    ccw = to >= from ? to - from : kInfinity;
    cw = to <= from ? from - to : kInfinity;
    return;
  }
  ccw = std::fmod(to - from + 2 * total, total);
  cw = total - ccw;
}

}  // namespace

double SurfacePaths::min_side(const PathPoint& prev, const PathPoint& cur, const PathPoint& next) const {
  const Fan fan = fan_view(cur.a);
  const double from = direction(fan, prev), to = direction(fan, next);
  if (!std::isfinite(from) || !std::isfinite(to)) return 0;
  double ccw, cw;
  side_angles(fan.open, fan.total(), from, to, ccw, cw);
  return std::min(ccw, cw);
}

// The notes' vertex step: when the smaller side of the path at v is under π, the fan on that side is
// unfolded and v replaced by the segment prev -> next's crossings of the fan's edges (an edge's far
// vertex when the segment passes beyond it). Kept only if it does not lengthen the path.
void SurfacePaths::vertex_step(const PathPoint& prev, const PathPoint& cur, const PathPoint& next, std::vector<PathPoint>& out) const {
  const Fan fan = fan_view(cur.a);
  const double from = direction(fan, prev), to = direction(fan, next);
  double ccw = 0, cw = 0;
  if (std::isfinite(from) && std::isfinite(to)) side_angles(fan.open, fan.total(), from, to, ccw, cw);
  const double side = std::min(ccw, cw);
  if (!std::isfinite(from) || !std::isfinite(to) || !(side < std::numbers::pi)) {
    out.push_back(cur);  // both sides >= π: a shortest path may pass here
    return;
  }
  const bool forward = ccw <= cw;
  std::vector<std::pair<double, int>> rays;  // (angle from prev on that side, fan edge)
  for (size_t k = 0; k < fan.neighbours.size(); ++k) {
    double rel = forward ? fan.theta[k] - from : from - fan.theta[k];
    if (!fan.open) rel = std::fmod(rel + 2 * fan.total(), fan.total());
    if (rel > 1e-12 && rel < side - 1e-12) rays.push_back({rel, static_cast<int>(k)});
  }
  std::sort(rays.begin(), rays.end());
  const TriangleMesh& mesh = map_.surface;
  const Vec3& xv = mesh.positions[static_cast<size_t>(cur.a)];
  const Vec3 xp = position(prev), xn = position(next);
  const Vec2 P((xp - xv).norm(), 0), N = (xn - xv).norm() * Vec2(std::cos(side), std::sin(side));
  std::vector<PathPoint> replacement;
  for (const auto& [rel, k] : rays) {
    const Vec2 u(std::cos(rel), std::sin(rel));
    const double den = cross2(u, N - P);
    if (den == 0) {
      out.push_back(cur);
      return;
    }
    const double lambda = -cross2(u, P) / den;
    const double s = u.dot(P + lambda * (N - P));
    const int n = fan.neighbours[static_cast<size_t>(k)];
    const double l = (mesh.positions[static_cast<size_t>(n)] - xv).norm();
    replacement.push_back(s >= l * (1 - kSnap) ? vertex_point(n) : edge_point(cur.a, n, std::max(s / l, kSnap)));
  }
  double before = (xp - xv).norm() + (xn - xv).norm(), after = 0;
  Vec3 last = xp;
  for (const PathPoint& p : replacement) {
    const Vec3 x = position(p);
    after += (x - last).norm();
    last = x;
  }
  after += (xn - last).norm();
  if (!(after <= before * (1 + 1e-15))) {
    out.push_back(cur);
    return;
  }
  out.insert(out.end(), replacement.begin(), replacement.end());
}

double SurfacePaths::point_error(const PathPoint& prev, const PathPoint& cur, const PathPoint& next) const {
  switch (cur.kind) {
    case PathPoint::kEdge: {
      Unfolded u;
      if (!unfold_pair(prev, cur, next, u)) return shared_face(prev, next) >= 0 ? 0 : std::numbers::pi;
      const Vec2 x = u.a + cur.t * (u.b - u.a);
      return std::abs(std::numbers::pi - plane_angle(u.prev - x, u.next - x));
    }
    case PathPoint::kVertex: return std::max(0.0, std::numbers::pi - min_side(prev, cur, next));
    case PathPoint::kFace: return 0;
  }
  return 0;
}

double SurfacePaths::angle_error(std::span<const PathPoint> path) const {
  double error = 0;
  for (size_t i = 1; i + 1 < path.size(); ++i) error = std::max(error, point_error(path[i - 1], path[i], path[i + 1]));
  return error;
}

// Deletes repeated points, and a point whose predecessor and successor share a face (the straight
// piece inside that face is no longer).
void SurfacePaths::cleanup(std::vector<PathPoint>& path) const {
  std::vector<PathPoint> out;
  out.reserve(path.size());
  for (size_t i = 0; i < path.size(); ++i) {
    const PathPoint& p = path[i];
    if (!out.empty() && same(out.back(), p)) {
      if (i + 1 == path.size() && out.size() > 1) out.back() = p;  // the end itself stays
      continue;
    }
    while (out.size() >= 2 && shared_face(out[out.size() - 2], p) >= 0) out.pop_back();
    out.push_back(p);
  }
  if (out.size() < 2) out.push_back(path.back());
  path.swap(out);
}

// One sweep over the interior points, each step seeing its predecessor already moved. The notes'
// steps one point at a time (strips false), or (strips true) the funnel over each run of edge
// points, reaching back over the edge points the sweep has already put out, and the vertex step
// at once on every corner the funnel bends round (they go back to the front of the queue): a bend
// then crosses several layers of vertices in one sweep instead of one.
void SurfacePaths::sweep(std::vector<PathPoint>& path, bool strips) const {
  std::vector<PathPoint> out, run, pulled;
  out.reserve(path.size() + 16);
  out.push_back(path.front());
  // The points still to visit, the next one last; the path's end stays at the bottom.
  std::vector<PathPoint> queue(path.rbegin(), path.rend() - 1);
  // Every accepted vertex step shortens the path, but equal lengths could cycle: a budget ends them.
  size_t budget = 16 * path.size() + 256;
  while (queue.size() > 1) {
    const PathPoint cur = queue.back();
    if (cur.kind == PathPoint::kVertex) {
      queue.pop_back();
      vertex_step(out.back(), cur, queue.back(), out);
      continue;
    }
    if (cur.kind == PathPoint::kFace) {  // only an end can be inside a face
      out.push_back(cur);
      queue.pop_back();
      continue;
    }
    if (!strips) {
      PathPoint p = cur;
      queue.pop_back();
      local_step(out.back(), p, queue.back());
      out.push_back(p);
      continue;
    }
    size_t back = out.size();
    while (back > 1 && out[back - 1].kind == PathPoint::kEdge) --back;
    run.assign(out.begin() + static_cast<std::ptrdiff_t>(back), out.end());
    const size_t from_out = run.size();
    while (queue.size() > 1 && queue.back().kind == PathPoint::kEdge) {
      run.push_back(queue.back());
      queue.pop_back();
    }
    if (!pull_string(out[back - 1], run, queue.back(), pulled)) {
      // Not a strip (a redundant point, say): one point at a time, the ones already out kept.
      for (size_t k = from_out; k < run.size(); ++k) {
        PathPoint p = run[k];
        local_step(out.back(), p, k + 1 < run.size() ? run[k + 1] : queue.back());
        out.push_back(p);
      }
      continue;
    }
    out.resize(back);
    size_t corner = 0;
    while (corner < pulled.size() && pulled[corner].kind != PathPoint::kVertex) ++corner;
    if (budget > 0 && corner < pulled.size()) {
      --budget;
      out.insert(out.end(), pulled.begin(), pulled.begin() + static_cast<std::ptrdiff_t>(corner));
      queue.insert(queue.end(), pulled.rbegin(), pulled.rend() - static_cast<std::ptrdiff_t>(corner));
    } else {
      out.insert(out.end(), pulled.begin(), pulled.end());
    }
  }
  out.push_back(queue.back());
  path.swap(out);
  cleanup(path);
}

Correction SurfacePaths::correct(std::vector<PathPoint>& path, const GeodesicFrameOptions& options) const {
  Correction c;
  c.lengths.push_back(length(path));
  cleanup(path);
  c.angle_error = angle_error(path);
  double previous = length(path);
  while (!(c.angle_error < options.angle_tolerance) && c.sweeps < options.max_sweeps) {
    // Alternate directions, so a bend is not always carried the same way (a symmetric sweep).
    const bool backwards = c.sweeps % 2 == 1;
    if (backwards) std::reverse(path.begin(), path.end());
    sweep(path, options.unfold_strips);
    if (backwards) std::reverse(path.begin(), path.end());
    ++c.sweeps;
    const double now = length(path);
    c.lengths.push_back(now);
    c.angle_error = angle_error(path);
    if (!(previous - now > options.length_tolerance * previous)) break;  // no longer shortening
    previous = now;
  }
  c.converged = c.angle_error < options.angle_tolerance;
  for (size_t i = 1; i + 1 < path.size(); ++i) c.vertex_points += path[i].kind == PathPoint::kVertex;
  return c;
}

}  // namespace facemorph
