// The geodesic frame of the reference frame (paper §4) and its partition mesh (§5), built once per
// capture: the landmark graph, one corrected geodesic per graph edge inside the disk, and a
// triangulation of the disk whose edges follow those curves.
#include "codec/encoder/registration/surface_path.hpp"

#include "codec/core/util/elapsed.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/registration/partition_map.hpp"
#include "codec/encoder/registration/registration_internal.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <unordered_map>
#include <unordered_set>

namespace facemorph {
namespace {

double angular_distance(double a, double b) { return std::abs(std::remainder(a - b, kTwoPi)); }

// Adds points of the circle every `spacing` radians, except within a quarter spacing of a circle
// point already there (a near-duplicate only makes a sliver).
void add_circle_samples(std::vector<Vec2>& points, std::vector<uint8_t>& on_circle, double spacing) {
  std::vector<double> taken;
  for (size_t i = 0; i < points.size(); ++i) {
    if (on_circle[i]) taken.push_back(circle_angle(points[i]));
  }
  const int count = std::max(3, static_cast<int>(std::lround(kTwoPi / spacing)));
  for (int s = 0; s < count; ++s) {
    const double psi = kTwoPi * s / count;
    if (std::any_of(taken.begin(), taken.end(), [&](double a) { return angular_distance(a, psi) < 0.25 * spacing; })) continue;
    points.emplace_back(std::cos(psi), std::sin(psi));
    on_circle.push_back(1);
  }
}

// Delaunay triangulation with the circle's points pushed out by tiny deterministic amounts: points on
// one circle are co-circular, and the in-circle test would settle their ties by rounding noise,
// which can break a cavity. The faces must be positive with the true coordinates and use every point.
std::vector<Face> triangulate(const std::vector<Vec2>& points, const std::vector<uint8_t>& on_circle, const std::string& what) {
  for (uint64_t attempt = 1; attempt <= 4; ++attempt) {
    std::vector<Vec2> jittered = points;
    std::mt19937_64 rng(attempt);
    std::uniform_real_distribution<double> u(1e-9, 2e-9);
    for (size_t i = 0; i < points.size(); ++i) {
      if (on_circle[i]) jittered[i] *= 1 + u(rng);
    }
    std::vector<Face> faces;
    try {
      faces = delaunay_triangulation(jittered);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::kNumerical) throw;
      continue;
    }
    std::vector<uint8_t> used(points.size(), 0);
    bool positive = true;
    for (const Face& f : faces) {
      positive =
          positive && orient2d(points[static_cast<size_t>(f[0])], points[static_cast<size_t>(f[1])], points[static_cast<size_t>(f[2])]) > 0;
      for (int v : f) used[static_cast<size_t>(v)] = 1;
    }
    if (positive && std::all_of(used.begin(), used.end(), [](uint8_t x) { return x != 0; })) return faces;
  }
  throw Error(ErrorCode::kNumerical, "geodesic frame: the " + what + " cannot be triangulated (points too close together)");
}

// An edge of the landmark graph and its faces: `left` holds lo -> hi, `right` hi -> lo (-1: the hull).
struct GraphEdge {
  int lo = -1, hi = -1, left = -1, right = -1;
};

std::vector<GraphEdge> graph_edges(const std::vector<Face>& faces) {
  std::map<uint64_t, GraphEdge> edges;
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = faces[f][static_cast<size_t>(k)], b = faces[f][static_cast<size_t>((k + 1) % 3)];
      GraphEdge& e = edges[undirected_edge_key(a, b)];
      e.lo = std::min(a, b);
      e.hi = std::max(a, b);
      (a < b ? e.left : e.right) = static_cast<int>(f);
    }
  }
  std::vector<GraphEdge> out;
  for (const auto& [key, e] : edges) out.push_back(e);
  return out;
}

int third_vertex(const Face& f, int a, int b) {
  for (int v : f) {
    if (v != a && v != b) return v;
  }
  return -1;
}

// Whether the curve's interior points lie in the open union of its edge's two graph triangles:
// (a, b, c) counter-clockwise and (b, a, d).
bool inside_diamond(const std::vector<Vec2>& curve, const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  for (size_t i = 1; i + 1 < curve.size(); ++i) {
    const Vec2& p = curve[i];
    const bool left = orient2d(a, b, p) >= 0 && orient2d(b, c, p) > 0 && orient2d(c, a, p) > 0;
    const bool right = orient2d(b, a, p) >= 0 && orient2d(a, d, p) > 0 && orient2d(d, b, p) > 0;
    if (!left && !right) return false;
  }
  return true;
}

double deviation(const std::vector<Vec2>& curve) {
  const Vec2 &a = curve.front(), &b = curve.back(), ab = b - a;
  double most = 0;
  for (const Vec2& p : curve) {
    const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    most = std::max(most, (p - a - s * ab).norm());
  }
  return most;
}

int sign(double v) { return (v > 0) - (v < 0); }

bool within_box(const Vec2& a, const Vec2& b, const Vec2& p) {
  return p.x() >= std::min(a.x(), b.x()) && p.x() <= std::max(a.x(), b.x()) && p.y() >= std::min(a.y(), b.y()) &&
         p.y() <= std::max(a.y(), b.y());
}

// Whether segment k1 of curve c1 and segment k2 of curve c2 meet anywhere but at a graph point that
// both curves end at; there only a collinear overlap counts.
bool segments_meet(const FramePath& c1, size_t k1, const FramePath& c2, size_t k2) {
  const Vec2 *e1[2] = {&c1.disk[k1], &c1.disk[k1 + 1]}, *e2[2] = {&c2.disk[k2], &c2.disk[k2 + 1]};
  auto curve_end = [](const FramePath& c, size_t index) { return index == 0 || index + 1 == c.disk.size(); };
  for (size_t i = 0; i < 2; ++i) {
    for (size_t j = 0; j < 2; ++j) {
      if (*e1[i] != *e2[j]) continue;
      if (!curve_end(c1, k1 + i) || !curve_end(c2, k2 + j)) return true;
      const Vec2 &s = *e1[i], &x = *e1[1 - i], &y = *e2[1 - j];
      return orient2d(s, x, y) == 0 && (x - s).dot(y - s) > 0;
    }
  }
  const Vec2 &p1 = *e1[0], &q1 = *e1[1], &p2 = *e2[0], &q2 = *e2[1];
  const int d1 = sign(orient2d(p2, q2, p1)), d2 = sign(orient2d(p2, q2, q1));
  const int d3 = sign(orient2d(p1, q1, p2)), d4 = sign(orient2d(p1, q1, q2));
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  return (d1 == 0 && within_box(p2, q2, p1)) || (d2 == 0 && within_box(p2, q2, q1)) || (d3 == 0 && within_box(p1, q1, p2)) ||
         (d4 == 0 && within_box(p1, q1, q2));
}

// The pairs of curves that meet (a curve paired with itself when it does), by a bucket grid of
// their segments over the disk.
std::set<std::pair<int, int>> crossings(const std::vector<FramePath>& paths) {
  constexpr int kCells = 64;
  auto cell = [](double x) { return std::clamp(static_cast<int>((x + 1) * 0.5 * kCells), 0, kCells - 1); };
  std::vector<std::vector<std::pair<int, int>>> buckets(kCells * kCells);
  for (size_t c = 0; c < paths.size(); ++c) {
    const std::vector<Vec2>& disk = paths[c].disk;
    for (size_t k = 0; k + 1 < disk.size(); ++k) {
      const Vec2 lo = disk[k].cwiseMin(disk[k + 1]), hi = disk[k].cwiseMax(disk[k + 1]);
      for (int y = cell(lo.y()); y <= cell(hi.y()); ++y) {
        for (int x = cell(lo.x()); x <= cell(hi.x()); ++x)
          buckets[static_cast<size_t>(y * kCells + x)].push_back({static_cast<int>(c), static_cast<int>(k)});
      }
    }
  }
  std::set<std::pair<int, int>> out;
  for (const auto& bucket : buckets) {
    for (size_t i = 0; i < bucket.size(); ++i) {
      for (size_t j = i + 1; j < bucket.size(); ++j) {
        const auto [c1, k1] = bucket[i];
        const auto [c2, k2] = bucket[j];
        if (c1 == c2 && std::abs(k1 - k2) <= 1) continue;
        const std::pair<int, int> pair = std::minmax(c1, c2);
        if (out.count(pair)) continue;
        if (segments_meet(paths[static_cast<size_t>(c1)], static_cast<size_t>(k1), paths[static_cast<size_t>(c2)],
                          static_cast<size_t>(k2))) {
          out.insert(pair);
        }
      }
    }
  }
  return out;
}

// Points added to the partition, refusing one within 1e-6 of another: Delaunay leaves out exact
// duplicates and near ones make slivers; a sample that close adds nothing.
class PointSet {
 public:
  explicit PointSet(std::vector<Vec2>& points) : points_(points) {
    for (size_t i = 0; i < points.size(); ++i) cells_[key(points[i])].push_back(static_cast<int>(i));
  }
  // The new point's index, or -1 when it is too near one already there.
  int add(const Vec2& p) {
    const int64_t cx = coordinate(p.x()), cy = coordinate(p.y());
    for (int64_t y = cy - 1; y <= cy + 1; ++y) {
      for (int64_t x = cx - 1; x <= cx + 1; ++x) {
        const auto it = cells_.find(pack(x, y));
        if (it == cells_.end()) continue;
        for (int i : it->second) {
          if ((points_[static_cast<size_t>(i)] - p).norm() < kSpacing) return -1;
        }
      }
    }
    points_.push_back(p);
    cells_[pack(cx, cy)].push_back(static_cast<int>(points_.size()) - 1);
    return static_cast<int>(points_.size()) - 1;
  }

 private:
  static constexpr double kSpacing = 1e-6;
  static int64_t coordinate(double x) { return static_cast<int64_t>(std::floor(x / kSpacing)); }
  static uint64_t pack(int64_t x, int64_t y) { return (static_cast<uint64_t>(x) << 32) ^ static_cast<uint64_t>(y & 0xffffffff); }
  static uint64_t key(const Vec2& p) { return pack(coordinate(p.x()), coordinate(p.y())); }
  std::vector<Vec2>& points_;
  std::unordered_map<uint64_t, std::vector<int>> cells_;
};

// A triangulation that takes constraint edges by flips (Sloan 1993): an edge the Delaunay
// triangulation lacks is recovered by flipping the edges that cross it, then the Delaunay property
// is restored round it by Lawson flips that leave constrained edges alone.
class ConstrainedTriangulation {
 public:
  ConstrainedTriangulation(const std::vector<Vec2>& points, std::vector<Face> faces) : points_(points), faces_(std::move(faces)) {
    for (size_t f = 0; f < faces_.size(); ++f) link(static_cast<int>(f));
  }
  const std::vector<Face>& faces() const { return faces_; }

  // Makes (u, v) an edge that no later flip removes. False, the triangulation still valid, when it
  // cannot: another point on the segment, or a constrained edge across it.
  bool constrain(int u, int v) {
    if (face_of(u, v) >= 0 || face_of(v, u) >= 0) {
      fixed_.insert(undirected_edge_key(u, v));
      return true;
    }
    std::deque<std::pair<int, int>> queue;
    if (!crossed_edges(u, v, queue)) return false;
    std::vector<std::pair<int, int>> created;
    for (size_t budget = 64 * queue.size() + 64; !queue.empty(); --budget) {
      if (budget == 0) return false;
      const auto [a, b] = queue.front();
      queue.pop_front();
      if (fixed_.count(undirected_edge_key(a, b))) return false;
      int c = -1, d = -1;
      if (!flip(a, b, c, d)) {
        queue.push_back({a, b});  // not convex yet: other flips first
        continue;
      }
      const bool crosses = c != u && c != v && d != u && d != v && orient2d(P(u), P(v), P(c)) * orient2d(P(u), P(v), P(d)) < 0 &&
                           orient2d(P(c), P(d), P(u)) * orient2d(P(c), P(d), P(v)) < 0;
      (crosses ? queue.emplace_back(c, d) : created.emplace_back(c, d));
    }
    fixed_.insert(undirected_edge_key(u, v));
    // Lawson flips round the new edges, a bounded number of passes (co-circular points could swap
    // an edge back and forth on rounding alone).
    for (size_t pass = 0; pass < 4 * created.size() + 4; ++pass) {
      bool changed = false;
      for (auto& [a, b] : created) {
        if (fixed_.count(undirected_edge_key(a, b))) continue;
        const int f = face_of(a, b), g = face_of(b, a);
        if (f < 0 || g < 0) continue;
        if (!(incircle(P(a), P(b), P(third(f, a, b)), P(third(g, a, b))) > 0)) continue;
        int c = -1, d = -1;
        if (flip(a, b, c, d)) {
          a = c;
          b = d;
          changed = true;
        }
      }
      if (!changed) break;
    }
    return true;
  }

 private:
  const Vec2& P(int i) const { return points_[static_cast<size_t>(i)]; }
  int face_of(int a, int b) const {
    const auto it = face_of_.find(directed_edge_key(a, b));
    return it == face_of_.end() ? -1 : it->second;
  }
  int third(int f, int a, int b) const { return third_vertex(faces_[static_cast<size_t>(f)], a, b); }
  void link(int f) {
    const Face& t = faces_[static_cast<size_t>(f)];
    for (size_t k = 0; k < 3; ++k) face_of_[directed_edge_key(t[k], t[(k + 1) % 3])] = f;
  }
  void unlink(int f) {
    const Face& t = faces_[static_cast<size_t>(f)];
    for (size_t k = 0; k < 3; ++k) face_of_.erase(directed_edge_key(t[k], t[(k + 1) % 3]));
  }

  // Flips edge (a, b) when its two triangles (a, b, c) and (b, a, d) make a strictly convex quad;
  // the new edge is (c, d).
  bool flip(int a, int b, int& c, int& d) {
    const int f = face_of(a, b), g = face_of(b, a);
    if (f < 0 || g < 0) return false;
    c = third(f, a, b);
    d = third(g, a, b);
    if (!(orient2d(P(c), P(d), P(a)) * orient2d(P(c), P(d), P(b)) < 0)) return false;
    unlink(f);
    unlink(g);
    faces_[static_cast<size_t>(f)] = {a, d, c};
    faces_[static_cast<size_t>(g)] = {b, c, d};
    link(f);
    link(g);
    return true;
  }

  // The edges the segment u -> v crosses, in order, walking from u; false when a point lies on it.
  bool crossed_edges(int u, int v, std::deque<std::pair<int, int>>& out) const {
    const Vec2 &pu = P(u), &pv = P(v);
    int right = -1, left = -1;
    // The triangle whose corner at u holds the direction to v (a scan: few pieces are missing).
    for (size_t f = 0; f < faces_.size() && right < 0; ++f) {
      const Face& t = faces_[f];
      for (size_t k = 0; k < 3; ++k) {
        if (t[k] != u) continue;
        const int a = t[(k + 1) % 3], b = t[(k + 2) % 3];
        const double oa = orient2d(pu, P(a), pv), ob = orient2d(pu, P(b), pv);
        if ((oa == 0 && (P(a) - pu).dot(pv - pu) > 0) || (ob == 0 && (P(b) - pu).dot(pv - pu) > 0)) return false;
        if (oa > 0 && ob < 0) {
          right = a;
          left = b;
        }
      }
    }
    if (right < 0) return false;
    for (size_t steps = 0; steps <= faces_.size(); ++steps) {
      out.emplace_back(right, left);
      const int beyond = face_of(left, right);
      if (beyond < 0) return false;
      const int c = third(beyond, left, right);
      if (c == v) return true;
      const double o = orient2d(pu, pv, P(c));
      if (o == 0) return false;
      (o > 0 ? left : right) = c;
    }
    return false;
  }

  const std::vector<Vec2>& points_;
  std::vector<Face> faces_;
  std::unordered_map<uint64_t, int> face_of_;  // directed edge -> face
  std::unordered_set<uint64_t> fixed_;         // constrained edges
};

// The partition mesh (notes §6, "Partition mesh and registration"): graph points, circle samples,
// samples along each curve; Delaunay-triangulated, then every curve piece between consecutive samples
// that the triangulation lacks recovered by flips, so the triangles follow the curves exactly.
std::shared_ptr<const PartitionMesh> build_partition(const std::vector<Vec2>& graph_points, const std::vector<uint8_t>& graph_circle,
                                                     const std::vector<FramePath>& paths, const GeodesicFrameOptions& options,
                                                     int& unconforming) {
  std::vector<Vec2> points = graph_points;
  std::vector<uint8_t> on_circle = graph_circle;
  add_circle_samples(points, on_circle, options.partition_boundary_spacing_degrees * std::numbers::pi / 180);
  // The circle points' polygon holds every point nearer the centre than its inradius. A graph point
  // beyond it gets a circle point at its own angle, which puts it back inside.
  auto inradius = [&] {
    std::vector<double> angles;
    for (size_t i = 0; i < points.size(); ++i) {
      if (on_circle[i]) angles.push_back(circle_angle(points[i]));
    }
    std::sort(angles.begin(), angles.end());
    double gap = angles.front() + kTwoPi - angles.back();
    for (size_t i = 1; i < angles.size(); ++i) gap = std::max(gap, angles[i] - angles[i - 1]);
    return std::cos(gap / 2);
  };
  const double first = inradius();
  for (size_t i = 0; i < graph_points.size(); ++i) {
    if (!on_circle[i] && graph_points[i].norm() >= first - 1e-9) {
      const double a = circle_angle(graph_points[i]);
      points.emplace_back(std::cos(a), std::sin(a));
      on_circle.push_back(1);
    }
  }
  const double inside = inradius() - 1e-9;
  // Samples along each curve, evenly by arc length on the disk: a chain of partition vertices.
  PointSet set(points);
  std::vector<std::vector<int>> chains;
  for (const FramePath& path : paths) {
    const std::vector<Vec2>& disk = path.disk;
    std::vector<double> at(disk.size(), 0.0);
    for (size_t i = 1; i < disk.size(); ++i) at[i] = at[i - 1] + (disk[i] - disk[i - 1]).norm();
    std::vector<int> chain{path.from};
    const int pieces = std::max(1, static_cast<int>(std::lround(at.back() / options.sample_spacing)));
    size_t piece = 0;
    for (int k = 1; k < pieces; ++k) {
      const double s = at.back() * k / pieces;
      while (piece + 2 < at.size() && at[piece + 1] < s) ++piece;
      const double span = at[piece + 1] - at[piece];
      const Vec2 q = span > 0 ? Vec2(disk[piece] + (s - at[piece]) / span * (disk[piece + 1] - disk[piece])) : disk[piece];
      if (!(q.norm() < inside)) continue;
      const int index = set.add(q);
      if (index < 0) continue;
      on_circle.push_back(0);
      chain.push_back(index);
    }
    chain.push_back(path.to);
    chains.push_back(std::move(chain));
  }
  // The Delaunay triangulation, then every curve piece it lacks recovered by flips.
  ConstrainedTriangulation triangulation(points, triangulate(points, on_circle, "partition mesh"));
  unconforming = 0;
  for (const std::vector<int>& chain : chains) {
    for (size_t k = 0; k + 1 < chain.size(); ++k) unconforming += !triangulation.constrain(chain[k], chain[k + 1]);
  }
  std::vector<Face> faces = triangulation.faces();
  return std::make_shared<const PartitionMesh>(std::move(points), std::move(faces));
}

}  // namespace

GeodesicFrame make_geodesic_frame(const DiskMap& reference, const std::vector<Vec2>& landmarks, const std::vector<uint8_t>& on_rim,
                                  const GeodesicFrameOptions& options) {
  check_frame_options(options);
  const auto start = std::chrono::steady_clock::now();
  const size_t n = landmarks.size();
  if (n < 3) refuse_geodesic_frame_input("needs at least 3 landmarks, got " + std::to_string(n));
  if (!on_rim.empty() && on_rim.size() != n)
    refuse_geodesic_frame_input(std::to_string(on_rim.size()) + " rim flags for " + std::to_string(n) + " landmarks");

  // 1. The landmark graph: landmarks on the circle exactly where register_disks puts them (p / |p|
  // for rim markers), then circle samples, Delaunay-triangulated.
  GeodesicFrame frame;
  std::vector<uint8_t> on_circle;
  for (size_t j = 0; j < n; ++j) {
    const std::string name = "landmark " + std::to_string(j);
    const Vec2& p = landmarks[j];
    if (!p.allFinite()) refuse_geodesic_frame_input(name + " is not finite");
    const double r = p.norm();
    if (r > 1 + 1e-9) refuse_geodesic_frame_input(name + " lies outside the unit disk (|p| = " + std::to_string(r) + ")");
    const bool rim = !on_rim.empty() && on_rim[j] != 0;
    if (rim && std::abs(r - 1) > 1e-3) refuse_geodesic_frame_input(name + " is a rim marker but does not lie on the circle");
    Complex z = to_complex(p);
    const bool circle = rim || r > 1 - 1e-9;
    if (circle) z /= std::abs(z);
    frame.graph_points.push_back(to_vec2(z));
    on_circle.push_back(circle);
  }
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      if ((frame.graph_points[i] - frame.graph_points[j]).norm() <= 1e-12) {
        refuse_geodesic_frame_input("landmarks " + std::to_string(i) + " and " + std::to_string(j) + " coincide");
      }
    }
  }
  frame.landmark_count = static_cast<int>(n);
  add_circle_samples(frame.graph_points, on_circle, options.graph_boundary_spacing_degrees * std::numbers::pi / 180);
  frame.graph_faces = triangulate(frame.graph_points, on_circle, "landmark graph");

  // 2. One curve per graph edge inside the disk: pulled back, corrected, mapped back.
  std::vector<GraphEdge> inner;
  for (const GraphEdge& e : graph_edges(frame.graph_faces)) {
    if (e.left >= 0 && e.right >= 0) inner.push_back(e);
  }
  const SurfacePaths surface(reference);
  std::vector<TracedPath> traced(inner.size());
  const std::vector<Vec2>& g = frame.graph_points;
  parallel_for(static_cast<int>(inner.size()), 0, [&](int i) {
    const GraphEdge& e = inner[static_cast<size_t>(i)];
    traced[static_cast<size_t>(i)] = trace_path(surface, g[static_cast<size_t>(e.lo)], g[static_cast<size_t>(e.hi)], options);
  });
  frame.paths.resize(inner.size());
  auto use = [&](size_t i, const FramePath& curve, bool straight, std::string reason) {
    FramePath& path = frame.paths[i];
    path = curve;
    path.from = inner[i].lo;
    path.to = inner[i].hi;
    path.straight = straight;
    path.reason = std::move(reason);
  };
  std::vector<double> moved(inner.size(), 0.0);
  for (size_t i = 0; i < inner.size(); ++i) {
    const GraphEdge& e = inner[i];
    if (!options.correct_paths) {
      use(i, traced[i].straight, true, "path correction is off");
      continue;
    }
    if (!traced[i].correction_valid) {
      use(i, traced[i].straight, true, "path correction broke the path");
      continue;
    }
    const Vec2 &a = g[static_cast<size_t>(e.lo)], &b = g[static_cast<size_t>(e.hi)];
    const Vec2& c = g[static_cast<size_t>(third_vertex(frame.graph_faces[static_cast<size_t>(e.left)], e.lo, e.hi))];
    const Vec2& d = g[static_cast<size_t>(third_vertex(frame.graph_faces[static_cast<size_t>(e.right)], e.lo, e.hi))];
    if (!inside_diamond(traced[i].corrected.disk, a, b, c, d)) {
      use(i, traced[i].straight, true, "the geodesic leaves its two landmark-graph triangles");
      continue;
    }
    use(i, traced[i].corrected, false, "");
    moved[i] = deviation(frame.paths[i].disk);
  }
  // Curves that meet: of two corrected ones, the one that moved farther from its segment goes back
  // to it (straight segments of one triangulation never cross), until none meet.
  for (size_t round = 0; round <= inner.size(); ++round) {
    std::map<int, int> revert;  // curve -> a curve it meets
    for (const auto& [i, j] : crossings(frame.paths)) {
      const bool ci = !frame.paths[static_cast<size_t>(i)].straight, cj = !frame.paths[static_cast<size_t>(j)].straight;
      if (ci && (!cj || moved[static_cast<size_t>(i)] >= moved[static_cast<size_t>(j)])) {
        revert.emplace(i, j);
      } else if (cj) {
        revert.emplace(j, i);
      }
    }
    if (revert.empty()) break;
    for (const auto& [i, j] : revert) {
      const FramePath& other = frame.paths[static_cast<size_t>(j)];
      use(static_cast<size_t>(i), traced[static_cast<size_t>(i)].straight, true,
          i == j ? "the geodesic meets itself"
                 : "the geodesic meets the curve between graph points " + std::to_string(other.from) + " and " + std::to_string(other.to));
    }
  }
  for (const FramePath& path : frame.paths) {
    frame.straight_paths += path.straight;
    frame.unconverged_paths += !path.straight && !path.converged;
  }
  frame.seconds_paths = seconds_since(start);

  // 3. The partition mesh.
  const auto partition_start = std::chrono::steady_clock::now();
  frame.partition = build_partition(frame.graph_points, on_circle, frame.paths, options, frame.unconforming_segments);
  frame.seconds_partition = seconds_since(partition_start);
  return frame;
}

}  // namespace facemorph
