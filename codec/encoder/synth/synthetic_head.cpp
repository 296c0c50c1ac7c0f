// The synthetic whole head (fmsynth --head) and the face's holes (fmsynth --holes): see
// codec/encoder/synth/synth.hpp. The back of the head is a star-shaped surface about a point behind
// the face, sampled by directions: directions evenly spread on the sphere (a Fibonacci lattice),
// triangulated by Delaunay in a stereographic plane (conformal, so the planar Delaunay is the
// spherical one and the triangles come out near-equilateral on the head), between the face's rim
// and the neck's. Its vertices follow the face's rim where they join it, fading with the angle away.
#include "codec/encoder/synth/synth.hpp"
#include "format/error.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace facemorph {
namespace {

const Vec3 kCentre(0, 0.0, -0.06);                      // the head's rays start here (behind the nose, metres)
const Vec3 kNeckAxis = Vec3(0, -1, -0.3).normalized();  // down and a little back: where the neck leaves
// The neck rim: directions this far from kNeckAxis, where the neck cylinder is 0.215 m from
// kCentre (its rim about 0.1 m below the chin). A neck is a tube, and a conformal map shrinks a
// tube's far end by about e per radius of its length: this is what crowds a whole head's map.
constexpr double kNeckCap = 14 * std::numbers::pi / 180;
constexpr double kNeckRingsTo = 40 * std::numbers::pi / 180;  // the neck sampled in rings up to here, the rest by a lattice
constexpr double kJoinAngle = 25 * std::numbers::pi / 180;    // the back follows the face's rim within this angle
// The cranium: an ellipsoid about (0, 0.01, -0.06) whose section by the face's plane z = 0 is near
// the face's rim ellipse (0.08 x 0.10), so the join needs only a small correction.
const Vec3 kSkullCentre(0, 0.01, -0.06);
const Vec3 kSkullAxes(0.0955, 0.119, 0.11);
constexpr double kNeckRadius = 0.052;  // the neck: a cylinder about the axis through kCentre

// The two hole kinds' material ellipses (centre, semi-axes), inside the eyes' and mouth's colours.
struct HoleEllipse {
  Vec2 centre, axes;
};
const std::array<HoleEllipse, 5> kHoles = {{{{-0.032, 0.025}, {0.0095, 0.0038}},
                                            {{0.032, 0.025}, {0.0095, 0.0038}},
                                            {{0, -0.046}, {0.017, 0.0028}},
                                            {{-0.0075, -0.0225}, {0.0026, 0.0022}},
                                            {{0.0075, -0.0225}, {0.0026, 0.0022}}}};

bool in_hole(const Vec2& m) {
  for (const HoleEllipse& h : kHoles) {
    if (std::hypot((m.x() - h.centre.x()) / h.axes.x(), (m.y() - h.centre.y()) / h.axes.y()) < 1) return true;
  }
  return false;
}

// Distance from kCentre to the head along unit direction u: the cranium, blended smoothly into the
// neck cylinder (a smooth maximum of the two radii), by bisection on the ray.
double head_radius(const Vec3& u) {
  const Vec3 q = u.cwiseQuotient(kSkullAxes);
  const Vec3 o = (kCentre - kSkullCentre).cwiseQuotient(kSkullAxes);
  // |o + r q| = 1: the far root.
  const double a = q.squaredNorm(), b = 2 * o.dot(q), c = o.squaredNorm() - 1;
  const double skull = (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
  const double sine = std::max(u.cross(kNeckAxis).norm(), 1e-6);
  // The cylinder only below the skull's centre: faded in over the lower half of the directions.
  const double neck = kNeckRadius / sine * smoothstep(u.dot(kNeckAxis) / 0.5);
  const double k = 60;  // 1/k metres: how round the blend is
  return std::log(std::exp(k * skull) + std::exp(k * std::min(neck, 1.0))) / k;
}

Vec3 any_perpendicular(const Vec3& n) {
  const Vec3 other = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return n.cross(other).normalized();
}

// Stereographic projection from the face's centre direction (+z): the face cap goes to infinity,
// the back of the head and the neck to a bounded part of the plane.
Vec2 project(const Vec3& u) { return Vec2(u.x(), u.y()) / (1 - u.z()); }

// A hole cut by the triangles' centroids can leave two cut pieces touching at one vertex, a bow tie
// (at --vertices 1500 and 2000 a nostril was two triangles meeting at a corner), which no scanner
// writes for an eye or a nostril and which the encoder's preparation would have to split. At such a
// vertex the cut faces about it form more than one fan (faces joined through an edge at the
// vertex); every face about it is cut too, joining the pieces into one hole through it, until no
// vertex has two. (Putting the smaller fan back instead left the rest of its piece a hole of its
// own: seven or eight boundary loops where the head has six.) Each pass cuts at least one face, so
// it ends.
void close_bow_ties(const std::vector<Face>& faces, int vertex_count, std::vector<char>& cut) {
  std::vector<std::vector<int>> around(static_cast<size_t>(vertex_count));
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int32_t v : faces[f]) around[static_cast<size_t>(v)].push_back(static_cast<int>(f));
  }
  // Whether faces a and b (both about v) share an edge at v: a second vertex in common.
  auto share_edge = [&](int a, int b, size_t v) {
    for (int32_t x : faces[static_cast<size_t>(a)]) {
      for (int32_t y : faces[static_cast<size_t>(b)]) {
        if (x == y && static_cast<size_t>(x) != v) return true;
      }
    }
    return false;
  };
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t v = 0; v < around.size(); ++v) {
      std::vector<int> cut_here;
      for (int f : around[v]) {
        if (cut[static_cast<size_t>(f)]) cut_here.push_back(f);
      }
      if (cut_here.size() < 2 || cut_here.size() == around[v].size()) continue;
      // Fans by union over shared edges.
      std::vector<size_t> fan(cut_here.size());
      for (size_t i = 0; i < fan.size(); ++i) fan[i] = i;
      auto root = [&](size_t i) {
        while (fan[i] != i) i = fan[i] = fan[fan[i]];
        return i;
      };
      for (size_t i = 0; i < cut_here.size(); ++i) {
        for (size_t j = 0; j < i; ++j) {
          if (share_edge(cut_here[i], cut_here[j], v)) fan[root(i)] = root(j);
        }
      }
      bool one_fan = true;
      for (size_t i = 1; i < fan.size(); ++i) one_fan = one_fan && root(i) == root(0);
      if (one_fan) continue;
      for (int f : around[v]) cut[static_cast<size_t>(f)] = 1;
      changed = true;
    }
  }
}

}  // namespace

bool SyntheticFace::in_hole(const Vec2& material) { return facemorph::in_hole(material); }

Vec3 SyntheticFace::neck_rim_direction(double theta) {
  const Vec3 side = any_perpendicular(kNeckAxis), other = kNeckAxis.cross(side);
  return (std::cos(kNeckCap) * kNeckAxis + std::sin(kNeckCap) * (std::cos(theta) * side + std::sin(theta) * other)).normalized();
}

Vec3 SyntheticFace::head_point(const HeadVertex& v, double time) const {
  // The rim's displacement since time 0 (unposed), carried onto the back near the join.
  const Vec3 rim_rest =
      (1 - v.rim_mix) * unposed_position(rim_point(v.rim_theta[0]), 0) + v.rim_mix * unposed_position(rim_point(v.rim_theta[1]), 0);
  const Vec3 rim_now =
      (1 - v.rim_mix) * unposed_position(rim_point(v.rim_theta[0]), time) + v.rim_mix * unposed_position(rim_point(v.rim_theta[1]), time);
  return head_pose(v.rest + v.join_weight * (rim_now - rim_rest), time);
}

HeadSampling sample_head(int face_vertices, const SyntheticFace& face, bool holes, bool whole_head) {
  HeadSampling out;
  out.face = sample_material_ellipse(face_vertices, false, 0);
  MaterialSampling& s = out.face;
  // Mean edge of the face's lattice (material metres, close to the surface's).
  double spacing = 0;
  for (const Face& f : s.faces) spacing += (s.points[static_cast<size_t>(f[0])] - s.points[static_cast<size_t>(f[1])]).norm();
  spacing /= static_cast<double>(std::max<size_t>(s.faces.size(), 1));
  std::vector<char> cut(s.faces.size(), 0);
  for (size_t f = 0; f < s.faces.size(); ++f) {
    const Face& t = s.faces[f];
    const Vec2 centroid =
        (s.points[static_cast<size_t>(t[0])] + s.points[static_cast<size_t>(t[1])] + s.points[static_cast<size_t>(t[2])]) / 3.0;
    cut[f] = holes && SyntheticFace::in_hole(centroid);
  }
  if (holes) close_bow_ties(s.faces, static_cast<int>(s.points.size()), cut);
  for (size_t f = 0; f < s.faces.size(); ++f) {
    if (!cut[f]) out.faces.push_back(s.faces[f]);
  }
  // The lattice points inside the holes go with their faces (a scanner writes no vertex there).
  std::vector<int32_t> index(s.points.size(), -1);
  for (const Face& f : out.faces) {
    for (int32_t v : f) index[static_cast<size_t>(v)] = 0;
  }
  std::vector<Vec2> kept;
  for (size_t v = 0; v < index.size(); ++v) {
    if (index[v] == 0 || static_cast<int>(v) < s.boundary_count) {
      index[v] = static_cast<int32_t>(kept.size());
      kept.push_back(s.points[v]);
    }
  }
  for (Face& f : out.faces) {
    for (int32_t& v : f) v = index[static_cast<size_t>(v)];
  }
  out.face.points = std::move(kept);
  out.face.faces = out.faces;
  out.face_vertices = static_cast<int>(out.face.points.size());
  out.face_faces = out.faces.size();
  if (!whole_head) return out;

  // The face's rim as directions from kCentre, at rest (time 0, unposed), and their plane images.
  const int rim = s.boundary_count;
  std::vector<Vec3> rim_dir(static_cast<size_t>(rim));
  std::vector<double> rim_theta(static_cast<size_t>(rim));
  std::vector<double> rim_radius(static_cast<size_t>(rim));
  std::vector<Vec2> face_polygon(static_cast<size_t>(rim));
  for (int k = 0; k < rim; ++k) {
    const Vec2& m = s.points[static_cast<size_t>(k)];
    const Vec3 p = face.unposed_position(m, 0) - kCentre;
    rim_dir[static_cast<size_t>(k)] = p.normalized();
    rim_radius[static_cast<size_t>(k)] = p.norm();
    rim_theta[static_cast<size_t>(k)] = std::atan2(m.y() / SyntheticFace::kHalfHeight, m.x() / SyntheticFace::kHalfWidth);
    face_polygon[static_cast<size_t>(k)] = project(rim_dir[static_cast<size_t>(k)]);
  }
  const double angle_step = spacing / 0.1;  // the lattice's spacing as an angle seen from kCentre (head radius ~0.1 m)
  // Directions on the back's side of the face's rim, not crowding its vertices.
  auto clear_of_face = [&](const Vec3& u) {
    if (u.z() > 0.999 || !inside_polygon(project(u), face_polygon)) return false;
    for (const Vec3& d : rim_dir) {
      if (u.dot(d) > std::cos(0.6 * angle_step)) return false;
    }
    return true;
  };
  // The neck: rings about its axis, the first its rim. The rays meet the neck's cylinder at a grazing
  // angle, so evenly spread directions would make long slivers there: rings spaced by the
  // lattice's spacing along the cylinder (h = r cot β, dh = r dβ / sin² β), staggered.
  const int neck = std::max(12, static_cast<int>(std::lround(2 * std::numbers::pi * kNeckRadius / spacing)));
  std::vector<Vec2> neck_polygon;
  std::vector<Vec3> directions;  // of the back's vertices: the neck rim first, then the inside
  for (int k = 0; k < neck; ++k) {
    directions.push_back(SyntheticFace::neck_rim_direction(2 * std::numbers::pi * k / neck));
    neck_polygon.push_back(project(directions.back()));
  }
  out.neck_count = neck;
  {
    const Vec3 side = any_perpendicular(kNeckAxis), other = kNeckAxis.cross(side);
    double beta = kNeckCap;
    for (int ring = 1;; ++ring) {
      beta += std::min(spacing * std::sin(beta) * std::sin(beta) / kNeckRadius, angle_step);
      if (beta > kNeckRingsTo) break;
      for (int k = 0; k < neck; ++k) {
        const double theta = 2 * std::numbers::pi * (k + 0.5 * (ring % 2)) / neck;
        const Vec3 u = (std::cos(beta) * kNeckAxis + std::sin(beta) * (std::cos(theta) * side + std::sin(theta) * other)).normalized();
        if (clear_of_face(u)) directions.push_back(u);
      }
    }
  }
  // Fibonacci directions beyond the rings, as many as the sphere holds at the lattice's spacing.
  const int count = static_cast<int>(4 * std::numbers::pi / (angle_step * angle_step * std::sqrt(3.0) / 2));
  const double golden = std::numbers::pi * (3 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double y = 1 - 2 * (i + 0.5) / count, r = std::sqrt(1 - y * y);
    const Vec3 u(r * std::cos(golden * i), y, r * std::sin(golden * i));
    if (std::acos(std::clamp(u.dot(kNeckAxis), -1.0, 1.0)) < kNeckRingsTo + 0.5 * angle_step) continue;
    if (clear_of_face(u)) directions.push_back(u);
  }
  out.rim_plane = face_polygon;
  // Delaunay of the face's rim, the neck's rim and the back's directions in the plane; the triangles
  // between the two rims are the back.
  std::vector<Vec2> plane(face_polygon);
  for (const Vec3& u : directions) plane.push_back(project(u));
  const std::vector<Face> triangles = delaunay_triangulation(plane);
  auto global = [&](int32_t i) { return i < rim ? i : out.face_vertices + (i - rim); };
  for (const Face& t : triangles) {
    const Vec2 centroid = (plane[static_cast<size_t>(t[0])] + plane[static_cast<size_t>(t[1])] + plane[static_cast<size_t>(t[2])]) / 3.0;
    if (!inside_polygon(centroid, face_polygon) || inside_polygon(centroid, neck_polygon)) continue;
    // Wound like the face (outward normals): the projection reverses orientation seen from outside.
    out.faces.push_back({global(t[0]), global(t[2]), global(t[1])});
  }
  // Each back vertex: its rest position, and the rim points (two neighbours) it follows near the join.
  for (const Vec3& u : directions) {
    HeadVertex v;
    size_t best = 0;
    double nearest = std::numbers::pi;
    for (size_t k = 0; k < rim_dir.size(); ++k) {
      const double a = std::acos(std::clamp(u.dot(rim_dir[k]), -1.0, 1.0));
      if (a < nearest) nearest = a, best = k;
    }
    const size_t prev = (best + rim_dir.size() - 1) % rim_dir.size(), next = (best + 1) % rim_dir.size();
    const size_t other = u.dot(rim_dir[prev]) > u.dot(rim_dir[next]) ? prev : next;
    const double a0 = nearest, a1 = std::acos(std::clamp(u.dot(rim_dir[other]), -1.0, 1.0));
    v.rim_mix = a0 / std::max(a0 + a1, 1e-12);
    v.rim_theta = {rim_theta[best], rim_theta[other]};
    v.join_weight = smoothstep(1 - nearest / kJoinAngle);
    // The radius: the head's, corrected to meet the face's rim exactly and faded out away from it.
    const double rim_r = (1 - v.rim_mix) * rim_radius[best] + v.rim_mix * rim_radius[other];
    const Vec3 rim_u = ((1 - v.rim_mix) * rim_dir[best] + v.rim_mix * rim_dir[other]).normalized();
    const double radius = head_radius(u) + v.join_weight * (rim_r - head_radius(rim_u));
    v.rest = kCentre + radius * u;
    v.normal = u;
    v.plane = project(u);
    out.back.push_back(v);
  }
  return out;
}

}  // namespace facemorph
