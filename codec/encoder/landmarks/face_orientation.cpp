// The face's orientation from its geometry: facing direction, nose tip, mirror plane, up.
#include "codec/encoder/landmarks/face_orientation.hpp"
#include "codec/encoder/landmarks/face_facing.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {
namespace {

// Below this share of its area facing one way a surface is no face seen from the front.
constexpr double kMinFacingShare = 0.25;
// The mirror test uses vertices within this share of the diagonal of the tip (the middle of the
// face: a scan's cut edge need not be symmetric), at most MirrorSearch::samples of them.
constexpr double kMirrorReach = 0.35;
// The nose's profile along the midline, between kProfileNear and kProfileFar of the tip (fractions
// of the diagonal; ~0.5 to 1.5 cm on a face).
constexpr double kProfileNear = 0.02, kProfileFar = 0.06;
// The eye sockets are read this far (fraction of the diagonal; ~2 cm on a face) up or down the
// midline from the tip and as far to either side.
constexpr double kSocketReach = 0.08;
// Below this summed evidence the two readings do not say which way is up.
constexpr double kMinUpEvidence = 0.15;
// A hint from another frame decides only if it is within 60° of this frame's vertical axis.
constexpr double kMinHintCosine = 0.5;
// How far up the midline the `up` point is taken (about where nose_bridge is).
constexpr double kUpDistance = 0.08;

std::string percent(double share) {
  char text[32];
  std::snprintf(text, sizeof text, "%.2g%%", 100 * share);
  return text;
}

// Heights averaged over each vertex and its neighbours, `rounds` times: a scanner's noise must not
// pick the tip.
std::vector<double> smoothed(const TriangleMesh& mesh, std::vector<double> values, int rounds) {
  std::vector<std::vector<int32_t>> ring(mesh.positions.size());
  for (const Face& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) ring[static_cast<size_t>(f[k])].push_back(f[(k + 1) % 3]);
  }
  for (int r = 0; r < rounds; ++r) {
    std::vector<double> next(values.size());
    for (size_t v = 0; v < values.size(); ++v) {
      double sum = values[v];
      for (int32_t u : ring[v]) sum += values[static_cast<size_t>(u)];
      next[v] = sum / static_cast<double>(1 + ring[v].size());
    }
    values = std::move(next);
  }
  return values;
}

// The point of the face's midline (the mirror plane's section of the surface) at straight-line
// distance `distance` from the tip that lies farthest up the face (up: the sign `up_sign` of the
// first coordinate); nullopt where the section does not reach that far. `projected` holds each
// face's corners as (along the midline, across it, out of the face) from the tip. Measured along
// the midline and not as the surface point nearest to tip + distance · vertical: that point lies
// off a sloping nose, and its nearest point slid along the bridge as the vertical tilted by a few degrees between frames (9.5-14.7 mm from
// the tip over 12 frames of fmsynth --head at one probe distance), which the registration took for motion.
std::optional<Vec3> midline_point(const std::vector<std::array<Vec3, 3>>& projected, double distance, double up_sign) {
  std::optional<Vec3> best;
  for (const auto& t : projected) {
    // The section of the triangle by the plane across = 0: a segment between two edge crossings.
    std::array<Vec3, 2> ends;
    int found = 0;
    for (int k = 0; k < 3 && found < 2; ++k) {
      const Vec3 &a = t[static_cast<size_t>(k)], &b = t[static_cast<size_t>((k + 1) % 3)];
      if ((a.y() < 0) == (b.y() < 0)) continue;
      const double s = a.y() / (a.y() - b.y());
      ends[static_cast<size_t>(found++)] = a + s * (b - a);
    }
    if (found < 2) continue;
    // |ends[0] + u (ends[1] - ends[0])| = distance for u in [0, 1].
    const Vec3 d = ends[1] - ends[0];
    const double qa = d.squaredNorm(), qb = 2 * ends[0].dot(d), qc = ends[0].squaredNorm() - distance * distance;
    const double disc = qb * qb - 4 * qa * qc;
    if (!(qa > 0) || disc < 0) continue;
    for (double sign : {-1.0, 1.0}) {
      const double u = (-qb + sign * std::sqrt(disc)) / (2 * qa);
      if (u < 0 || u > 1) continue;
      const Vec3 p = ends[0] + u * d;
      if (up_sign * p.x() > 0 && (!best || up_sign * p.x() > up_sign * best->x())) best = p;
    }
  }
  return best;
}

}  // namespace

void refuse_face_orientation(const std::string& name, const std::string& why) {
  throw Error(ErrorCode::kInvalidArgument,
              name + ": no face orientation found: " + why + " (give the capture its landmarks nose_tip and nose_bridge)");
}

FaceOrientation find_face_orientation(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint, double up_scale) {
  return find_face_orientation_up_side(mesh, name, vertical_hint, up_scale, nullptr);
}

FaceOrientation find_face_orientation_up_side(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint, double up_scale,
                                              const Vec3* up_side, const MirrorSearch& search) {
  FaceOrientation o;
  if (mesh.faces.empty()) refuse_face_orientation(name, "the surface has no faces");
  // 1. Facing: the area-weighted mean normal, about the area-weighted centroid.
  Vec3 normal_sum = Vec3::Zero(), centroid = Vec3::Zero();
  double area = 0;
  for (const Face& f : mesh.faces) {
    const Vec3 &a = mesh.positions[static_cast<size_t>(f[0])], &b = mesh.positions[static_cast<size_t>(f[1])],
               &c = mesh.positions[static_cast<size_t>(f[2])];
    const Vec3 n = 0.5 * (b - a).cross(c - a);
    normal_sum += n;
    area += n.norm();
    centroid += n.norm() * (a + b + c) / 3;
  }
  if (!(area > 0)) refuse_face_orientation(name, "the surface has no area");
  centroid /= area;
  o.facing_share = normal_sum.norm() / area;
  if (o.facing_share < kMinFacingShare) {
    refuse_face_orientation(name, "the surface faces no single direction (its mean normal is " + percent(o.facing_share) +
                                      " of its area: a closed surface or a whole head)");
  }
  o.facing = normal_sum.normalized();
  const double diagonal = bounding_box_diagonal(mesh.positions);

  // 2. The nose tip: the most protruding vertex along the facing direction, off the boundary.
  std::vector<double> height(mesh.positions.size());
  for (size_t v = 0; v < height.size(); ++v) height[v] = (mesh.positions[v] - centroid).dot(o.facing);
  const std::vector<double> smooth = smoothed(mesh, height, 2);
  const MeshTopology topology(mesh.faces, mesh.vertex_count());
  int tip = -1;
  for (int v = 0; v < mesh.vertex_count(); ++v) {
    if (topology.is_boundary_vertex(v)) continue;
    if (tip < 0 || smooth[static_cast<size_t>(v)] > smooth[static_cast<size_t>(tip)]) tip = v;
  }
  if (tip < 0) refuse_face_orientation(name, "the surface has no interior vertex");
  o.nose_tip = mesh.positions[static_cast<size_t>(tip)];

  // 3. The mirror plane through the tip that contains the facing direction.
  const Vec3 e1 = o.facing.unitOrthogonal(), e2 = o.facing.cross(e1);
  std::vector<Vec3> samples;
  {
    std::vector<Vec3> near;
    for (const Vec3& p : mesh.positions) {
      if ((p - o.nose_tip).norm() < kMirrorReach * diagonal) near.push_back(p);
    }
    const size_t stride = std::max<size_t>(1, near.size() / static_cast<size_t>(std::max(search.samples, 1)));
    for (size_t i = 0; i < near.size(); i += stride) samples.push_back(near[i]);
  }
  const PointToMesh surface(mesh);
  // The sum of squared distances of the samples' mirror images to the surface; infinity once it
  // passes `give_up`, the best plane's so far: a plane that cannot win is not measured to the end,
  // and no image is looked for farther than what is left of that sum (the planes far from the
  // mirror put their images far off the surface, where a nearest-point search visits the most
  // cells: measuring every plane to the end was half of an ICT frame's encode without landmarks).
  // The plane chosen and its sum are those of measuring every plane in full.
  auto mirror_sum = [&](double theta, double give_up) {
    const Vec3 n = std::cos(theta) * e1 + std::sin(theta) * e2;
    double sum = 0;
    for (const Vec3& p : samples) {
      const double d = surface.distance_below(p - 2 * (p - o.nose_tip).dot(n) * n, std::sqrt(give_up - sum));
      sum += d * d;
      if (sum > give_up) return std::numeric_limits<double>::infinity();
    }
    return sum;
  };
  constexpr double kDegree = std::numbers::pi / 180;
  // Planes every step_degrees over the half turn, then every refine_degrees within a step of the best.
  const int planes = std::max(1, static_cast<int>(std::lround(180 / search.step_degrees)));
  double best = 0, best_sum = mirror_sum(0, std::numeric_limits<double>::infinity());
  for (int step = 1; step < planes; ++step) {
    const double sum = mirror_sum(step * search.step_degrees * kDegree, best_sum);
    if (sum < best_sum) best_sum = sum, best = step * search.step_degrees * kDegree;
  }
  // (Each offset is taken from the best so far, as it always was: the default search picks the
  // planes it picked before the search was parametrised.)
  const int refine = static_cast<int>(std::lround(search.step_degrees / search.refine_degrees)) - 1;
  for (int k = -refine; k <= refine; ++k) {
    const double theta = best + k * search.refine_degrees * kDegree;
    const double sum = mirror_sum(theta, best_sum);
    if (sum < best_sum) best_sum = sum, best = theta;
  }
  o.mirror_error = std::sqrt(best_sum / static_cast<double>(std::max<size_t>(samples.size(), 1))) / diagonal;
  if (o.mirror_error > kMaxFaceMirrorError) {
    refuse_face_orientation(name, "no plane maps the surface onto itself (best " + percent(o.mirror_error) + " of its diagonal off)");
  }
  const Vec3 lateral = std::cos(best) * e1 + std::sin(best) * e2;
  o.vertical = o.facing.cross(lateral).normalized();
  const Vec3 midline_axis = o.vertical;  // the axis the readings below are taken on, before up's sign is known

  // 4. Up. Two readings of the surface in the face's plane, each signed towards +vertical, summed:
  // the nose's profile (above the tip the bridge rises to the forehead, below it the nose ends
  // above the lip, so the surface falls away more slowly upwards) and the eye sockets (beside the
  // midline above the tip the surface lies deeper than the cheeks beside it below). Heights are
  // read off the surface itself (the front-most triangle over a point of the plane), so a coarse
  // mesh reads as well as a dense one.
  std::vector<std::array<Vec3, 3>> projected(mesh.faces.size());  // (vertical, lateral, height) per corner
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vec3 d = mesh.positions[static_cast<size_t>(mesh.faces[f][k])] - o.nose_tip;
      projected[f][static_cast<size_t>(k)] = Vec3(d.dot(o.vertical), d.dot(lateral), d.dot(o.facing));
    }
  }
  auto height_at = [&](double along, double across) -> std::optional<double> {
    std::optional<double> front;
    for (const auto& t : projected) {
      const Vec2 a = t[0].head<2>(), b = t[1].head<2>(), c = t[2].head<2>(), p(along, across);
      const double twice_area = cross2(b - a, c - a);
      if (std::abs(twice_area) < 1e-300) continue;
      const double wb = cross2(p - a, c - a) / twice_area;
      const double wc = cross2(b - a, p - a) / twice_area;
      if (wb < 0 || wc < 0 || wb + wc > 1) continue;
      const double h = (1 - wb - wc) * t[0].z() + wb * t[1].z() + wc * t[2].z();
      if (!front || h > *front) front = h;
    }
    return front;
  };
  double profile[2] = {0, 0};  // mean drop from the tip per unit distance, on the +vertical and -vertical sides
  for (int side = 0; side < 2; ++side) {
    const double sign = side == 0 ? 1.0 : -1.0;
    double drop = 0, run = 0;
    for (int k = 0; k <= 8; ++k) {
      const double along = (kProfileNear + (kProfileFar - kProfileNear) * k / 8) * diagonal;
      const std::optional<double> h = height_at(sign * along, 0);
      if (!h) refuse_face_orientation(name, "the surface does not reach along its midline past the nose tip");
      drop += -*h;
      run += along;
    }
    profile[side] = drop / run;
  }
  o.nose_prominence = std::max(profile[0], profile[1]);
  double sockets[2] = {0, 0};  // mean depth beside the midline, on each side
  for (int side = 0; side < 2; ++side) {
    const double sign = side == 0 ? 1.0 : -1.0;
    double depth = 0;
    int count = 0;
    for (double across : {-kSocketReach, kSocketReach}) {
      if (const std::optional<double> h = height_at(sign * kSocketReach * diagonal, across * diagonal)) {
        depth += -*h / diagonal;
        ++count;
      }
    }
    sockets[side] = count > 0 ? depth / count : 0;
  }
  // Each reading as evidence for +vertical being up, in [-1, 1].
  const double from_profile = (profile[1] - profile[0]) / std::max({profile[0], profile[1], 1e-12});
  const double from_sockets = (sockets[0] - sockets[1]) / std::max({sockets[0], sockets[1], 1e-12});
  // The sockets count twice: on real faces they are the steadier reading (every Medusa frame reads
  // 0.39-0.48 there, while its coarse nose's profile points the wrong way in 83 of 232 frames, by
  // up to 0.30); on a face without marked sockets (fmsynth's) they read ~0 and the profile decides.
  const double evidence = from_profile + 2 * from_sockets;
  o.up_evidence = std::min(1.0, std::abs(evidence));
  if (up_side && std::abs(up_side->normalized().dot(o.vertical)) > kMinHintCosine) {
    if (up_side->dot(o.vertical) < 0) o.vertical = -o.vertical;
  } else if (o.up_evidence >= kMinUpEvidence) {
    if (evidence < 0) o.vertical = -o.vertical;
  } else if (vertical_hint && std::abs(vertical_hint->dot(o.vertical)) > kMinHintCosine) {
    if (vertical_hint->dot(o.vertical) < 0) o.vertical = -o.vertical;
    o.up_from_hint = true;
  } else {
    refuse_face_orientation(name, "neither the nose's profile nor the eye sockets say which way is up");
  }
  // 5. The up point, up the midline.
  const double up_distance = kUpDistance * (up_scale > 0 ? up_scale : diagonal);
  if (const std::optional<Vec3> m = midline_point(projected, up_distance, o.vertical.dot(midline_axis) > 0 ? 1.0 : -1.0)) {
    o.up = o.nose_tip + m->x() * midline_axis + m->y() * lateral + m->z() * o.facing;
    return o;
  }
  // The midline ends before that distance (a small region): the surface point nearest to it.
  const SurfacePoint up = surface.closest(o.nose_tip + up_distance * o.vertical);
  const Face& f = mesh.faces[static_cast<size_t>(up.face)];
  o.up = up.bary[0] * mesh.positions[static_cast<size_t>(f[0])] + up.bary[1] * mesh.positions[static_cast<size_t>(f[1])] +
         up.bary[2] * mesh.positions[static_cast<size_t>(f[2])];
  return o;
}

}  // namespace facemorph
