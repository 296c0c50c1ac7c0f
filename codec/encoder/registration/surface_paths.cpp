// The surface's connectivity as paths walk it (SurfacePaths: each edge's faces, each vertex's fan),
// points on it, and a straight disk segment pulled back onto it (method-notes §6 step 2).
#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/registration/surface_path.hpp"

#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace facemorph {

using namespace path_points;

namespace {

template <typename Point>
Point interpolate(const std::vector<Point>& values, const TriangleMesh& mesh, const PathPoint& p) {
  switch (p.kind) {
    case PathPoint::kVertex: return values[static_cast<size_t>(p.a)];
    case PathPoint::kEdge: return (1 - p.t) * values[static_cast<size_t>(p.a)] + p.t * values[static_cast<size_t>(p.b)];
    case PathPoint::kFace: {
      const Face& f = mesh.faces[static_cast<size_t>(p.a)];
      return p.bary[0] * values[static_cast<size_t>(f[0])] + p.bary[1] * values[static_cast<size_t>(f[1])] +
             p.bary[2] * values[static_cast<size_t>(f[2])];
    }
  }
  return values.front();
}

}  // namespace

SurfacePaths::SurfacePaths(const DiskMap& map) : map_(map), locator_(map.disk, map.surface.faces) {
  const TriangleMesh& mesh = map.surface;
  const size_t n = mesh.positions.size();
  if (map.disk.size() != n) {
    throw Error(ErrorCode::kInvalidArgument, "geodesic frame: the disk map has " + std::to_string(map.disk.size()) + " disk points for " +
                                                 std::to_string(n) + " surface vertices");
  }
  if (mesh.faces.empty() || map.rim.size() < 3)
    throw Error(ErrorCode::kInvalidArgument, "geodesic frame: the disk map has no faces or no rim");
  fan_start_.assign(n + 1, 0);
  face_of_.reserve(3 * mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& face = mesh.faces[f];
    for (int k = 0; k < 3; ++k) {
      if (face[k] < 0 || static_cast<size_t>(face[k]) >= n) {
        throw Error(ErrorCode::kInvalidArgument, "geodesic frame: face " + std::to_string(f) + " has a vertex index out of range");
      }
      face_of_[directed_edge_key(face[k], face[(k + 1) % 3])] = static_cast<int>(f);
      ++fan_start_[static_cast<size_t>(face[k]) + 1];
    }
  }
  for (size_t v = 0; v < n; ++v) fan_start_[v + 1] += fan_start_[v];
  std::vector<int> incident(static_cast<size_t>(fan_start_.back()));
  std::vector<int> cursor(fan_start_.begin(), fan_start_.end() - 1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int v : mesh.faces[f]) incident[static_cast<size_t>(cursor[static_cast<size_t>(v)]++)] = static_cast<int>(f);
  }
  // Order each fan counter-clockwise: the face after (v, n1, n2) holds the directed edge v -> n2. A
  // boundary vertex's fan starts at the face with nothing before it (no face holds n1 -> v).
  fan_faces_.resize(incident.size());
  open_fan_.assign(n, 0);
  for (size_t v = 0; v < n; ++v) {
    const size_t begin = static_cast<size_t>(fan_start_[v]), count = static_cast<size_t>(fan_start_[v + 1]) - begin;
    if (count == 0) continue;
    const int vertex = static_cast<int>(v);
    int start = incident[begin];
    for (size_t i = begin; i < begin + count; ++i) {
      const Face& f = mesh.faces[static_cast<size_t>(incident[i])];
      if (face_of(f[static_cast<size_t>((corner_of(f, vertex) + 1) % 3)], vertex) < 0) {
        start = incident[i];
        open_fan_[v] = 1;
        break;
      }
    }
    int face = start;
    size_t walked = 0;
    do {
      fan_faces_[begin + walked++] = face;
      const Face& f = mesh.faces[static_cast<size_t>(face)];
      face = face_of(vertex, f[static_cast<size_t>((corner_of(f, vertex) + 2) % 3)]);
    } while (face >= 0 && face != start && walked < count);
    const bool closed = !open_fan_[v] && face == start, ended = open_fan_[v] && face < 0;
    if (walked != count || !(closed || ended)) {
      throw Error(ErrorCode::kInvalidMesh, "geodesic frame: the faces round vertex " + std::to_string(v) + " do not form one fan");
    }
  }
}

std::span<const int> SurfacePaths::fan(int v) const {
  const size_t begin = static_cast<size_t>(fan_start_[static_cast<size_t>(v)]);
  return {fan_faces_.data() + begin, static_cast<size_t>(fan_start_[static_cast<size_t>(v) + 1]) - begin};
}

int SurfacePaths::face_of(int a, int b) const {
  const auto it = face_of_.find(directed_edge_key(a, b));
  return it == face_of_.end() ? -1 : it->second;
}

int SurfacePaths::across(int a, int b, int face) const {
  const int left = face_of(a, b), right = face_of(b, a);
  return left == face ? right : (right == face ? left : -1);
}

bool SurfacePaths::touches(const PathPoint& p, int face) const {
  const Face& f = map_.surface.faces[static_cast<size_t>(face)];
  switch (p.kind) {
    case PathPoint::kVertex: return corner_of(f, p.a) >= 0;
    case PathPoint::kEdge: return corner_of(f, p.a) >= 0 && corner_of(f, p.b) >= 0;
    case PathPoint::kFace: return p.a == face;
  }
  return false;
}

int SurfacePaths::shared_face(const PathPoint& p, const PathPoint& q) const {
  switch (p.kind) {
    case PathPoint::kVertex:
      for (int f : fan(p.a)) {
        if (touches(q, f)) return f;
      }
      return -1;
    case PathPoint::kEdge:
      for (int f : {face_of(p.a, p.b), face_of(p.b, p.a)}) {
        if (f >= 0 && touches(q, f)) return f;
      }
      return -1;
    case PathPoint::kFace: return touches(q, p.a) ? p.a : -1;
  }
  return -1;
}

bool SurfacePaths::same(const PathPoint& p, const PathPoint& q) const {
  if (p.kind != q.kind) return false;
  switch (p.kind) {
    case PathPoint::kVertex: return p.a == q.a;
    case PathPoint::kEdge:
      if (p.a == q.a && p.b == q.b) return std::abs(p.t - q.t) <= 1e-15;
      return p.a == q.b && p.b == q.a && std::abs(p.t - (1 - q.t)) <= 1e-15;
    case PathPoint::kFace: return p.a == q.a && (p.bary - q.bary).cwiseAbs().maxCoeff() <= 1e-15;
  }
  return false;
}

PathPoint SurfacePaths::at(const SurfacePoint& s) const {
  Vec3 w = s.bary.cwiseMax(0.0);
  w /= w.sum();
  const Face& f = map_.surface.faces[static_cast<size_t>(s.face)];
  const int zeros = static_cast<int>((w.array() <= kSnap).count());
  if (zeros >= 2) {
    Eigen::Index k;
    w.maxCoeff(&k);
    return vertex_point(f[static_cast<size_t>(k)]);
  }
  if (zeros == 1) {
    Eigen::Index k0;
    w.minCoeff(&k0);
    const size_t i = static_cast<size_t>(k0 + 1) % 3, j = static_cast<size_t>(k0 + 2) % 3;
    return edge_point(f[i], f[j], w[static_cast<Eigen::Index>(j)] / (w[static_cast<Eigen::Index>(i)] + w[static_cast<Eigen::Index>(j)]));
  }
  return {PathPoint::kFace, s.face, -1, 0, w};
}

Vec3 SurfacePaths::position(const PathPoint& p) const { return interpolate(map_.surface.positions, map_.surface, p); }
Vec2 SurfacePaths::disk(const PathPoint& p) const { return interpolate(map_.disk, map_.surface, p); }

double SurfacePaths::length(std::span<const PathPoint> path) const {
  double total = 0;
  for (size_t i = 0; i + 1 < path.size(); ++i) total += (position(path[i + 1]) - position(path[i])).norm();
  return total;
}

bool SurfacePaths::connected(std::span<const PathPoint> path) const {
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    if (shared_face(path[i], path[i + 1]) < 0) return false;
  }
  return true;
}

// ---- The pull-back (notes §6 step 2) ----

std::vector<PathPoint> SurfacePaths::pull_back(const Vec2& from, const Vec2& to, bool& clipped_from, bool& clipped_to) const {
  const std::vector<Face>& faces = map_.surface.faces;
  const Vec2 d = to - from;
  auto where = [](const Vec2& p) { return "(" + std::to_string(p.x()) + ", " + std::to_string(p.y()) + ")"; };
  // An end in the gap between the rim and the circle moves to where the segment enters the rim
  // polygon, convex since every rim vertex lies on the circle: clip the segment's line against the
  // half-plane of each rim edge.
  clipped_from = !locator_.locate(from).has_value();
  clipped_to = !locator_.locate(to).has_value();
  double s_in = 0, s_out = 1;
  if (clipped_from || clipped_to) {
    double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
    const size_t m = map_.rim.size();
    for (size_t k = 0; k < m; ++k) {
      const Vec2& a = map_.disk[static_cast<size_t>(map_.rim[k])];
      const Vec2 e = map_.disk[static_cast<size_t>(map_.rim[(k + 1) % m])] - a;
      const double f0 = cross2(e, from - a), f1 = cross2(e, d);
      if (f1 > 0) lo = std::max(lo, -f0 / f1);
      if (f1 < 0) hi = std::min(hi, -f0 / f1);
      if (f1 == 0 && f0 < 0) lo = std::numeric_limits<double>::infinity();
    }
    if (clipped_from) s_in = std::clamp(lo, 0.0, 1.0);
    if (clipped_to) s_out = std::clamp(hi, 0.0, 1.0);
    if (!(s_in < s_out)) {
      throw Error(ErrorCode::kNumerical,
                  "geodesic frame: the segment from " + where(from) + " to " + where(to) + " misses the disk triangulation");
    }
  }
  const Vec2 A = from + s_in * d, B = from + s_in * d + (s_out - s_in) * d;
  std::optional<SurfacePoint> start = locator_.locate(A);
  if (!start) start = locator_.locate(A, 1e-6);  // a clipped end: on a rim edge up to rounding
  if (!start) throw Error(ErrorCode::kNumerical, "geodesic frame: the point " + where(A) + " is not on the disk triangulation");

  std::vector<PathPoint> path{at(*start)};
  const Vec2 dir = B - A;
  // The face the segment runs into from a path point: an edge's face on the side dir points to, the
  // fan face whose corner holds dir at a vertex (-1 when dir points out of the mesh).
  auto face_towards = [&](const PathPoint& p, int fallback) {
    if (p.kind == PathPoint::kFace) return p.a;
    if (p.kind == PathPoint::kEdge) {
      const int left = face_of(p.a, p.b), right = face_of(p.b, p.a);
      const int f = cross2(map_.disk[static_cast<size_t>(p.b)] - map_.disk[static_cast<size_t>(p.a)], dir) > 0 ? left : right;
      return f >= 0 ? f : fallback;
    }
    int best = -1;
    double best_score = -1e-9;
    const Vec2& pv = map_.disk[static_cast<size_t>(p.a)];
    for (int f : fan(p.a)) {
      const Face& face = faces[static_cast<size_t>(f)];
      const int k = corner_of(face, p.a);
      const Vec2 u1 = map_.disk[static_cast<size_t>(face[static_cast<size_t>((k + 1) % 3)])] - pv;
      const Vec2 u2 = map_.disk[static_cast<size_t>(face[static_cast<size_t>((k + 2) % 3)])] - pv;
      const double score = std::min(cross2(u1, dir) / u1.norm(), cross2(dir, u2) / u2.norm()) / dir.norm();
      if (score > best_score) {
        best_score = score;
        best = f;
      }
    }
    return best >= 0 ? best : fallback;
  };
  int face = face_towards(path[0], start->face);
  double s_now = 0;
  const size_t limit = 4 * faces.size() + 16;
  for (size_t step = 0;; ++step) {
    if (step > limit) throw Error(ErrorCode::kNumerical, "geodesic frame: the walk from " + where(A) + " to " + where(B) + " does not end");
    if (locator_.barycentric(face, B).minCoeff() >= -1e-12) break;
    // The exit: of the edges the segment's line meets between their ends, the one farthest along.
    const Face& f = faces[static_cast<size_t>(face)];
    int best = -1;
    double best_s = -std::numeric_limits<double>::infinity(), best_t = 0;
    for (int k = 0; k < 3; ++k) {
      const Vec2& pa = map_.disk[static_cast<size_t>(f[static_cast<size_t>(k)])];
      const Vec2 e = map_.disk[static_cast<size_t>(f[static_cast<size_t>((k + 1) % 3)])] - pa;
      const double den = cross2(dir, e);
      if (den == 0) continue;
      const double s = cross2(pa - A, e) / den, t = cross2(pa - A, dir) / den;
      if (t < -1e-9 || t > 1 + 1e-9) continue;
      if (s > best_s) {
        best = k;
        best_s = s;
        best_t = t;
      }
    }
    if (best < 0 || best_s >= 1) break;  // B is in this face up to rounding
    if (best_s < s_now - 1e-9)
      throw Error(ErrorCode::kNumerical, "geodesic frame: the walk from " + where(A) + " to " + where(B) + " turned back");
    s_now = std::max(s_now, best_s);
    const int a = f[static_cast<size_t>(best)], b = f[static_cast<size_t>((best + 1) % 3)];
    const double t = std::clamp(best_t, 0.0, 1.0);
    const PathPoint p = t <= kSnap ? vertex_point(a) : (t >= 1 - kSnap ? vertex_point(b) : edge_point(a, b, t));
    if (!same(path.back(), p)) path.push_back(p);
    face = p.kind == PathPoint::kEdge ? across(a, b, face) : face_towards(p, -1);
    if (face < 0) break;  // out through the rim: the end lies on it
  }
  std::optional<SurfacePoint> end;
  if (face >= 0) {
    end = SurfacePoint{face, locator_.barycentric(face, B)};
  } else {
    end = locator_.locate(B, 1e-6);
    if (!end) throw Error(ErrorCode::kNumerical, "geodesic frame: the point " + where(B) + " is not on the disk triangulation");
  }
  const PathPoint last = at(*end);
  if (!same(path.back(), last)) path.push_back(last);
  if (path.size() < 2) path.push_back(path.back());  // both ends at one vertex: a path of length 0
  return path;
}

}  // namespace facemorph
