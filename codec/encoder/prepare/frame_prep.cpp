// Frame validation and repair: from a scanner's triangle soup to a disk the conformal map accepts.
#include "codec/core/geometry/differential.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include "codec/encoder/prepare/manifold_repair.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace facemorph {
namespace {

class FramePreparer {
 public:
  FramePreparer(const TriangleMesh& input, const std::string& name, const PrepareOptions& options)
      : name_(name), options_(options), input_(input), mesh_(input) {
    face_points_ = options.face_points;
    face_points_.insert(face_points_.end(), options.rim_markers.begin(), options.rim_markers.end());
  }

  PreparedFrame run() {
    check_values();
    source_.resize(mesh_.positions.size());
    std::iota(source_.begin(), source_.end(), 0);
    weld_duplicate_vertices();
    drop_degenerate_faces();
    drop_duplicate_faces();
    report_.dropped_unreferenced_vertices = compact_vertices() - report_.merged_vertices;
    if (mesh_.faces.empty()) fail(ErrorCode::kInvalidMesh, "no faces left after removing degenerate ones");
    if (options_.repair_non_manifold) {
      resolve_non_manifold_edges();
      split_bow_ties();
    }
    keep_face_component();
    orient_consistently();
    std::vector<std::vector<int>> loops = check_topology();
    count_changes();
    const size_t rim = choose_rim(loops);
    for (size_t i = 0; i < loops.size(); ++i) {
      if (i != rim) fill(loops[i]);
    }
    const MeshTopology& final_topology = topologies_.of(mesh_);
    if (!final_topology.is_manifold() || final_topology.boundary_loops().size() != 1 || final_topology.euler_characteristic() != 1) {
      fail(ErrorCode::kNotADisk, "hole filling did not produce a disk (" + std::to_string(final_topology.boundary_loops().size()) +
                                     " boundary loops, Euler characteristic " + std::to_string(final_topology.euler_characteristic()) +
                                     ", " + std::to_string(final_topology.non_manifold_edges().size()) + " non-manifold edges, " +
                                     std::to_string(final_topology.non_manifold_vertices().size()) + " non-manifold vertices, " +
                                     std::to_string(final_topology.inconsistently_oriented_edges().size()) + " flipped edges)");
    }
    PreparedFrame out;
    out.rim = final_topology.boundary_loops()[0];
    if (face_outward(out.rim)) {
      for (Face& f : mesh_.faces) std::swap(f[1], f[2]);
      for (Face& f : mesh_.uv_faces) std::swap(f[1], f[2]);
      std::reverse(out.rim.begin(), out.rim.end());
      report_.reoriented_faces += mesh_.face_count();
    }
    out.mesh = std::move(mesh_);
    out.source_vertex = std::move(source_);
    out.report = std::move(report_);
    return out;
  }

 private:
  [[noreturn]] void fail(ErrorCode code, const std::string& why) const { throw Error(code, name_ + ": " + why); }

  void check_values() const {
    if (mesh_.faces.empty()) fail(ErrorCode::kInvalidMesh, "the mesh has no faces");
    for (size_t i = 0; i < mesh_.positions.size(); ++i) {
      if (!mesh_.positions[i].allFinite())
        fail(ErrorCode::kInvalidMesh, "vertex " + std::to_string(i) + " has a non-finite coordinate (NaN or Inf)");
    }
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      for (int32_t v : mesh_.faces[f]) {
        if (v < 0 || v >= mesh_.vertex_count()) {
          fail(ErrorCode::kInvalidMesh,
               "face " + std::to_string(f) + " refers to vertex " + std::to_string(v) + " of " + std::to_string(mesh_.vertex_count()));
        }
      }
    }
    if (mesh_.has_uvs()) {
      for (const Vec2& t : mesh_.uvs) {
        if (!t.allFinite()) fail(ErrorCode::kInvalidMesh, "a texture coordinate is not finite");
      }
      for (const Face& t : mesh_.uv_faces) {
        for (int32_t v : t) {
          if (v < 0 || static_cast<size_t>(v) >= mesh_.uvs.size())
            fail(ErrorCode::kInvalidMesh, "a texture-coordinate index is out of range");
        }
      }
    } else if (!mesh_.uv_faces.empty()) {
      fail(ErrorCode::kInvalidMesh, "texture-coordinate faces do not match the faces");
    }
    // Colours are optional but, when present, one per vertex: every later step keeps them so.
    if (!mesh_.colours.empty() && !mesh_.has_colours()) {
      fail(ErrorCode::kInvalidMesh,
           std::to_string(mesh_.colours.size()) + " vertex colours for " + std::to_string(mesh_.vertex_count()) + " vertices");
    }
    for (size_t i = 0; i < mesh_.colours.size(); ++i) {
      const Vec3& c = mesh_.colours[i];
      if (!c.allFinite() || c.minCoeff() < 0 || c.maxCoeff() > 1)
        fail(ErrorCode::kInvalidMesh, "vertex " + std::to_string(i) + " has a colour outside [0, 1]");
    }
  }

  // Scanners split vertices along texture seams; welding exact duplicates restores one surface.
  void weld_duplicate_vertices() {
    std::vector<int32_t> order(mesh_.positions.size());
    std::iota(order.begin(), order.end(), 0);
    auto less = [&](int32_t a, int32_t b) {
      const Vec3 &p = mesh_.positions[static_cast<size_t>(a)], &q = mesh_.positions[static_cast<size_t>(b)];
      return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
    };
    std::sort(order.begin(), order.end(), less);
    std::vector<int32_t> target(mesh_.positions.size());
    std::iota(target.begin(), target.end(), 0);
    for (size_t i = 1; i < order.size(); ++i) {
      const int32_t a = order[i - 1], b = order[i];
      if (mesh_.positions[static_cast<size_t>(a)] == mesh_.positions[static_cast<size_t>(b)]) {
        target[static_cast<size_t>(b)] = target[static_cast<size_t>(a)];
        ++report_.merged_vertices;
      }
    }
    if (report_.merged_vertices == 0) return;
    for (Face& f : mesh_.faces) {
      for (int32_t& v : f) v = target[static_cast<size_t>(v)];
    }
  }

  void remove_faces(const std::vector<uint8_t>& drop) { facemorph::remove_faces(mesh_, drop); }

  // Edges with three or more faces: the sheet that holds the face keeps them (manifold_repair.hpp).
  void resolve_non_manifold_edges() {
    NonManifoldEdgeRepair counts;
    const std::vector<uint8_t> drop = non_manifold_edge_drops(mesh_, face_points_, &counts, topologies_);
    if (counts.edges == 0) return;
    report_.non_manifold_edges += counts.edges;
    report_.dropped_sheet_faces += counts.dropped_faces;
    report_.dropped_sheets += counts.dropped_sheets;
    remove_faces(drop);
    compact_vertices();  // the sheets' vertices go with them, counted in the totals
    if (mesh_.faces.empty()) fail(ErrorCode::kInvalidMesh, "no faces left after resolving the non-manifold edges");
  }

  void split_bow_ties() {
    const BowTieRepair split = split_bow_tie_vertices(mesh_, source_, topologies_);
    report_.split_vertices += split.vertices;
    report_.added_vertices += split.added_vertices;
    report_.rewired_faces += split.rewired_faces;
    largest_vertex_move_ = std::max(largest_vertex_move_, split.largest_move);
  }

  // Real scans carry eyeballs, teeth, stray shells and specks as separate surfaces. The face is the
  // component the landmarks lie on, else the one of largest area (not of most faces: a dense
  // eyeball can outnumber a coarse face). Specks (under kSpeckAreaFraction of its area) are dropped
  // whenever repairs are on; the rest only with keep_largest_component (else check_topology names
  // the count).
  void keep_face_component() {
    const MeshTopology& topology = topologies_.of(mesh_);
    if (topology.component_count() <= 1 || (!options_.repair_non_manifold && !options_.keep_largest_component)) return;
    const std::vector<int>& component = topology.face_components();
    std::vector<double> area(static_cast<size_t>(topology.component_count()), 0.0);
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      const Face& t = mesh_.faces[f];
      area[static_cast<size_t>(component[f])] +=
          triangle_area(mesh_.positions[static_cast<size_t>(t[0])], mesh_.positions[static_cast<size_t>(t[1])],
                        mesh_.positions[static_cast<size_t>(t[2])]);
    }
    int keep = choose_face_group(mesh_, component, topology.component_count(), area, face_points_);
    if (keep < 0) keep = static_cast<int>(std::max_element(area.begin(), area.end()) - area.begin());
    std::vector<uint8_t> speck(area.size(), 0), other(area.size(), 0);
    for (size_t c = 0; c < area.size(); ++c) {
      if (static_cast<int>(c) == keep) continue;
      if (options_.repair_non_manifold && area[c] < kSpeckAreaFraction * area[static_cast<size_t>(keep)]) {
        speck[c] = 1;
        ++report_.dropped_specks;
      } else if (options_.keep_largest_component) {
        other[c] = 1;
        ++report_.dropped_components;
      }
    }
    std::vector<uint8_t> drop(mesh_.faces.size(), 0);
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      const auto c = static_cast<size_t>(component[f]);
      drop[f] = speck[c] | other[c];
      report_.dropped_speck_faces += speck[c];
      report_.dropped_component_faces += other[c];
    }
    remove_faces(drop);
    compact_vertices();  // the components' vertices are not a repair of their own
  }

  // Faces with a repeated vertex are dropped. A zero-area face with three distinct vertices has
  // one vertex on the segment of the other two (a T-junction): the face across that segment is
  // split at the vertex, so the surface stays closed there instead of opening a slit.
  void drop_degenerate_faces() {
    Vec3 lo = mesh_.positions[0], hi = lo;
    for (const Vec3& p : mesh_.positions) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double tolerance = 1e-14 * (hi - lo).squaredNorm();
    for (int round = 0; round < 8; ++round) {
      std::vector<uint8_t> drop(mesh_.faces.size(), 0);
      std::unordered_map<uint64_t, std::vector<int>> by_edge;
      for (size_t f = 0; f < mesh_.faces.size(); ++f) {
        for (int k = 0; k < 3; ++k)
          by_edge[undirected_edge_key(mesh_.faces[f][k], mesh_.faces[f][(k + 1) % 3])].push_back(static_cast<int>(f));
      }
      bool changed = false;
      const size_t count = mesh_.faces.size();
      for (size_t f = 0; f < count; ++f) {
        if (drop[f]) continue;
        const Face face = mesh_.faces[f];
        if (face[0] == face[1] || face[1] == face[2] || face[0] == face[2]) {
          drop[f] = 1;
          ++report_.dropped_degenerate_faces;
          changed = true;
          continue;
        }
        const Vec3 &a = mesh_.positions[static_cast<size_t>(face[0])], &b = mesh_.positions[static_cast<size_t>(face[1])],
                   &c = mesh_.positions[static_cast<size_t>(face[2])];
        if (triangle_area(a, b, c) > tolerance) continue;
        drop[f] = 1;
        ++report_.dropped_degenerate_faces;
        changed = true;
        // Corner k lies between the other two when its edge vectors point apart.
        for (int k = 0; k < 3; ++k) {
          const int32_t m = face[k], e0 = face[(k + 1) % 3], e1 = face[(k + 2) % 3];
          const Vec3& pm = mesh_.positions[static_cast<size_t>(m)];
          if ((mesh_.positions[static_cast<size_t>(e0)] - pm).dot(mesh_.positions[static_cast<size_t>(e1)] - pm) >= 0) continue;
          for (int g : by_edge[undirected_edge_key(e0, e1)]) {
            if (g == static_cast<int>(f) || drop[static_cast<size_t>(g)]) continue;
            const Face other = mesh_.faces[static_cast<size_t>(g)];
            int j = 0;  // other = (e1, e0, d) up to rotation: find e1
            while (j < 3 && other[j] != e1) ++j;
            if (j == 3 || other[(j + 1) % 3] != e0) continue;  // inconsistent orientation: leave it
            const int32_t d = other[(j + 2) % 3];
            mesh_.faces[static_cast<size_t>(g)] = {e1, m, d};
            mesh_.faces.push_back({m, e0, d});
            drop.push_back(0);
            if (mesh_.has_uvs()) {
              const Face uv = mesh_.uv_faces[static_cast<size_t>(g)];
              const int32_t uv_m = mesh_.uv_faces[f][k];
              mesh_.uv_faces[static_cast<size_t>(g)] = {uv[j], uv_m, uv[(j + 2) % 3]};
              mesh_.uv_faces.push_back({uv_m, uv[(j + 1) % 3], uv[(j + 2) % 3]});
            }
            ++report_.split_faces;
            break;
          }
          break;
        }
      }
      remove_faces(drop);
      if (!changed) return;
    }
  }

  void drop_duplicate_faces() {
    std::map<std::array<int32_t, 3>, int> seen;
    std::vector<uint8_t> drop(mesh_.faces.size(), 0);
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      std::array<int32_t, 3> key = mesh_.faces[f];
      std::sort(key.begin(), key.end());
      if (!seen.emplace(key, static_cast<int>(f)).second) {
        drop[f] = 1;
        ++report_.dropped_duplicate_faces;
      }
    }
    if (report_.dropped_duplicate_faces > 0) remove_faces(drop);
  }

  // Drops the vertices no face uses; returns how many.
  int compact_vertices() {
    std::vector<int32_t> remap(mesh_.positions.size(), -1);
    for (const Face& f : mesh_.faces) {
      for (int32_t v : f) remap[static_cast<size_t>(v)] = 0;
    }
    int32_t next = 0;
    for (int32_t& r : remap) {
      if (r == 0) r = next++;
    }
    const int dropped = static_cast<int>(mesh_.positions.size()) - next;
    std::vector<Vec3> positions(static_cast<size_t>(next));
    std::vector<Vec3> colours(mesh_.has_colours() ? static_cast<size_t>(next) : 0);
    std::vector<int> source(static_cast<size_t>(next));
    for (size_t v = 0; v < remap.size(); ++v) {
      if (remap[v] < 0) continue;
      positions[static_cast<size_t>(remap[v])] = mesh_.positions[v];
      if (!colours.empty()) colours[static_cast<size_t>(remap[v])] = mesh_.colours[v];
      source[static_cast<size_t>(remap[v])] = source_[v];
    }
    mesh_.colours = std::move(colours);
    for (Face& f : mesh_.faces) {
      for (int32_t& v : f) v = remap[static_cast<size_t>(v)];
    }
    mesh_.positions = std::move(positions);
    source_ = std::move(source);
    return dropped;
  }

  // The totals every repair adds to (spec/method.md §2.1), before holes are filled: what changed,
  // and how far the repaired surface lies from the captured vertices it no longer holds.
  void count_changes() {
    RepairReport& r = report_;
    r.faces_changed = r.dropped_degenerate_faces + 2 * r.split_faces + r.dropped_duplicate_faces + r.reoriented_faces +
                      r.dropped_sheet_faces + r.rewired_faces + r.dropped_component_faces + r.dropped_speck_faces;
    std::vector<uint8_t> kept(input_.positions.size(), 0), used(input_.positions.size(), 0);
    for (int s : source_) kept[static_cast<size_t>(s)] = 1;
    for (const Face& f : input_.faces) {
      for (int32_t v : f) used[static_cast<size_t>(v)] = 1;
    }
    const auto kept_count = static_cast<int>(std::count(kept.begin(), kept.end(), uint8_t{1}));
    r.vertices_changed = static_cast<int>(input_.positions.size()) - kept_count + r.added_vertices;
    r.diagonal = bounding_box_diagonal(input_.positions);
    r.largest_move = largest_vertex_move_;
    if (kept_count == static_cast<int>(input_.positions.size())) return;
    const PointToMesh surface(mesh_);
    for (size_t v = 0; v < input_.positions.size(); ++v) {
      if (used[v] && !kept[v]) r.largest_move = std::max(r.largest_move, surface.distance(input_.positions[v]));
    }
  }

  // Flips faces so that every interior edge is traversed once each way (fewest flips per
  // component); a surface where that is impossible is non-orientable.
  void orient_consistently() {
    const MeshTopology& topology = topologies_.of(mesh_);
    if (!topology.non_manifold_edges().empty()) {
      const auto e = topology.edge(topology.non_manifold_edges()[0]);
      fail(ErrorCode::kInvalidMesh, std::to_string(topology.non_manifold_edges().size()) + " non-manifold edges (edge " +
                                        std::to_string(e[0]) + "-" + std::to_string(e[1]) + " has " +
                                        std::to_string(topology.edge_faces(topology.non_manifold_edges()[0]).size()) + " faces)");
    }
    if (topology.inconsistently_oriented_edges().empty()) return;
    const auto face_count = static_cast<size_t>(topology.face_count());
    std::vector<int8_t> flip(face_count, -1);
    for (size_t seed = 0; seed < face_count; ++seed) {
      if (flip[seed] >= 0) continue;
      std::vector<size_t> component = {seed};
      flip[seed] = 0;
      for (size_t i = 0; i < component.size(); ++i) {
        const size_t f = component[i];
        for (int k = 0; k < 3; ++k) {
          const int e = topology.face_edge(static_cast<int>(f), k);
          for (int32_t g : topology.edge_faces(e)) {
            if (static_cast<size_t>(g) == f) continue;
            // Same direction in both faces means exactly one of them must flip.
            const int32_t a = mesh_.faces[f][k], b = mesh_.faces[f][(k + 1) % 3];
            const Face& other = mesh_.faces[static_cast<size_t>(g)];
            bool same = false;
            for (int m = 0; m < 3; ++m) same = same || (other[m] == a && other[(m + 1) % 3] == b);
            const int8_t want = static_cast<int8_t>(flip[f] ^ (same ? 1 : 0));
            if (flip[static_cast<size_t>(g)] < 0) {
              flip[static_cast<size_t>(g)] = want;
              component.push_back(static_cast<size_t>(g));
            } else if (flip[static_cast<size_t>(g)] != want) {
              fail(ErrorCode::kInvalidMesh, "the surface is not orientable (a Moebius band); it cannot be a face capture");
            }
          }
        }
      }
      size_t flipped = 0;
      for (size_t f : component) flipped += static_cast<size_t>(flip[f]);
      const bool invert = 2 * flipped > component.size();
      for (size_t f : component) {
        if ((flip[f] != 0) != invert) {
          std::swap(mesh_.faces[f][1], mesh_.faces[f][2]);
          if (mesh_.has_uvs()) std::swap(mesh_.uv_faces[f][1], mesh_.uv_faces[f][2]);
          ++report_.reoriented_faces;
        }
      }
    }
  }

  // Captures from different scanners disagree on orientation; facemorph's convention is normals
  // on the convex side of the face (towards the viewer), so H has one sign across frames. True
  // when the faces must be flipped: the vector area points away from where the surface bulges
  // relative to its rim.
  bool face_outward(const std::vector<int>& rim) const {
    Vec3 rim_centroid = Vec3::Zero();
    for (int v : rim) rim_centroid += mesh_.positions[static_cast<size_t>(v)] / static_cast<double>(rim.size());
    Vec3 vector_area = Vec3::Zero(), bulge = Vec3::Zero();
    for (const Face& f : mesh_.faces) {
      const Vec3 &a = mesh_.positions[static_cast<size_t>(f[0])], &b = mesh_.positions[static_cast<size_t>(f[1])],
                 &c = mesh_.positions[static_cast<size_t>(f[2])];
      const Vec3 n = 0.5 * (b - a).cross(c - a);
      vector_area += n;
      bulge += n.norm() * ((a + b + c) / 3.0 - rim_centroid);
    }
    return vector_area.dot(bulge) < 0;
  }

  std::vector<std::vector<int>> check_topology() {
    const MeshTopology& topology = topologies_.of(mesh_);
    if (!topology.non_manifold_vertices().empty()) {
      fail(ErrorCode::kInvalidMesh, std::to_string(topology.non_manifold_vertices().size()) +
                                        " non-manifold vertices where separate fans of faces touch (vertex " +
                                        std::to_string(source_[static_cast<size_t>(topology.non_manifold_vertices()[0])]) + ")");
    }
    if (topology.component_count() > 1) {
      fail(ErrorCode::kNotADisk, std::to_string(topology.component_count()) +
                                     " components; a face capture must be one open surface (--largest-component keeps the largest)");
    }
    const auto& loops = topology.boundary_loops();
    if (loops.empty()) fail(ErrorCode::kNotADisk, "a closed surface (no boundary); a face capture must be an open surface");
    // χ = 2 - 2g - b for a connected orientable surface with b boundary loops.
    const int genus = (2 - static_cast<int>(loops.size()) - topology.euler_characteristic()) / 2;
    if (genus != 0) {
      fail(ErrorCode::kNotADisk, "the surface has " + std::to_string(genus) + " handle(s) (genus " + std::to_string(genus) +
                                     "); a face capture must be a disk with holes at most");
    }
    if (loops.size() > 1 && !options_.fill_holes) {
      fail(ErrorCode::kNotADisk, std::to_string(loops.size() - 1) + " holes besides the outer rim, and hole filling is off");
    }
    return loops;
  }

  double loop_perimeter(const std::vector<int>& loop) const {
    double length = 0;
    for (size_t i = 0; i < loop.size(); ++i) {
      length += (mesh_.positions[static_cast<size_t>(loop[i])] - mesh_.positions[static_cast<size_t>(loop[(i + 1) % loop.size()])]).norm();
    }
    return length;
  }

  // The rim is the loop the rim markers lie on (smallest median distance), else the longest.
  size_t choose_rim(const std::vector<std::vector<int>>& loops) const {
    size_t best = 0;
    double best_score = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < loops.size(); ++i) {
      double score;
      if (options_.rim_markers.empty()) {
        score = -loop_perimeter(loops[i]);
      } else {
        std::vector<double> distance;
        for (const Vec3& marker : options_.rim_markers) {
          double nearest = std::numeric_limits<double>::infinity();
          for (int v : loops[i]) nearest = std::min(nearest, (mesh_.positions[static_cast<size_t>(v)] - marker).norm());
          distance.push_back(nearest);
        }
        std::nth_element(distance.begin(), distance.begin() + static_cast<long>(distance.size() / 2), distance.end());
        score = distance[distance.size() / 2];
      }
      if (score < best_score) {
        best_score = score;
        best = i;
      }
    }
    return best;
  }

  void fill(const std::vector<int>& loop) {
    // Target edge length at each loop vertex: the mean length of its edges in the mesh.
    std::unordered_map<int, std::pair<double, int>> lengths;
    for (int v : loop) lengths[v] = {0.0, 0};
    std::vector<Vec2> loop_uv(loop.size(), Vec2::Zero());
    std::unordered_map<int, int> uv_of;
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int32_t a = mesh_.faces[f][k], b = mesh_.faces[f][(k + 1) % 3];
        const double length = (mesh_.positions[static_cast<size_t>(a)] - mesh_.positions[static_cast<size_t>(b)]).norm();
        for (int32_t v : {a, b}) {
          auto it = lengths.find(v);
          if (it == lengths.end()) continue;
          it->second.first += length;
          it->second.second += 1;
        }
        if (mesh_.has_uvs() && lengths.contains(a)) uv_of.try_emplace(a, mesh_.uv_faces[f][k]);
      }
    }
    std::vector<double> sigma;
    for (size_t i = 0; i < loop.size(); ++i) {
      const auto& [sum, count] = lengths[loop[i]];
      sigma.push_back(count > 0 ? sum / count : 0.0);
      if (mesh_.has_uvs()) loop_uv[i] = mesh_.uvs[static_cast<size_t>(uv_of[loop[i]])];
    }
    const HoleFill fill = fill_hole(mesh_, loop, sigma, mesh_.has_uvs() ? &loop_uv : nullptr);

    FilledHole hole;
    hole.loop = loop;
    hole.first_vertex = mesh_.vertex_count();
    hole.vertex_count = static_cast<int>(fill.positions.size());
    hole.first_face = mesh_.face_count();
    hole.face_count = static_cast<int>(fill.faces.size());
    hole.perimeter = loop_perimeter(loop);
    hole.min_angle_degrees = fill.min_angle_degrees;
    hole.sharpest_hole_corner_degrees = fill.sharpest_hole_corner_degrees;
    hole.folded_faces = fill.folded_faces;
    const auto uv_base = static_cast<int32_t>(mesh_.uvs.size());
    for (const Vec3& p : fill.positions) {
      mesh_.positions.push_back(p);
      source_.push_back(-1);
    }
    if (!mesh_.colours.empty()) mesh_.colours.insert(mesh_.colours.end(), fill.colours.begin(), fill.colours.end());
    if (mesh_.has_uvs()) {
      mesh_.uvs.insert(mesh_.uvs.end(), fill.uvs.begin(), fill.uvs.end());
      for (const Face& f : fill.faces) {
        Face uv;
        for (int k = 0; k < 3; ++k) {
          uv[static_cast<size_t>(k)] = f[k] >= hole.first_vertex ? uv_base + (f[k] - hole.first_vertex) : uv_of[f[k]];
        }
        mesh_.uv_faces.push_back(uv);
      }
    }
    for (const Face& f : fill.faces) {
      mesh_.faces.push_back(f);
      hole.area += triangle_area(mesh_.positions[static_cast<size_t>(f[0])], mesh_.positions[static_cast<size_t>(f[1])],
                                 mesh_.positions[static_cast<size_t>(f[2])]);
    }
    report_.holes.push_back(std::move(hole));
  }

  std::string name_;
  const PrepareOptions& options_;
  const TriangleMesh& input_;
  std::vector<Vec3> face_points_;  // the landmarks, rim markers included
  double largest_vertex_move_ = 0;
  TriangleMesh mesh_;
  TopologyCache topologies_;  // mesh_'s topology, rebuilt only after a step has edited the faces
  std::vector<int> source_;
  RepairReport report_;
};

}  // namespace

bool RepairReport::changed() const {
  return merged_vertices || dropped_degenerate_faces || split_faces || dropped_duplicate_faces || dropped_unreferenced_vertices ||
         reoriented_faces || dropped_components || non_manifold_edges || split_vertices || dropped_specks || !holes.empty();
}

std::string RepairReport::summary() const {
  std::ostringstream out;
  const char* separator = "";
  auto item = [&](int count, const char* what) {
    if (count == 0) return;
    out << separator << what << " " << count;
    separator = "; ";
  };
  if (!holes.empty()) {
    int faces = 0, folded = 0;
    double min_angle = 180;
    for (const FilledHole& h : holes) {
      faces += h.face_count;
      folded += h.folded_faces;
      min_angle = std::min(min_angle, h.min_angle_degrees);
    }
    out << "filled " << holes.size() << " hole" << (holes.size() > 1 ? "s" : "") << " (" << faces << " faces, smallest angle "
        << static_cast<int>(min_angle) << " deg";
    if (folded > 0) out << ", " << folded << " facing against the hole";
    out << ")";
    separator = "; ";
  }
  item(merged_vertices, "welded duplicate vertices:");
  item(dropped_degenerate_faces, "dropped degenerate faces:");
  item(split_faces, "split faces at T-junctions:");
  item(dropped_duplicate_faces, "dropped duplicate faces:");
  item(dropped_unreferenced_vertices, "dropped unreferenced vertices:");
  item(reoriented_faces, "reoriented faces:");
  if (non_manifold_edges > 0) {
    out << separator << "resolved " << non_manifold_edges << " edge" << (non_manifold_edges > 1 ? "s" : "") << " with 3+ faces (dropped "
        << dropped_sheet_faces << " faces, " << dropped_sheets << " whole sheet" << (dropped_sheets != 1 ? "s" : "") << ")";
    separator = "; ";
  }
  if (split_vertices > 0) {
    out << separator << "split " << split_vertices << " bow-tie vert" << (split_vertices > 1 ? "ices" : "ex") << " (" << added_vertices
        << " added, " << rewired_faces << " faces re-attached)";
    separator = "; ";
  }
  if (dropped_specks > 0) {
    out << separator << "dropped " << dropped_specks << " speck" << (dropped_specks > 1 ? "s" : "") << " (" << dropped_speck_faces
        << " faces, each under " << 100 * kSpeckAreaFraction << "% of the face's area)";
    separator = "; ";
  }
  if (dropped_components > 0) {
    out << separator << "dropped " << dropped_components << " other component" << (dropped_components > 1 ? "s" : "") << " ("
        << dropped_component_faces << " faces)";
    separator = "; ";
  }
  if (faces_changed > 0 || vertices_changed > 0) {
    char moved[96];
    std::snprintf(moved, sizeof moved, "%.3g (%.3g%% of the diagonal)", largest_move, diagonal > 0 ? 100 * largest_move / diagonal : 0.0);
    out << separator << "in all " << faces_changed << " faces and " << vertices_changed << " vertices changed, the surface moved at most "
        << moved;
  }
  const std::string text = out.str();
  return text.empty() ? "valid as captured" : text;
}

PreparedFrame prepare_frame(const TriangleMesh& mesh, const std::string& name, const PrepareOptions& options) {
  return FramePreparer(mesh, name, options).run();
}

}  // namespace facemorph
