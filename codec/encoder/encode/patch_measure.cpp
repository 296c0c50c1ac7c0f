// Measuring a frame patch (patch_measure.hpp).
#include "codec/encoder/encode/patch_measure.hpp"

#include <algorithm>

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

}  // namespace

std::vector<OffsetSample> offset_samples(const TriangleMesh& shown, const TriangleMesh& captured, const PointToMesh& to_shown,
                                         const PointToMesh& to_captured) {
  std::vector<OffsetSample> samples;
  const auto disk = [&](int face, int corner) {
    return Vec2(2 * shown.uvs[static_cast<size_t>(shown.uv_faces[static_cast<size_t>(face)][static_cast<size_t>(corner)])] - Vec2(1, 1));
  };
  const std::vector<uint8_t> used = used_vertices(captured);
  for (size_t v = 0; v < captured.positions.size(); ++v) {
    if (!used[v]) continue;
    const SurfacePoint s = to_shown.closest(captured.positions[v]);
    if (s.face < 0) continue;
    Vec2 w = Vec2::Zero();
    for (int k = 0; k < 3; ++k) w += s.bary[k] * disk(s.face, k);
    samples.push_back({w, captured.positions[v] - position_on(shown, s)});
  }
  std::vector<Vec2> vertex_w(shown.positions.size(), Vec2::Zero());
  std::vector<uint8_t> shown_used(shown.positions.size(), 0);
  for (size_t f = 0; f < shown.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<size_t>(shown.faces[f][static_cast<size_t>(k)]);
      vertex_w[v] = disk(static_cast<int>(f), k);
      shown_used[v] = 1;
    }
  }
  for (size_t v = 0; v < shown.positions.size(); ++v) {
    if (!shown_used[v]) continue;
    const SurfacePoint s = to_captured.closest(shown.positions[v]);
    if (s.face < 0) continue;
    samples.push_back({vertex_w[v], position_on(captured, s) - shown.positions[v]});
  }
  return samples;
}

PatchMeasure::PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before)
    : grid_(grid), shown_(shown), captured_(captured), before_(before), to_captured_(captured), to_before_(before) {
  const PointToMesh& to_before = to_before_;
  const std::vector<uint8_t> captured_used = used_vertices(captured), before_used = used_vertices(before);
  std::vector<double> distances;
  before_distance_.assign(before.positions.size(), -1);
  for (size_t v = 0; v < before.positions.size(); ++v) {
    if (!before_used[v]) continue;
    before_distance_[v] = to_captured_.distance(before.positions[v]);
    distances.push_back(before_distance_[v]);
  }
  for (size_t v = 0; v < captured.positions.size(); ++v) {
    if (!captured_used[v]) continue;
    double d = 0;  // one search for the nearest point and its distance
    const SurfacePoint nearest = to_before.closest(captured.positions[v], &d);
    distances.push_back(d);
    anchors_.push_back({static_cast<int32_t>(v), nearest, d});
  }
  p99_before_ = nearest_rank_p99(distances);
  diagonal_ = bounding_box_diagonal(captured.positions);
  if (p99_before_ > 0) samples_ = offset_samples(before, captured, to_before_, to_captured_);
}

double PatchMeasure::exact(const FramePatch& patch) const {
  const TriangleMesh mesh = patched(patch);
  std::vector<double> distances = shown_side(mesh);
  const PointToMesh to_mesh(mesh);
  for (const Anchor& a : anchors_) distances.push_back(to_mesh.distance(captured_.positions[static_cast<size_t>(a.vertex)]));
  return nearest_rank_p99(distances);
}

double PatchMeasure::approximate(const FramePatch& patch) const {
  const TriangleMesh mesh = patched(patch);
  if (mesh.faces.size() != before_.faces.size() || mesh.positions.size() != before_.positions.size()) return exact(patch);
  std::vector<double> distances = shown_side(mesh);
  // The faces the patch moved, alone (a few cells' worth), with their own locator.
  TriangleMesh moved;
  std::vector<char> face_moved(mesh.faces.size(), 0);
  std::vector<int32_t> remap(mesh.positions.size(), -1);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (const int32_t v : mesh.faces[f])
      face_moved[f] |= mesh.positions[static_cast<size_t>(v)] != before_.positions[static_cast<size_t>(v)];
    if (!face_moved[f]) continue;
    Face g;
    for (int k = 0; k < 3; ++k) {
      int32_t& r = remap[static_cast<size_t>(mesh.faces[f][static_cast<size_t>(k)])];
      if (r < 0) {
        r = static_cast<int32_t>(moved.positions.size());
        moved.positions.push_back(mesh.positions[static_cast<size_t>(mesh.faces[f][static_cast<size_t>(k)])]);
      }
      g[static_cast<size_t>(k)] = r;
    }
    moved.faces.push_back(g);
  }
  const PointToMesh to_moved(moved);
  for (const Anchor& a : anchors_) {
    const Vec3& p = captured_.positions[static_cast<size_t>(a.vertex)];
    if (a.point.face < 0) {
      distances.push_back(a.distance);
      continue;
    }
    // An upper bound of the distance to the patched surface: to the anchor's face where it is
    // still (the nearest of the still faces), else to the anchor moved with its face; and to the
    // moved faces, nearer where they came closer.
    double bound = a.distance;
    if (face_moved[static_cast<size_t>(a.point.face)]) {
      bound = (p - position_on(mesh, a.point)).norm();
    }
    distances.push_back(moved.faces.empty() ? bound : std::min(bound, to_moved.distance_below(p, bound)));
  }
  return nearest_rank_p99(distances);
}

std::vector<double> PatchMeasure::shown_side(const TriangleMesh& mesh) const {
  std::vector<double> distances;
  distances.reserve(before_distance_.size() + anchors_.size());
  if (mesh.positions.size() != before_.positions.size()) {  // not expected (see above); measured in full
    const std::vector<uint8_t> used = used_vertices(mesh);
    for (size_t v = 0; v < mesh.positions.size(); ++v)
      if (used[v]) distances.push_back(to_captured_.distance(mesh.positions[v]));
    return distances;
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    if (before_distance_[v] < 0) continue;
    distances.push_back(mesh.positions[v] == before_.positions[v] ? before_distance_[v] : to_captured_.distance(mesh.positions[v]));
  }
  return distances;
}

}  // namespace facemorph
