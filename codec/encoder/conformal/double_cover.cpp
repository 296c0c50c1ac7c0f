#include "codec/encoder/conformal/double_cover.hpp"

#include "codec/meshkit/geometry/surface_measures.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {
namespace {

// Adds a vertex on the segment a-b (parameter t from a) with interpolated UV and colour; returns its index.
class MeshEditor {
 public:
  MeshEditor(TriangleMesh& mesh, std::vector<int>& source) : mesh_(mesh), source_(source) {}

  // Splits edge a-b (one or two faces) at a + t (b - a).
  void split_edge(int32_t a, int32_t b, double t = 0.5) {
    const bool has_uv = mesh_.has_uvs();  // before faces and uv_faces are grown one after the other
    const auto m = static_cast<int32_t>(mesh_.positions.size());
    if (mesh_.has_colours())
      mesh_.colours.push_back((1 - t) * mesh_.colours[static_cast<size_t>(a)] + t * mesh_.colours[static_cast<size_t>(b)]);
    mesh_.positions.push_back((1 - t) * mesh_.positions[static_cast<size_t>(a)] + t * mesh_.positions[static_cast<size_t>(b)]);
    source_.push_back(-1);
    const size_t count = mesh_.faces.size();
    for (size_t f = 0; f < count; ++f) {
      const Face face = mesh_.faces[f];
      for (int k = 0; k < 3; ++k) {
        const int32_t u = face[k], v = face[(k + 1) % 3], w = face[(k + 2) % 3];
        if (!((u == a && v == b) || (u == b && v == a))) continue;
        // (u, v, w) -> (u, m, w) and (m, v, w)
        mesh_.faces[f] = {u, m, w};
        mesh_.faces.push_back({m, v, w});
        if (has_uv) {
          const Face uv = mesh_.uv_faces[f];
          const auto tm = static_cast<int32_t>(mesh_.uvs.size());
          const double s = u == a ? t : 1 - t;  // the new vertex's parameter from u
          mesh_.uvs.push_back((1 - s) * mesh_.uvs[static_cast<size_t>(uv[k])] + s * mesh_.uvs[static_cast<size_t>(uv[(k + 1) % 3])]);
          mesh_.uv_faces[f] = {uv[k], tm, uv[(k + 2) % 3]};
          mesh_.uv_faces.push_back({tm, uv[(k + 1) % 3], uv[(k + 2) % 3]});
        }
        break;
      }
    }
  }

  void split_face_at_centroid(size_t f) {
    const bool has_uv = mesh_.has_uvs();
    const Face face = mesh_.faces[f];
    const auto g = static_cast<int32_t>(mesh_.positions.size());
    Vec3 c = Vec3::Zero();
    for (int32_t v : face) c += mesh_.positions[static_cast<size_t>(v)] / 3.0;
    if (mesh_.has_colours()) {
      Vec3 colour = Vec3::Zero();
      for (int32_t v : face) colour += mesh_.colours[static_cast<size_t>(v)] / 3.0;
      mesh_.colours.push_back(colour);
    }
    mesh_.positions.push_back(c);
    source_.push_back(-1);
    mesh_.faces[f] = {face[0], face[1], g};
    mesh_.faces.push_back({face[1], face[2], g});
    mesh_.faces.push_back({face[2], face[0], g});
    if (has_uv) {
      const Face t = mesh_.uv_faces[f];
      const auto tg = static_cast<int32_t>(mesh_.uvs.size());
      mesh_.uvs.push_back(
          (mesh_.uvs[static_cast<size_t>(t[0])] + mesh_.uvs[static_cast<size_t>(t[1])] + mesh_.uvs[static_cast<size_t>(t[2])]) / 3.0);
      mesh_.uv_faces[f] = {t[0], t[1], tg};
      mesh_.uv_faces.push_back({t[1], t[2], tg});
      mesh_.uv_faces.push_back({t[2], t[0], tg});
    }
  }

 private:
  TriangleMesh& mesh_;
  std::vector<int>& source_;
};

// A cap is a corner above 150° (its cosine below -cos 30°).
constexpr double kCapCosine = 0.866;
// How near an end of its edge a cap's altitude foot may lie and still be split there: closer, the
// apex nearly touches that end, and the split would leave an edge a thousandth of its neighbours.
constexpr double kCapFootMargin = 1e-3;
// Rounds of cap and of obtuse-boundary splits. Measured on every frame of Medusa, the whole ICT
// capture and fmsynth (fmbench conformal --sweep): a frame that settles at all settles within 12.
constexpr int kCapRounds = 24;
constexpr int kObtuseRounds = 24;

double cot_from_lengths(double opposite, double left, double right) {
  const CornerValues l = {opposite, left, right};
  return corner_cotangents_from_lengths(std::span<const CornerValues>(&l, 1))[0][0];
}

}  // namespace

DiskPreconditioning precondition_disk(TriangleMesh& mesh, std::vector<int>& source_vertex, TopologyCache& topologies) {
  // Termination, by construction rather than by hope. Ears and chords are split first, each once,
  // and no later split makes another: once none is left, the vertex facing a boundary edge is
  // interior (were it on the boundary, its two other edges would be chords or boundary edges, and
  // the face an ear), so a boundary split joins the new rim vertex to an interior one, and an
  // interior split adds an interior vertex. Caps and obtuse boundary edges are improvements the
  // map can live without (the cover's own intrinsic flips make its weights non-negative, and
  // untangling guarantees an embedding), so each class gets a bounded number of rounds, and what
  // is left after them is counted, not chased. A real ICT frame (20 s, frame 42) once chased a
  // chain of needle caps forever: a foot clamped away from its edge's end left every cap standing
  // and made a copy of it beside.
  DiskPreconditioning report;
  MeshEditor editor(mesh, source_vertex);
  int cap_rounds = 0, obtuse_rounds = 0;
  for (int round = 0;; ++round) {
    const MeshTopology& topology = topologies.of(mesh);
    // Ears first: their two interior-facing edges are also chords.
    std::vector<size_t> ears;
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const Face& face = mesh.faces[f];
      if (topology.is_boundary_vertex(face[0]) && topology.is_boundary_vertex(face[1]) && topology.is_boundary_vertex(face[2]))
        ears.push_back(f);
    }
    std::vector<std::array<int32_t, 2>> chords, obtuse;
    for (int e = 0; e < topology.edge_count(); ++e) {
      const auto [a, b] = topology.edge(e);
      if (!topology.is_boundary_edge(e)) {
        if (topology.is_boundary_vertex(a) && topology.is_boundary_vertex(b)) chords.push_back({a, b});
        continue;
      }
      const Face& face = mesh.faces[static_cast<size_t>(topology.edge_faces(e)[0])];
      int32_t c = face[0];
      for (int32_t v : face) {
        if (v != a && v != b) c = v;
      }
      const Vec3& pc = mesh.positions[static_cast<size_t>(c)];
      // Opposite angle above 90° (with a little margin, so near-right angles do not cascade).
      if ((mesh.positions[static_cast<size_t>(a)] - pc).dot(mesh.positions[static_cast<size_t>(b)] - pc) <
          -1e-9 * (mesh.positions[static_cast<size_t>(a)] - pc).norm() * (mesh.positions[static_cast<size_t>(b)] - pc).norm()) {
        obtuse.push_back({a, b});
      }
    }
    if (!ears.empty() || !chords.empty()) {
      // The argument above bounds this at two rounds (ears, then the chords they leave).
      if (round >= 2) throw Error(ErrorCode::kNumerical, "preconditioning the disk: ears or chords reappeared (a bug)");
      for (size_t f : ears) editor.split_face_at_centroid(f);
      report.split_ears += static_cast<int>(ears.size());
      if (!ears.empty()) continue;
      for (const auto& [a, b] : chords) editor.split_edge(a, b);
      report.split_chords += static_cast<int>(chords.size());
      continue;
    }
    // Caps: the edge facing an angle above 150° is split at the foot of the altitude, which leaves
    // two right angles there. The foot lies inside the edge (the angle is obtuse); one within
    // kCapFootMargin of an end (a needle whose apex nearly touches that end) is left standing, since
    // a split moved off the foot would leave the cap too.
    std::vector<std::pair<std::array<int32_t, 2>, double>> caps;
    int caps_standing = 0;
    {
      std::vector<uint8_t> taken(static_cast<size_t>(topology.edge_count()), 0);
      for (size_t f = 0; f < mesh.faces.size(); ++f) {
        for (int k = 0; k < 3; ++k) {
          const Face& face = mesh.faces[f];
          const Vec3& p = mesh.positions[static_cast<size_t>(face[k])];
          const Vec3& a = mesh.positions[static_cast<size_t>(face[(k + 1) % 3])];
          const Vec3& b = mesh.positions[static_cast<size_t>(face[(k + 2) % 3])];
          if ((a - p).dot(b - p) >= -kCapCosine * (a - p).norm() * (b - p).norm()) continue;
          const int e = topology.face_edge(static_cast<int>(f), (k + 1) % 3);
          if (taken[static_cast<size_t>(e)]) continue;
          taken[static_cast<size_t>(e)] = 1;
          const double t = (p - a).dot(b - a) / (b - a).squaredNorm();
          if (!(t >= kCapFootMargin && t <= 1 - kCapFootMargin)) {
            ++caps_standing;
            continue;
          }
          caps.push_back({{face[(k + 1) % 3], face[(k + 2) % 3]}, t});
        }
      }
    }
    if (!caps.empty() && cap_rounds < kCapRounds) {
      ++cap_rounds;
      for (const auto& [edge, t] : caps) editor.split_edge(edge[0], edge[1], t);
      report.split_caps += static_cast<int>(caps.size());
      continue;
    }
    if (!obtuse.empty() && obtuse_rounds < kObtuseRounds) {
      ++obtuse_rounds;
      for (const auto& [a, b] : obtuse) editor.split_edge(a, b);
      report.split_obtuse_boundary += static_cast<int>(obtuse.size());
      continue;
    }
    report.caps_left = static_cast<int>(caps.size()) + caps_standing;
    report.obtuse_boundary_left = static_cast<int>(obtuse.size());
    report.rounds = round;
    return report;
  }
}

std::vector<CornerValues> face_edge_lengths(const TriangleMesh& mesh) {
  std::vector<CornerValues> lengths(mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      lengths[f][k] = (mesh.positions[static_cast<size_t>(mesh.faces[f][(k + 1) % 3])] -
                       mesh.positions[static_cast<size_t>(mesh.faces[f][(k + 2) % 3])])
                          .norm();
    }
  }
  return lengths;
}

DoubleCover build_double_cover(std::span<const Face> faces, std::span<const CornerValues> lengths,
                               const std::vector<uint8_t>& on_boundary) {
  DoubleCover cover;
  const int n = static_cast<int>(on_boundary.size());
  cover.disk_vertices = n;
  cover.on_boundary = on_boundary;
  cover.mirror.resize(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) cover.mirror[static_cast<size_t>(v)] = v;
  for (int v = 0; v < n; ++v) {
    if (on_boundary[static_cast<size_t>(v)]) continue;
    const int copy = static_cast<int>(cover.mirror.size());
    cover.mirror[static_cast<size_t>(v)] = copy;
    cover.mirror.push_back(v);
    cover.on_boundary.push_back(0);
  }
  cover.faces.assign(faces.begin(), faces.end());
  cover.lengths.assign(lengths.begin(), lengths.end());
  for (size_t f = 0; f < faces.size(); ++f) {
    const Face& face = faces[f];
    // (a, b, c) -> (m(a), m(c), m(b)); the lengths opposite b and c swap with their corners.
    cover.faces.push_back({cover.mirror[static_cast<size_t>(face[0])], cover.mirror[static_cast<size_t>(face[2])],
                           cover.mirror[static_cast<size_t>(face[1])]});
    cover.lengths.push_back({lengths[f][0], lengths[f][2], lengths[f][1]});
  }
  return cover;
}

int flip_to_intrinsic_delaunay(std::vector<Face>& faces, std::vector<CornerValues>& lengths,
                               const std::vector<std::array<uint8_t, 3>>& fixed_input) {
  const size_t face_count = faces.size();
  // Neighbour across the edge opposite each corner, as (face, corner); -1 on the boundary.
  std::vector<std::array<int32_t, 3>> nf(face_count, {-1, -1, -1});
  std::vector<std::array<int8_t, 3>> nc(face_count, {-1, -1, -1});
  std::vector<std::array<uint8_t, 3>> fixed = fixed_input;
  if (fixed.empty()) fixed.assign(face_count, {0, 0, 0});
  {
    // Each half-edge a -> b (the edge opposite corner k of face f) listed under a, in face order (a
    // counting sort: no allocation an edge, which a hash map's nodes cost 3% of the sample's encode);
    // the edge's twin b -> a is then the last of b's few listing a: the face a map written in face
    // order would hold where an edge comes twice.
    size_t vertices = 0;
    for (const Face& face : faces)
      for (const int32_t v : face) vertices = std::max(vertices, static_cast<size_t>(v) + 1);
    std::vector<int32_t> start(vertices + 1, 0);
    for (const Face& face : faces)
      for (int k = 0; k < 3; ++k) ++start[static_cast<size_t>(face[static_cast<size_t>((k + 1) % 3)]) + 1];
    for (size_t v = 0; v < vertices; ++v) start[v + 1] += start[v];
    std::vector<std::pair<int32_t, int32_t>> from(3 * face_count);  // (b, 3 f + k) under a
    std::vector<int32_t> fill(start.begin(), start.end() - 1);
    for (size_t f = 0; f < face_count; ++f)
      for (int k = 0; k < 3; ++k) {
        const auto a = static_cast<size_t>(faces[f][static_cast<size_t>((k + 1) % 3)]);
        from[static_cast<size_t>(fill[a]++)] = {faces[f][static_cast<size_t>((k + 2) % 3)], static_cast<int32_t>(3 * f) + k};
      }
    for (size_t f = 0; f < face_count; ++f) {
      for (int k = 0; k < 3; ++k) {
        const auto b = static_cast<size_t>(faces[f][static_cast<size_t>((k + 2) % 3)]);
        const int32_t a = faces[f][static_cast<size_t>((k + 1) % 3)];
        int32_t twin = -1;
        for (int32_t i = start[b]; i < start[b + 1]; ++i)
          if (from[static_cast<size_t>(i)].first == a) twin = from[static_cast<size_t>(i)].second;
        if (twin < 0) continue;
        nf[f][static_cast<size_t>(k)] = twin / 3;
        nc[f][static_cast<size_t>(k)] = static_cast<int8_t>(twin % 3);
      }
    }
  }
  auto cot_at = [&](size_t f, int k) {
    return cot_from_lengths(lengths[f][static_cast<size_t>(k)], lengths[f][static_cast<size_t>((k + 1) % 3)],
                            lengths[f][static_cast<size_t>((k + 2) % 3)]);
  };
  std::vector<std::pair<int32_t, int8_t>> stack;
  for (size_t f = 0; f < face_count; ++f) {
    for (int k = 0; k < 3; ++k) stack.push_back({static_cast<int32_t>(f), static_cast<int8_t>(k)});
  }
  int flips = 0;
  const size_t limit = 100 * face_count + 1000;
  while (!stack.empty()) {
    const auto [f32, k8] = stack.back();
    stack.pop_back();
    const auto f = static_cast<size_t>(f32);
    const int k = k8;
    const int32_t g32 = nf[f][static_cast<size_t>(k)];
    if (g32 < 0 || fixed[f][static_cast<size_t>(k)]) continue;
    const auto g = static_cast<size_t>(g32);
    const int m = nc[f][static_cast<size_t>(k)];
    if (cot_at(f, k) + cot_at(g, m) >= -1e-12) continue;
    // f = (c, a, b), g = (d, b, a) sharing a-b; becomes f = (c, a, d), g = (d, b, c).
    const int32_t c = faces[f][k], a = faces[f][(k + 1) % 3], b = faces[f][(k + 2) % 3];
    const int32_t d = faces[g][m];
    if (c == d) continue;
    const double ab = lengths[f][k], bc = lengths[f][(k + 1) % 3], ca = lengths[f][(k + 2) % 3];
    const double ad = lengths[g][(m + 1) % 3], db = lengths[g][(m + 2) % 3];
    // Unfold: a = (0,0), b = (ab, 0), c above, d below.
    const double xc = (ca * ca - bc * bc + ab * ab) / (2 * ab), yc = std::sqrt(std::max(ca * ca - xc * xc, 0.0));
    const double xd = (ad * ad - db * db + ab * ab) / (2 * ab), yd = -std::sqrt(std::max(ad * ad - xd * xd, 0.0));
    const double cd = std::hypot(xc - xd, yc - yd);
    // Outer neighbours before the flip: (a,c) opposite b in f, (b,c) opposite a in f,
    // (a,d) opposite b in g, (d,b) opposite a in g.
    const auto k_ac = static_cast<size_t>((k + 2) % 3), k_bc = static_cast<size_t>((k + 1) % 3);
    const auto m_ad = static_cast<size_t>((m + 1) % 3), m_db = static_cast<size_t>((m + 2) % 3);
    const std::pair<int32_t, int8_t> n_ac{nf[f][k_ac], nc[f][k_ac]}, n_bc{nf[f][k_bc], nc[f][k_bc]};
    const std::pair<int32_t, int8_t> n_ad{nf[g][m_ad], nc[g][m_ad]}, n_db{nf[g][m_db], nc[g][m_db]};
    const uint8_t x_ac = fixed[f][k_ac], x_bc = fixed[f][k_bc], x_ad = fixed[g][m_ad], x_db = fixed[g][m_db];

    faces[f] = {c, a, d};
    lengths[f] = {ad, cd, ca};
    faces[g] = {d, b, c};
    lengths[g] = {bc, cd, db};
    auto link = [&](size_t face, int corner, std::pair<int32_t, int8_t> other, uint8_t is_fixed) {
      nf[face][static_cast<size_t>(corner)] = other.first;
      nc[face][static_cast<size_t>(corner)] = other.second;
      fixed[face][static_cast<size_t>(corner)] = is_fixed;
      if (other.first >= 0) {
        nf[static_cast<size_t>(other.first)][static_cast<size_t>(other.second)] = static_cast<int32_t>(face);
        nc[static_cast<size_t>(other.first)][static_cast<size_t>(other.second)] = static_cast<int8_t>(corner);
      }
    };
    link(f, 0, n_ad, x_ad);  // f = (c, a, d): a-d opposite c
    link(f, 2, n_ac, x_ac);  //                  c-a opposite d
    link(g, 0, n_bc, x_bc);  // g = (d, b, c): b-c opposite d
    link(g, 2, n_db, x_db);  //                  d-b opposite c
    nf[f][1] = static_cast<int32_t>(g);
    nc[f][1] = 1;
    nf[g][1] = static_cast<int32_t>(f);
    nc[g][1] = 1;
    fixed[f][1] = fixed[g][1] = 0;
    ++flips;
    for (int corner : {0, 2}) {
      stack.push_back({static_cast<int32_t>(f), static_cast<int8_t>(corner)});
      stack.push_back({static_cast<int32_t>(g), static_cast<int8_t>(corner)});
    }
    if (static_cast<size_t>(flips) > limit) throw Error(ErrorCode::kNumerical, "intrinsic Delaunay flipping did not terminate");
  }
  return flips;
}

}  // namespace facemorph
