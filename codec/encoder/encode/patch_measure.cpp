// Measuring a frame patch (patch_measure.hpp).
#include "codec/encoder/encode/patch_measure.hpp"

#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace facemorph {

namespace {

// The point of `mesh` at `s` (a face and barycentric coordinates on it).
Vec3 position_on(const TriangleMesh& mesh, const SurfacePoint& s) {
  const Face& f = mesh.faces[static_cast<size_t>(s.face)];
  Vec3 point = Vec3::Zero();
  for (int k = 0; k < 3; ++k) point += s.bary[k] * mesh.positions[static_cast<size_t>(f[static_cast<size_t>(k)])];
  return point;
}

std::vector<uint8_t> used_vertices(const TriangleMesh& mesh) {
  std::vector<uint8_t> used(mesh.positions.size(), 0);
  for (const Face& f : mesh.faces)
    for (int32_t v : f) used[static_cast<size_t>(v)] = 1;
  return used;
}

// The disk point of `shown`'s corner k of a face (its UV is (w + 1) / 2).
Vec2 disk_point(const TriangleMesh& shown, int face, int corner) {
  return 2 * shown.uvs[static_cast<size_t>(shown.uv_faces[static_cast<size_t>(face)][static_cast<size_t>(corner)])] - Vec2(1, 1);
}

// A captured point p to its nearest point s of `shown`.
OffsetSample captured_sample(const TriangleMesh& shown, const Vec3& p, const SurfacePoint& s) {
  Vec2 w = Vec2::Zero();
  for (int k = 0; k < 3; ++k) w += s.bary[k] * disk_point(shown, s.face, k);
  return {w, p - position_on(shown, s)};
}

// Each vertex's disk point (of the last face using it; 0 where none does).
std::vector<Vec2> vertex_disk_points(const TriangleMesh& shown) {
  std::vector<Vec2> w(shown.positions.size(), Vec2::Zero());
  for (size_t f = 0; f < shown.faces.size(); ++f)
    for (int k = 0; k < 3; ++k) w[static_cast<size_t>(shown.faces[f][static_cast<size_t>(k)])] = disk_point(shown, static_cast<int>(f), k);
  return w;
}

// The distance from p to `mesh` where under `bound` (closest_squared's search, which measures no
// face farther), else at least `bound` (infinity where nothing is nearer).
double distance_within(const PointToMesh& mesh, const Vec3& p, double bound) {
  double squared = 0;
  mesh.closest_squared(p, squared, nullptr, bound);
  return std::sqrt(squared);
}

}  // namespace

// The faces of a patched mesh that the patch moved (a vertex of theirs differs from the unpatched
// mesh's), alone, with their own locator: a few cells' worth of the surface.
class PatchMeasure::MovedFaces {
 public:
  MovedFaces(const TriangleMesh& mesh, const TriangleMesh& before)
      : flags_(moved_flags(mesh, before)), original_(indices_of(flags_)), part_(sub_mesh(mesh, flags_)), locator_(part_) {}
  MovedFaces(const MovedFaces&) = delete;
  MovedFaces& operator=(const MovedFaces&) = delete;

  bool moved(int32_t face) const { return flags_[static_cast<size_t>(face)] != 0; }
  const std::vector<char>& flags() const { return flags_; }
  bool empty() const { return part_.faces.empty(); }
  const PointToMesh& locator() const { return locator_; }
  // The nearest moved face to p (an index of the patched mesh) and its squared distance, where
  // nearer than `bound` (closest_squared's).
  SurfacePoint closest_squared(const Vec3& p, double& squared, double bound) const {
    SurfacePoint s = locator_.closest_squared(p, squared, nullptr, bound);
    if (s.face >= 0) s.face = original_[static_cast<size_t>(s.face)];
    return s;
  }

 private:
  static std::vector<char> moved_flags(const TriangleMesh& mesh, const TriangleMesh& before) {
    std::vector<char> moved(mesh.faces.size(), 0);
    for (size_t f = 0; f < mesh.faces.size(); ++f)
      for (const int32_t v : mesh.faces[f]) moved[f] |= mesh.positions[static_cast<size_t>(v)] != before.positions[static_cast<size_t>(v)];
    return moved;
  }
  // The moved faces' indices in the patched mesh, in its order (sub_mesh keeps that order, so of
  // equally near faces the lower index wins in both).
  static std::vector<int32_t> indices_of(const std::vector<char>& moved) {
    std::vector<int32_t> indices;
    for (size_t f = 0; f < moved.size(); ++f)
      if (moved[f]) indices.push_back(static_cast<int32_t>(f));
    return indices;
  }

  std::vector<char> flags_;
  std::vector<int32_t> original_;
  TriangleMesh part_;
  PointToMesh locator_;
};

PatchMeasure::PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before,
                           std::nullptr_t)
    : grid_(grid),
      shown_(shown),
      captured_(captured),
      before_(before),
      to_captured_(captured),
      to_before_(before),
      diagonal_(bounding_box_diagonal(captured.positions)) {}

PatchMeasure::PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before)
    : PatchMeasure(grid, shown, captured, before, nullptr) {
  const std::vector<uint8_t> captured_used = used_vertices(captured), before_used = used_vertices(before);
  std::vector<double> distances;
  // One search for each vertex of either mesh gives its distance and, for the samples, its point.
  std::vector<SurfacePoint> on_captured(before.positions.size()), on_before;
  distances_.shown.assign(before.positions.size(), -1);
  // Each search starts from the vertex before's nearest face (a neighbour's on either mesh: near the
  // nearest), which changes no result (closest_from), only the faces measured.
  int hint = -1;
  for (size_t v = 0; v < before.positions.size(); ++v) {
    if (!before_used[v]) continue;
    on_captured[v] = to_captured_.closest_from(before.positions[v], hint, &distances_.shown[v]);
    hint = on_captured[v].face;
    distances.push_back(distances_.shown[v]);
  }
  hint = -1;
  for (size_t v = 0; v < captured.positions.size(); ++v) {
    if (!captured_used[v]) continue;
    double squared = 0;
    on_before.push_back(to_before_.closest_squared(captured.positions[v], squared, nullptr, std::numeric_limits<double>::infinity(), hint));
    hint = on_before.back().face;
    anchor_vertex_.push_back(static_cast<int32_t>(v));
    distances_.anchor_face.push_back(on_before.back().face);
    distances_.anchor_squared.push_back(squared);
    distances.push_back(std::sqrt(squared));
  }
  distances_.p99 = nearest_rank_p99(distances);
  shown_face_.resize(on_captured.size());
  for (size_t v = 0; v < on_captured.size(); ++v) shown_face_[v] = on_captured[v].face;
  if (distances_.p99 <= 0) return;
  // The samples: the captured vertices', then the shown vertices' (the order the fit sums them in).
  anchor_sample_.assign(anchor_vertex_.size(), -1);
  for (size_t a = 0; a < anchor_vertex_.size(); ++a) {
    if (on_before[a].face < 0) continue;
    anchor_sample_[a] = static_cast<int32_t>(samples_.size());
    samples_.push_back(captured_sample(before, anchor_position(a), on_before[a]));
  }
  const std::vector<Vec2> vertex_w = vertex_disk_points(before);
  shown_sample_.assign(before.positions.size(), -1);
  for (size_t v = 0; v < before.positions.size(); ++v) {
    if (!before_used[v] || on_captured[v].face < 0) continue;
    shown_sample_[v] = static_cast<int32_t>(samples_.size());
    samples_.push_back({vertex_w[v], position_on(captured, on_captured[v]) - before.positions[v]});
  }
}

PatchMeasure::PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before,
                           UnpatchedDistances distances)
    : PatchMeasure(grid, shown, captured, before, nullptr) {
  distances_ = std::move(distances);
  const std::vector<uint8_t> used = used_vertices(captured);
  for (size_t v = 0; v < captured.positions.size(); ++v)
    if (used[v]) anchor_vertex_.push_back(static_cast<int32_t>(v));
  if (anchor_vertex_.size() != distances_.anchor_face.size() || distances_.shown.size() != before.positions.size())
    throw Error(ErrorCode::kInvalidArgument, "PatchMeasure: the kept distances are not this frame's");
}

std::vector<OffsetSample> PatchMeasure::samples_of(const TriangleMesh& mesh) const {
  std::vector<OffsetSample> out;
  if (shown_sample_.size() != mesh.positions.size() || mesh.faces.size() != before_.faces.size()) {
    // Not the unpatched mesh's faces, or measured without samples: every vertex searched.
    const PointToMesh to_mesh(mesh);
    for (size_t a = 0; a < anchor_vertex_.size(); ++a) {
      const SurfacePoint s = to_mesh.closest(anchor_position(a));
      if (s.face >= 0) out.push_back(captured_sample(mesh, anchor_position(a), s));
    }
    const std::vector<uint8_t> used = used_vertices(mesh);
    const std::vector<Vec2> vertex_w = vertex_disk_points(mesh);
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
      if (!used[v]) continue;
      const SurfacePoint s = to_captured_.closest(mesh.positions[v]);
      if (s.face >= 0) out.push_back({vertex_w[v], position_on(captured_, s) - mesh.positions[v]});
    }
    return out;
  }
  const MovedFaces moved(mesh, before_);
  for (size_t a = 0; a < anchor_vertex_.size(); ++a) {
    double squared = 0;
    const SurfacePoint s = nearest_patched(a, moved, squared);
    if (s.face < 0) continue;
    const bool anchor = s.face == distances_.anchor_face[a] && !moved.moved(s.face);  // its unpatched sample
    out.push_back(anchor ? samples_[static_cast<size_t>(anchor_sample_[a])] : captured_sample(mesh, anchor_position(a), s));
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const int32_t i = shown_sample_[v];
    if (i < 0) continue;
    const OffsetSample& unpatched = samples_[static_cast<size_t>(i)];
    if (mesh.positions[v] == before_.positions[v]) {
      out.push_back(unpatched);
      continue;
    }
    const SurfacePoint s = to_captured_.closest_from(mesh.positions[v], shown_face_[v]);  // from where it was
    if (s.face >= 0) out.push_back({unpatched.w, position_on(captured_, s) - mesh.positions[v]});
  }
  return out;
}

SurfacePoint PatchMeasure::nearest_patched(size_t a, const MovedFaces& moved, double& squared) const {
  const Vec3 p = anchor_position(a);
  const int32_t face = distances_.anchor_face[a];
  squared = distances_.anchor_squared[a];
  SurfacePoint best;
  if (face < 0) return best;  // no faces
  // A search stops a little past the nearest found so far (a relative 1e-9, far above the rounding
  // of the squares, so that a tie is still found and the lower face index wins, as in one search).
  const auto past = [](double squared_distance) { return std::sqrt(squared_distance) * (1 + 1e-9) + 1e-300; };
  if (!moved.moved(face)) {
    // The nearest still face is the unpatched nearest (bary left to the caller); a moved face wins
    // only as near as it.
    best.face = face;
    if (moved.empty()) return best;
    double nearer = 0;
    const SurfacePoint s = moved.closest_squared(p, nearer, past(squared));
    if (nearer < squared || (nearer == squared && s.face < best.face)) {
      best = s;
      squared = nearer;
    }
    return best;
  }
  // Its face moved: the moved faces (near p) first, then the still ones as near as they are.
  best = moved.closest_squared(p, squared, std::numeric_limits<double>::infinity());
  double still = 0;
  const SurfacePoint s = to_before_.closest_squared(p, still, &moved.flags(), past(squared));
  if (still < squared || (still == squared && s.face < best.face)) {
    best = s;
    squared = still;
  }
  return best;
}

double PatchMeasure::exact_at(const std::vector<Vec3>& positions) const {
  const TriangleMesh mesh = shown_mesh(grid_, positions, shown_.hole_level);
  std::vector<double> distances = shown_side(mesh);
  if (mesh.faces.size() != before_.faces.size() || mesh.positions.size() != before_.positions.size()) {
    const PointToMesh to_mesh(mesh);  // not expected (see above); measured in full
    for (size_t a = 0; a < anchor_vertex_.size(); ++a) distances.push_back(to_mesh.distance(anchor_position(a)));
    return nearest_rank_p99(distances);
  }
  const MovedFaces moved(mesh, before_);
  for (size_t a = 0; a < anchor_vertex_.size(); ++a) {
    const Vec3 p = anchor_position(a);
    const int32_t face = distances_.anchor_face[a];
    const double unpatched = std::sqrt(distances_.anchor_squared[a]);
    // The minimum of the two searches is the square root of the smaller square, as one search of
    // the patched mesh gives it; each second search stops at the first's distance.
    if (face < 0 || moved.empty()) {
      distances.push_back(unpatched);
    } else if (!moved.moved(face)) {  // the nearest still face: the unpatched nearest
      distances.push_back(std::min(unpatched, distance_within(moved.locator(), p, unpatched)));
    } else {  // its face moved: the moved faces (near p) first, then the still ones
      const double to_moved = moved.locator().distance(p);
      double still = 0;
      to_before_.closest_squared(p, still, &moved.flags(), to_moved);
      distances.push_back(std::min(to_moved, std::sqrt(still)));
    }
  }
  return nearest_rank_p99(distances);
}

double PatchMeasure::approximate(const FramePatch& patch) const {
  const TriangleMesh mesh = patched(patch);
  if (mesh.faces.size() != before_.faces.size() || mesh.positions.size() != before_.positions.size()) return exact(patch);
  std::vector<double> distances = shown_side(mesh);
  const MovedFaces moved(mesh, before_);
  for (size_t a = 0; a < anchor_vertex_.size(); ++a) {
    const Vec3 p = anchor_position(a);
    const int32_t face = distances_.anchor_face[a];
    // An upper bound of the distance to the patched surface: to the anchor's face where it is
    // still (the nearest of the still faces), else to the anchor moved with its face (its
    // barycentric coordinates as the unpatched search found them); and to the moved faces,
    // nearer where they came closer.
    double bound = std::sqrt(distances_.anchor_squared[a]);
    if (face < 0) {
      distances.push_back(bound);
      continue;
    }
    if (moved.moved(face)) {
      const Face& f = before_.faces[static_cast<size_t>(face)];
      const Vec3 bary = closest_point_barycentric(p, before_.positions[static_cast<size_t>(f[0])], before_.positions[static_cast<size_t>(f[1])],
                                                  before_.positions[static_cast<size_t>(f[2])]);
      bound = (p - position_on(mesh, SurfacePoint{face, bary})).norm();
    }
    distances.push_back(moved.empty() ? bound : std::min(bound, distance_within(moved.locator(), p, bound)));
  }
  return nearest_rank_p99(distances);
}

std::vector<double> PatchMeasure::shown_side(const TriangleMesh& mesh) const {
  std::vector<double> distances;
  distances.reserve(distances_.shown.size() + anchor_vertex_.size());
  if (mesh.positions.size() != before_.positions.size()) {  // not expected (see above); measured in full
    const std::vector<uint8_t> used = used_vertices(mesh);
    for (size_t v = 0; v < mesh.positions.size(); ++v)
      if (used[v]) distances.push_back(to_captured_.distance(mesh.positions[v]));
    return distances;
  }
  if (last_position_.empty()) {
    last_position_.assign(mesh.positions.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
    last_distance_.assign(mesh.positions.size(), 0);
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    if (distances_.shown[v] < 0) continue;
    const Vec3& p = mesh.positions[v];
    if (p == before_.positions[v]) {
      distances.push_back(distances_.shown[v]);
      continue;
    }
    // A node the patch's nodes near it moved as the last patch measured did (the search's tries
    // differ in a few lattice nodes) keeps that distance: a function of the position alone.
    if (!(p == last_position_[v])) {
      last_position_[v] = p;
      to_captured_.closest_from(p, v < shown_face_.size() ? shown_face_[v] : -1, &last_distance_[v]);
    }
    distances.push_back(last_distance_[v]);
  }
  return distances;
}

}  // namespace facemorph
