#include "codec/encoder/encode/frame_pipeline.hpp"

#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/landmarks/face_facing.hpp"

#include "codec/encoder/conformal/resample.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

namespace facemorph {

FrameLandmarks capture_frame_landmarks(const Capture& capture, size_t frame) {
  return frame_landmarks(capture.landmark_names, capture.landmarks[frame]);
}

FrameLandmarks frame_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& points) {
  FrameLandmarks landmarks;
  auto point = [&](const std::string& name) -> std::optional<Vec3> {
    const auto it = std::find(names.begin(), names.end(), name);
    const auto index = static_cast<size_t>(it - names.begin());
    if (it == names.end() || !points[index].allFinite()) return std::nullopt;
    return points[index];
  };
  for (size_t l = 0; l < names.size(); ++l) {
    if (names[l].rfind("rim_", 0) == 0 && points[l].allFinite()) landmarks.rim_markers.push_back(points[l]);
  }
  landmarks.centre = point("nose_tip");
  landmarks.up = point("nose_bridge");
  if (!landmarks.up) landmarks.up = point("between_eyes");
  return landmarks;
}

namespace {

// The surface points of the rim at disk angles π/2 + 2πk/count: on the rim edge whose disk angles
// bracket each.
std::vector<Vec3> rim_points_at_angles(const DiskMap& map, int count) {
  std::vector<Vec3> points;
  const std::vector<int>& rim = map.rim;
  const size_t n = rim.size();
  for (int k = 0; k < count; ++k) {
    const double target = std::remainder(std::numbers::pi / 2 + 2 * std::numbers::pi * k / count, 2 * std::numbers::pi);
    for (size_t i = 0; i < n; ++i) {
      const Vec2 &a = map.disk[static_cast<size_t>(rim[i])], &b = map.disk[static_cast<size_t>(rim[(i + 1) % n])];
      const double ta = std::atan2(a.y(), a.x());
      double span = std::remainder(std::atan2(b.y(), b.x()) - ta, 2 * std::numbers::pi);
      const double offset = std::remainder(target - ta, 2 * std::numbers::pi);
      // The rim runs counter-clockwise on the disk: the edge whose angles bracket the target.
      if (span > 0 && offset >= 0 && offset <= span) {
        const double s = offset / span;
        points.push_back((1 - s) * map.surface.positions[static_cast<size_t>(rim[i])] +
                         s * map.surface.positions[static_cast<size_t>(rim[(i + 1) % n])]);
        break;
      }
    }
  }
  return points;
}

}  // namespace

Vec3 filled_holes_facing(const PreparedFrame& prepared) {
  // Each hole's centroid counts once: the fills' normals (used first) followed the mouth's as the jaw
  // opened, and on ICT's blinking frame (eyes shut, mouth open) pointed 29 degrees up, to a tip on
  // the forehead.
  const std::vector<Vec3>& p = prepared.mesh.positions;
  if (prepared.report.holes.empty() || p.empty()) return Vec3::Zero();
  Vec3 holes = Vec3::Zero();
  for (const FilledHole& h : prepared.report.holes) {
    Vec3 centroid = Vec3::Zero();
    for (int f = h.first_face; f < h.first_face + h.face_count; ++f) {
      for (int32_t v : prepared.mesh.faces[static_cast<size_t>(f)]) centroid += p[static_cast<size_t>(v)];
    }
    holes += centroid / (3.0 * std::max(h.face_count, 1));
  }
  Vec3 all = Vec3::Zero();
  for (const Vec3& q : p) all += q;
  return holes / static_cast<double>(prepared.report.holes.size()) - all / static_cast<double>(p.size());
}

MappedFrame map_frame(const TriangleMesh& mesh, const std::string& name, const FrameLandmarks& landmarks, const MapFrameOptions& options) {
  MappedFrame frame;
  frame.name = name;
  auto start = std::chrono::steady_clock::now();
  PrepareOptions prepare;
  prepare.fill_holes = options.fill_holes;
  prepare.rim_markers = landmarks.rim_markers;
  prepare.keep_largest_component = options.keep_largest_component;
  prepare.repair_non_manifold = options.repair_non_manifold;
  // The landmarks on the face pick the sheet and component that hold it (the rim markers go with
  // rim_markers).
  if (landmarks.centre) prepare.face_points.push_back(*landmarks.centre);
  if (landmarks.up) prepare.face_points.push_back(*landmarks.up);
  frame.prepared = prepare_frame(mesh, name, prepare);
  frame.seconds_prepare = seconds_since(start);
  start = std::chrono::steady_clock::now();
  std::optional<Vec3> centre = landmarks.centre, up = landmarks.up;
  if ((!centre || !up) && options.find_orientation) {
    const Vec3 holes = filled_holes_facing(frame.prepared);
    frame.found = find_face_facing(frame.prepared.mesh, nullptr, name, options.vertical_hint ? &*options.vertical_hint : nullptr,
                                   holes.norm() > 0 ? &holes : nullptr);  // names the frame
    centre = frame.found->nose_tip;
    up = frame.found->up;
  }
  try {
    frame.map = conformal_disk_map(frame.prepared.mesh, options.conformal);
    if (centre && up) {
      normalize(frame.map, *centre, *up);
      frame.normalized = true;
      frame.found_rim = rim_points_at_angles(frame.map, kFoundRimMarkers);
    }
  } catch (const Error& e) {
    // Named like preparation's errors: a capture has hundreds of frames.
    throw Error(e.code(), name + ": " + e.what());
  }
  frame.seconds_map = seconds_since(start);
  return frame;
}

std::vector<Vec3> sample_on_grid(const MappedFrame& frame, const DiskGrid& grid) {
  return resample_positions(InverseDiskMap(frame.map), grid);
}

GridFields keyframe_fields(const GridGeometry& geometry, const std::vector<Vec3>& sampled, Representation representation,
                           const std::vector<int32_t>& fixed_nodes, bool quantized) {
  GridFields fields = compute_fields(geometry, sampled, representation, fixed_nodes);
  return quantized ? quantize_fields(fields) : fields;
}

}  // namespace facemorph
