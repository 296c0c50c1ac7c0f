#include "codec/encoder/prepare/manifold_repair.hpp"

#include "codec/core/geometry/differential.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include <algorithm>
#include <limits>
#include <unordered_map>

namespace facemorph {
namespace {

Vec3 centroid(const TriangleMesh& mesh, const Face& f) {
  return (mesh.positions[static_cast<size_t>(f[0])] + mesh.positions[static_cast<size_t>(f[1])] +
          mesh.positions[static_cast<size_t>(f[2])]) /
         3.0;
}

double face_area(const TriangleMesh& mesh, const Face& f) {
  return triangle_area(mesh.positions[static_cast<size_t>(f[0])], mesh.positions[static_cast<size_t>(f[1])],
                       mesh.positions[static_cast<size_t>(f[2])]);
}

}  // namespace

void remove_faces(TriangleMesh& mesh, const std::vector<uint8_t>& drop) {
  size_t out = 0;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (drop[f]) continue;
    mesh.faces[out] = mesh.faces[f];
    if (mesh.has_uvs()) mesh.uv_faces[out] = mesh.uv_faces[f];
    ++out;
  }
  mesh.faces.resize(out);
  if (!mesh.uv_faces.empty()) mesh.uv_faces.resize(out);
}

std::vector<int> landmark_votes(const TriangleMesh& mesh, const std::vector<int>& group_of_face, int group_count,
                                const std::vector<Vec3>& face_points) {
  std::vector<int> votes(static_cast<size_t>(group_count), 0);
  // A frame has a few dozen landmarks: a scan over the faces' centres per point is cheap, and this
  // runs only on frames that need a choice.
  for (const Vec3& p : face_points) {
    if (!p.allFinite()) continue;
    double best = std::numeric_limits<double>::infinity();
    int best_group = -1;
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const double d = (centroid(mesh, mesh.faces[f]) - p).squaredNorm();
      if (d < best) {
        best = d;
        best_group = group_of_face[f];
      }
    }
    if (best_group >= 0) ++votes[static_cast<size_t>(best_group)];
  }
  return votes;
}

int choose_face_group(const TriangleMesh& mesh, const std::vector<int>& group_of_face, int group_count,
                      const std::vector<double>& group_area, const std::vector<Vec3>& face_points) {
  const std::vector<int> votes = landmark_votes(mesh, group_of_face, group_count, face_points);
  if (std::all_of(votes.begin(), votes.end(), [](int v) { return v == 0; })) return -1;
  int chosen = 0;
  for (int g = 1; g < group_count; ++g) {
    const auto i = static_cast<size_t>(g), c = static_cast<size_t>(chosen);
    if (votes[i] > votes[c] || (votes[i] == votes[c] && group_area[i] > group_area[c])) chosen = g;
  }
  return chosen;
}

std::vector<uint8_t> non_manifold_edge_drops(const TriangleMesh& mesh, const std::vector<Vec3>& face_points,
                                             NonManifoldEdgeRepair* counts, TopologyCache& topologies) {
  const size_t face_total = mesh.faces.size();
  std::vector<uint8_t> drop(face_total, 0);
  const MeshTopology& topology = topologies.of(mesh);
  if (topology.non_manifold_edges().empty()) return drop;

  // Sheets: faces joined across edges with exactly two faces, so each edge with more ends sheets.
  DisjointSets sets(face_total);
  for (int e = 0; e < topology.edge_count(); ++e) {
    const auto incident = topology.edge_faces(e);
    if (incident.size() == 2) sets.unite(static_cast<size_t>(incident[0]), static_cast<size_t>(incident[1]));
  }
  std::vector<int> sheet_of(face_total), id_of_root(face_total, -1);
  int sheets = 0;
  for (size_t f = 0; f < face_total; ++f) {
    const size_t root = sets.find(f);
    if (id_of_root[root] < 0) id_of_root[root] = sheets++;
    sheet_of[f] = id_of_root[root];
  }
  std::vector<double> area(static_cast<size_t>(sheets), 0.0);
  for (size_t f = 0; f < face_total; ++f) area[static_cast<size_t>(sheet_of[f])] += face_area(mesh, mesh.faces[f]);
  // The landmarks' sheets first: where a seam closes round the face, the face's inner part and
  // its outer band (the rim markers') both end at the seam, and the fused sheet may be larger.
  const std::vector<int> votes = landmark_votes(mesh, sheet_of, sheets, face_points);
  const int face_sheet = choose_face_group(mesh, sheet_of, sheets, area, face_points);

  std::vector<uint8_t> kept(static_cast<size_t>(sheets), 0), lost(static_cast<size_t>(sheets), 0);
  for (int e : topology.non_manifold_edges()) {
    std::vector<int32_t> incident(topology.edge_faces(e).begin(), topology.edge_faces(e).end());
    auto at_edge = [&](int sheet) {
      return std::count_if(incident.begin(), incident.end(), [&](int32_t f) { return sheet_of[static_cast<size_t>(f)] == sheet; });
    };
    // The landmarks' sheets first; then a sheet that passes through the edge (a fin ends there); then area.
    auto rank = [&](int32_t f) {
      const auto s = static_cast<size_t>(sheet_of[static_cast<size_t>(f)]);
      return std::make_tuple(votes[s], at_edge(static_cast<int>(s)) >= 2, area[s], -f);
    };
    std::sort(incident.begin(), incident.end(), [&](int32_t a, int32_t b) { return rank(a) > rank(b); });
    const int32_t first = incident[0];
    // The partner: another face of the first's sheet (the surface continuing) where there is one.
    auto partner = std::find_if(incident.begin() + 1, incident.end(),
                                [&](int32_t f) { return sheet_of[static_cast<size_t>(f)] == sheet_of[static_cast<size_t>(first)]; });
    const int32_t second = partner != incident.end() ? *partner : incident[1];
    for (int32_t f : incident) {
      const auto s = static_cast<size_t>(sheet_of[static_cast<size_t>(f)]);
      if (f == first || f == second) {
        kept[s] = 1;
      } else {
        drop[static_cast<size_t>(f)] = 1;
        lost[s] = 1;
      }
    }
  }
  int dropped_sheets = 0;
  for (int s = 0; s < sheets; ++s) {
    const auto i = static_cast<size_t>(s);
    if (!lost[i] || kept[i] || s == face_sheet) continue;
    ++dropped_sheets;
    for (size_t f = 0; f < face_total; ++f) {
      if (sheet_of[f] == s) drop[f] = 1;
    }
  }
  if (counts) {
    counts->edges += static_cast<int>(topology.non_manifold_edges().size());
    counts->dropped_faces += static_cast<int>(std::count(drop.begin(), drop.end(), uint8_t{1}));
    counts->dropped_sheets += dropped_sheets;
  }
  return drop;
}

BowTieRepair split_bow_tie_vertices(TriangleMesh& mesh, std::vector<int>& source, TopologyCache& topologies) {
  BowTieRepair repair;
  const MeshTopology& topology = topologies.of(mesh);
  if (topology.non_manifold_vertices().empty()) return repair;
  std::unordered_map<int32_t, size_t> slot;
  for (int v : topology.non_manifold_vertices()) slot.emplace(v, slot.size());
  // Each bow-tie vertex's corners, as faces (a face holds a vertex once: degenerate faces are gone).
  std::vector<std::vector<int32_t>> faces_at(slot.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int32_t v : mesh.faces[f]) {
      auto it = slot.find(v);
      if (it != slot.end()) faces_at[it->second].push_back(static_cast<int32_t>(f));
    }
  }
  for (int v : topology.non_manifold_vertices()) {
    const std::vector<int32_t>& around = faces_at[slot[v]];
    std::unordered_map<int32_t, size_t> local;
    for (size_t i = 0; i < around.size(); ++i) local.emplace(around[i], i);
    // Fans: the faces at v joined across the edges at v that have exactly two faces.
    DisjointSets fans(around.size());
    for (size_t i = 0; i < around.size(); ++i) {
      const auto f = static_cast<size_t>(around[i]);
      const int k = static_cast<int>(std::find(mesh.faces[f].begin(), mesh.faces[f].end(), v) - mesh.faces[f].begin());
      for (int e : {topology.face_edge(static_cast<int>(f), k), topology.face_edge(static_cast<int>(f), (k + 2) % 3)}) {
        const auto incident = topology.edge_faces(e);
        if (incident.size() != 2) continue;
        const int32_t other = incident[0] == static_cast<int32_t>(f) ? incident[1] : incident[0];
        fans.unite(i, local.at(other));
      }
    }
    std::unordered_map<size_t, std::vector<int32_t>> members;
    for (size_t i = 0; i < around.size(); ++i) members[fans.find(i)].push_back(around[i]);
    if (members.size() < 2) continue;
    std::vector<std::vector<int32_t>> ordered;
    for (auto& [root, list] : members) ordered.push_back(std::move(list));
    // The fan of most faces keeps the vertex (ties: the one holding the lowest face, for determinism).
    std::sort(ordered.begin(), ordered.end(),
              [](const auto& a, const auto& b) { return a.size() != b.size() ? a.size() > b.size() : a[0] < b[0]; });
    ++repair.vertices;
    const Vec3 at = mesh.positions[static_cast<size_t>(v)];
    for (size_t fan = 1; fan < ordered.size(); ++fan) {
      Vec3 centre = Vec3::Zero();
      for (int32_t f : ordered[fan]) centre += centroid(mesh, mesh.faces[static_cast<size_t>(f)]);
      centre /= static_cast<double>(ordered[fan].size());
      const auto copy = static_cast<int32_t>(mesh.positions.size());
      mesh.positions.push_back(at + kBowTieSeparation * (centre - at));
      if (!mesh.colours.empty()) mesh.colours.push_back(mesh.colours[static_cast<size_t>(v)]);
      source.push_back(source[static_cast<size_t>(v)]);
      repair.largest_move = std::max(repair.largest_move, (mesh.positions.back() - at).norm());
      ++repair.added_vertices;
      for (int32_t f : ordered[fan]) {
        for (int32_t& corner : mesh.faces[static_cast<size_t>(f)]) {
          if (corner == v) corner = copy;
        }
        ++repair.rewired_faces;
      }
    }
  }
  return repair;
}

}  // namespace facemorph
