// fmsynth --defects: what scanners write into a face's mesh, written into a synthetic frame so the
// encoder's repairs (spec/method.md §2.1) have inputs whose every defect is known and counted.
#include "codec/encoder/synth/synth.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <numbers>
#include <sstream>

namespace facemorph {
namespace {

constexpr std::array<std::pair<DefectKind, const char*>, 7> kDefectNames = {{{kDefectBowTies, "bow-ties"},
                                                                             {kDefectThreeFaceEdges, "three-face-edges"},
                                                                             {kDefectDuplicateFaces, "duplicates"},
                                                                             {kDefectDegenerateFaces, "degenerate"},
                                                                             {kDefectFlippedPatch, "flipped"},
                                                                             {kDefectIslands, "islands"},
                                                                             {kDefectTorso, "torso"}}};

// Where each defect sits on the material ellipse (metres; the face is 0.16 x 0.20): apart from one
// another and from the landmarks (eyes at y 0.025, nose at the centre, mouth at y -0.045).
const Vec2 kPinchAt(-0.05, -0.02), kFlapAt(0.05, -0.03);
const std::array<Vec2, 3> kFinsAt = {Vec2(-0.045, -0.06), Vec2(0.045, -0.06), Vec2(0.0, 0.05)};
const std::array<Vec2, 5> kDuplicatesAt = {Vec2(-0.02, -0.075), Vec2(0.02, -0.075), Vec2(-0.06, 0.0), Vec2(0.06, 0.0), Vec2(0.0, -0.02)};
const std::array<Vec2, 2> kDegenerateAt = {Vec2(-0.03, 0.07), Vec2(0.03, 0.07)};
const Vec2 kSliverAt(0.035, -0.005);
const Vec2 kFlippedAt(0.05, 0.015);
constexpr double kFlippedRadius = 0.012;
constexpr int kIslands = 4;
constexpr double kSeamRadius = 0.85;             // of the ellipse's size
constexpr double kSeamFrom = 50, kSeamTo = 130;  // degrees, over the forehead
constexpr int kTorsoRows = 5;
constexpr double kTorsoRowSpacing = 0.012;  // metres

class DefectWriter {
 public:
  DefectWriter(TriangleMesh& mesh, const std::vector<Vec2>& material, int boundary_count)
      : mesh_(mesh), material_(material), boundary_(boundary_count), original_(static_cast<int32_t>(material.size())) {
    double sum = 0;
    for (const Face& f : mesh_.faces) sum += (position(f[0]) - position(f[1])).norm();
    edge_ = sum / static_cast<double>(std::max<size_t>(mesh_.faces.size(), 1));
  }

  // Two single faces cut out at an interior vertex, half its ring apart: the vertex's faces make
  // two fans, and the two holes one pinched loop.
  int pinch() {
    const int32_t v = nearest_vertex(kPinchAt);
    const std::vector<size_t> ring = faces_around(v);
    if (ring.size() < 4) return 0;
    drop_.push_back(ring[1]);
    drop_.push_back(ring[1 + ring.size() / 2]);
    return 1;
  }

  // A face that touches the surface at one vertex only, standing off it: a bow tie that, once
  // split, is a speck.
  int flap() {
    const int32_t v = nearest_vertex(kFlapAt);
    const Vec3 n = normal(v), side = any_perpendicular(n);
    const int32_t a = add_vertex(position(v) + edge_ * (n + side), v), b = add_vertex(position(v) + edge_ * (n - side), v);
    added_.push_back({v, a, b});
    return 1;
  }

  int fins() {
    int count = 0;
    for (const Vec2& at : kFinsAt) {
      const size_t f = nearest_face(at);
      const int32_t a = mesh_.faces[f][0], b = mesh_.faces[f][1];
      const int32_t c = add_vertex(0.5 * (position(a) + position(b)) + edge_ * normal(a), a);
      added_.push_back({a, b, c});
      ++count;
    }
    return count;
  }

  int duplicates() {
    int count = 0;
    for (size_t i = 0; i < kDuplicatesAt.size(); ++i) {
      const Face f = mesh_.faces[nearest_face(kDuplicatesAt[i])];
      switch (i % 3) {
        case 0: added_.push_back(f); break;                    // as written
        case 1: added_.push_back({f[1], f[2], f[0]}); break;   // rotated
        default: added_.push_back({f[0], f[2], f[1]}); break;  // reversed
      }
      ++count;
    }
    return count;
  }

  int degenerate() {
    int count = 0;
    for (const Vec2& at : kDegenerateAt) {
      const Face f = mesh_.faces[nearest_face(at)];
      added_.push_back({f[0], f[0], f[1]});
      added_.push_back({f[1], f[2], f[2]});
      count += 2;
    }
    return count;
  }

  // Where a scanner zips two patches, one side's edge a-b meets the other side's two edges a-m, m-b
  // (m on the segment): the face across a-b is split at m, and the crack is closed by the sliver
  // (b, a, m), three distinct vertices in a line, zero area. Still a closed manifold: only the sliver
  // is wrong, and the repair drops it and splits the face on a-b's other side at m.
  int sliver() {
    const Face f = mesh_.faces[nearest_face(kSliverAt)];
    const int32_t a = f[0], b = f[1];
    for (size_t g : faces_around(a)) {
      const Face across = mesh_.faces[g];
      for (int k = 0; k < 3; ++k) {
        if (across[k] != b || across[(k + 1) % 3] != a) continue;
        const int32_t d = across[(k + 2) % 3];
        const int32_t m = add_vertex(0.5 * (position(a) + position(b)), a);
        if (!mesh_.uvs.empty()) mesh_.uvs.back() = 0.5 * (mesh_.uvs[static_cast<size_t>(a)] + mesh_.uvs[static_cast<size_t>(b)]);
        drop_.push_back(g);
        added_.push_back({b, m, d});
        added_.push_back({m, a, d});
        added_.push_back({b, a, m});
        return 1;
      }
    }
    return 0;  // a-b on the rim: no face across (nearest_face keeps off the rim, so not at these points)
  }

  int flip_patch() {
    int count = 0;
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      if ((material_centre(mesh_.faces[f]) - kFlippedAt).norm() > kFlippedRadius) continue;
      std::swap(mesh_.faces[f][1], mesh_.faces[f][2]);
      ++count;
    }
    return count;
  }

  // Specks beyond the rim: two faces each, an edge length across, off the surface.
  int islands(int* faces) {
    for (int k = 0; k < kIslands; ++k) {
      const double theta = 2 * std::numbers::pi * (k + 0.5) / kIslands;
      const Vec2 rim = SyntheticFace::rim_point(theta);
      const int32_t near = nearest_vertex(0.98 * rim);
      const Vec3 out = (Vec3(rim.x(), rim.y(), 0)).normalized();
      const Vec3 centre = position(near) + 3 * edge_ * out, up = Vec3::UnitZ(), side = out.cross(up);
      const int32_t a = add_vertex(centre, near), b = add_vertex(centre + edge_ * side, near),
                    c = add_vertex(centre + edge_ * (side + up), near), d = add_vertex(centre + edge_ * up, near);
      added_.push_back({a, b, c});
      added_.push_back({a, c, d});
      *faces += 2;
    }
    return kIslands;
  }

  // A hair or torso surface fused to the face along an open seam of interior edges over the
  // forehead: kTorsoRows rows of faces going out and back from the seam. Each seam edge has a third
  // face; the face's sheet still passes through it.
  int torso(int* seam_edges) {
    std::vector<int32_t> seam;
    const int stops = 9;
    for (int s = 0; s < stops; ++s) {
      const double theta = (kSeamFrom + (kSeamTo - kSeamFrom) * s / (stops - 1)) * std::numbers::pi / 180;
      const int32_t v = nearest_vertex(kSeamRadius * SyntheticFace::rim_point(theta));
      if (seam.empty()) {
        seam.push_back(v);
      } else {
        const std::vector<int32_t> path = shortest_path(seam.back(), v);
        seam.insert(seam.end(), path.begin() + 1, path.end());
      }
    }
    int faces = 0;
    std::vector<int32_t> previous = seam;
    for (int row = 1; row <= kTorsoRows; ++row) {
      std::vector<int32_t> next;
      for (int32_t s : seam) {
        const Vec2 m = material_[static_cast<size_t>(s)];
        const Vec3 out = Vec3(m.x(), m.y(), 0).normalized();
        next.push_back(add_vertex(position(s) + row * kTorsoRowSpacing * (out - 0.7 * Vec3::UnitZ()).normalized(), s));
      }
      for (size_t i = 0; i + 1 < seam.size(); ++i) {
        added_.push_back({previous[i + 1], previous[i], next[i]});
        added_.push_back({previous[i + 1], next[i], next[i + 1]});
        faces += 2;
      }
      previous = std::move(next);
    }
    *seam_edges = static_cast<int>(seam.size()) - 1;
    return faces;
  }

  // Applies the cuts and the additions; texture coordinates stay one per vertex.
  void finish() {
    std::sort(drop_.begin(), drop_.end());
    for (auto it = drop_.rbegin(); it != drop_.rend(); ++it) mesh_.faces.erase(mesh_.faces.begin() + static_cast<long>(*it));
    mesh_.faces.insert(mesh_.faces.end(), added_.begin(), added_.end());
    if (!mesh_.uvs.empty()) mesh_.uv_faces = mesh_.faces;
  }

 private:
  Vec3 position(int32_t v) const { return mesh_.positions[static_cast<size_t>(v)]; }

  Vec2 material_centre(const Face& f) const {
    return (material_[static_cast<size_t>(f[0])] + material_[static_cast<size_t>(f[1])] + material_[static_cast<size_t>(f[2])]) / 3.0;
  }

  // The interior vertex of the frame nearest to material point m.
  int32_t nearest_vertex(const Vec2& m) const {
    int32_t best = boundary_;
    for (int32_t v = boundary_; v < original_; ++v) {
      if ((material_[static_cast<size_t>(v)] - m).squaredNorm() < (material_[static_cast<size_t>(best)] - m).squaredNorm()) best = v;
    }
    return best;
  }

  // The frame's own face (as sampled) nearest to material point m, away from the rim.
  size_t nearest_face(const Vec2& m) const {
    size_t best = 0;
    double best_distance = std::numeric_limits<double>::infinity();
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      const Face& face = mesh_.faces[f];
      if (std::any_of(face.begin(), face.end(), [&](int32_t v) { return v < boundary_ || v >= original_; })) continue;
      const double d = (material_centre(face) - m).squaredNorm();
      if (d < best_distance) {
        best_distance = d;
        best = f;
      }
    }
    return best;
  }

  // The faces at v, in order of angle around it on the material plane.
  std::vector<size_t> faces_around(int32_t v) const {
    std::vector<std::pair<double, size_t>> ring;
    const Vec2 at = material_[static_cast<size_t>(v)];
    for (size_t f = 0; f < mesh_.faces.size(); ++f) {
      const Face& face = mesh_.faces[f];
      if (std::find(face.begin(), face.end(), v) == face.end()) continue;
      const Vec2 d = material_centre(face) - at;
      ring.emplace_back(std::atan2(d.y(), d.x()), f);
    }
    std::sort(ring.begin(), ring.end());
    std::vector<size_t> out;
    for (const auto& r : ring) out.push_back(r.second);
    return out;
  }

  Vec3 normal(int32_t v) const {
    Vec3 n = Vec3::Zero();
    for (const Face& f : mesh_.faces) {
      if (std::find(f.begin(), f.end(), v) == f.end()) continue;
      n += (position(f[1]) - position(f[0])).cross(position(f[2]) - position(f[0]));
    }
    return n.norm() > 0 ? Vec3(n.normalized()) : Vec3(Vec3::UnitZ());
  }

  static Vec3 any_perpendicular(const Vec3& n) {
    const Vec3 axis = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    return n.cross(axis).normalized();
  }

  // A new vertex at p, with the texture coordinate and colour of vertex `like`.
  int32_t add_vertex(const Vec3& p, int32_t like) {
    mesh_.positions.push_back(p);
    if (!mesh_.uvs.empty()) mesh_.uvs.push_back(mesh_.uvs[static_cast<size_t>(like)]);
    if (!mesh_.colours.empty()) mesh_.colours.push_back(mesh_.colours[static_cast<size_t>(like)]);
    return static_cast<int32_t>(mesh_.positions.size() - 1);
  }

  // Fewest edges from a to b over the frame's own faces (breadth first), both ends included.
  std::vector<int32_t> shortest_path(int32_t a, int32_t b) const {
    std::vector<std::vector<int32_t>> neighbours(static_cast<size_t>(original_));
    for (const Face& f : mesh_.faces) {
      for (int k = 0; k < 3; ++k) {
        if (f[k] < original_ && f[(k + 1) % 3] < original_) neighbours[static_cast<size_t>(f[k])].push_back(f[(k + 1) % 3]);
      }
    }
    std::vector<int32_t> from(static_cast<size_t>(original_), -1);
    std::deque<int32_t> queue = {a};
    from[static_cast<size_t>(a)] = a;
    while (!queue.empty() && from[static_cast<size_t>(b)] < 0) {
      const int32_t v = queue.front();
      queue.pop_front();
      for (int32_t w : neighbours[static_cast<size_t>(v)]) {
        if (from[static_cast<size_t>(w)] >= 0 || w < boundary_) continue;  // stay off the rim: the seam's edges are interior
        from[static_cast<size_t>(w)] = v;
        queue.push_back(w);
      }
    }
    std::vector<int32_t> path = {b};
    while (path.back() != a) path.push_back(from[static_cast<size_t>(path.back())]);
    std::reverse(path.begin(), path.end());
    return path;
  }

  TriangleMesh& mesh_;
  const std::vector<Vec2>& material_;
  int32_t boundary_;
  int32_t original_;
  double edge_ = 0;
  std::vector<size_t> drop_;
  std::vector<Face> added_;
};

}  // namespace

uint32_t parse_defects(const std::string& list) {
  if (list == "all") return kDefectAll;
  uint32_t defects = 0;
  std::stringstream in(list);
  std::string name;
  while (std::getline(in, name, ',')) {
    const auto it = std::find_if(kDefectNames.begin(), kDefectNames.end(), [&](const auto& d) { return name == d.second; });
    if (it == kDefectNames.end()) {
      throw Error(ErrorCode::kInvalidArgument, "--defects: '" + name + "' is none of all, " + defect_names(kDefectAll));
    }
    defects |= it->first;
  }
  return defects;
}

std::string defect_names(uint32_t defects) {
  std::string out;
  for (const auto& [kind, name] : kDefectNames) {
    if (!(defects & kind)) continue;
    if (!out.empty()) out += ',';
    out += name;
  }
  return out;
}

DefectCounts add_defects(TriangleMesh& mesh, const std::vector<Vec2>& material, int boundary_count, uint32_t defects) {
  if (material.size() != mesh.positions.size()) throw Error(ErrorCode::kInvalidArgument, "add_defects: one material point a vertex");
  DefectCounts counts;
  DefectWriter writer(mesh, material, boundary_count);
  // Cuts and flips first, on the frame's own faces; then what is added.
  if (defects & kDefectFlippedPatch) counts.flipped_faces = writer.flip_patch();
  if (defects & kDefectBowTies) {
    counts.bow_ties = writer.pinch();
    counts.flaps = writer.flap();
    counts.bow_ties += counts.flaps;
  }
  if (defects & kDefectThreeFaceEdges) counts.fins = counts.three_face_edges = writer.fins();
  if (defects & kDefectDuplicateFaces) counts.duplicate_faces = writer.duplicates();
  if (defects & kDefectDegenerateFaces) {
    counts.slivers = writer.sliver();
    counts.degenerate_faces = writer.degenerate() + counts.slivers;
  }
  if (defects & kDefectIslands) counts.islands = writer.islands(&counts.island_faces);
  if (defects & kDefectTorso) {
    counts.torso_faces = writer.torso(&counts.seam_edges);
    counts.three_face_edges += counts.seam_edges;
  }
  writer.finish();
  return counts;
}

}  // namespace facemorph
