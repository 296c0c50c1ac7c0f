// The keyframes on G: each keyframe's registered surface in the face frame (fitted to every frame
// where asked), its fields with the fixed-frame nodes of every keyframe's folds, its holes as a
// level set and its texture on the disk; each array put in the store as it is made.
#include "codec/encoder/encode/build_stage.hpp"

#include "codec/encoder/encode/frame_sampler.hpp"

#include "codec/core/util/elapsed.hpp"
#include "codec/encoder/stages/fit_keyframes.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>
#include <vector>

namespace facemorph {

namespace {

double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double length2 = ab.squaredNorm();
  const double s = length2 > 0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

// --texture auto: the disk texture as sharp as the captured one, not sharper. The face covers
// `texels` of the captured image (its UV area); the disk shows them on π/4 M² texels, and the
// conformal map shrinks some regions against others, so M is 1.5 times the equal-area size, rounded
// up to a multiple of 64, within [128, 1024] (a 1024² disk already holds a 1024² texture's face).
int auto_texture_size(const TriangleMesh& surface, int width, int height) {
  constexpr double kMargin = 1.5;
  constexpr int kLowest = 128, kHighest = 1024;
  double area = 0;
  for (const Face& f : surface.uv_faces) {
    const Vec2 a = surface.uvs[static_cast<size_t>(f[0])], b = surface.uvs[static_cast<size_t>(f[1])],
               c = surface.uvs[static_cast<size_t>(f[2])];
    area += std::abs(signed_area(a, b, c));
  }
  const double texels = std::min(area, 1.0) * width * height;
  const double side = kMargin * std::sqrt(texels * 4 / std::numbers::pi);
  return std::clamp(64 * static_cast<int>(std::ceil(side / 64)), kLowest, kHighest);
}

// --texture auto for a frame coloured per vertex: vertex colours hold no detail finer than the
// triangles, so the disk gets a texel per triangle (about 2 V for V vertices) over its π/4 M²
// texels, with the same 1.5 margin for the conformal map's crowding, rounding and bounds as above.
// 20k vertices give 384, 5k give 192 (spec/method.md §7.7).
int auto_texture_size_for_colours(int vertex_count) {
  constexpr double kMargin = 1.5, kTexelsPerVertex = 2;
  constexpr int kLowest = 128, kHighest = 1024;
  const double side = kMargin * std::sqrt(kTexelsPerVertex * vertex_count * 4 / std::numbers::pi);
  return std::clamp(64 * static_cast<int>(std::ceil(side / 64)), kLowest, kHighest);
}

}  // namespace

std::vector<double> hole_level(const PreparedFrame& prepared, const DiskMap& map, const std::vector<Vec2>& points) {
  std::vector<double> level(points.size(), kHoleLevelBand);
  std::vector<std::vector<Vec2>> outlines;
  Vec2 lo = Vec2::Constant(1e300), hi = -lo;
  for (const FilledHole& hole : prepared.report.holes) {
    std::vector<Vec2> outline;
    for (int v : hole.loop) {
      outline.push_back(map.disk[static_cast<size_t>(v)]);
      lo = lo.cwiseMin(outline.back());
      hi = hi.cwiseMax(outline.back());
    }
    if (outline.size() >= 3) outlines.push_back(std::move(outline));
  }
  if (outlines.empty()) return level;
  lo -= Vec2::Constant(kHoleLevelBand);
  hi += Vec2::Constant(kHoleLevelBand);
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec2& p = points[i];
    if (p.x() < lo.x() || p.y() < lo.y() || p.x() > hi.x() || p.y() > hi.y()) continue;  // farther than the band
    double distance = 1e300;
    bool inside = false;
    for (const auto& outline : outlines) {
      for (size_t k = 0; k < outline.size(); ++k)
        distance = std::min(distance, distance_to_segment(p, outline[k], outline[(k + 1) % outline.size()]));
      inside = inside || inside_polygon(p, outline);
    }
    if (!inside) distance = std::min(distance, kHoleLevelBand);
    // Outside, the distance is capped (far from every hole it does not matter); inside it is not, so
    // a hole that one keyframe has and the next has not opens from its deepest point and grows
    // smoothly as the blend shifts, instead of appearing at once where a capped inside would meet
    // the other keyframe's cap.
    level[i] = inside ? -distance : distance;
  }
  return level;
}

std::unique_ptr<StoredSequence> build_keyframes(const BuildSettings& settings, const BuildFrames& frames, const std::vector<int>& keyframes,
                                                int grid_n, const KeyframeSegment* segment, EncodeReport& report,
                                                KeyframeSurfaces* kept, const StoredSequence* textures_from) {
  if (kept && segment) throw Error(ErrorCode::kInvalidArgument, "build: a segment's surfaces are not kept");
  const auto start = std::chrono::steady_clock::now();
  const Capture& capture = frames.capture;
  const FrameMaps& maps = frames.maps;
  const FrameSampler sampler(maps, frames.registrations);
  const std::vector<SelectionFrame>& selection = frames.selection.frames();
  if (keyframes.empty()) throw Error(ErrorCode::kInvalidArgument, "no keyframes to build");
  const std::shared_ptr<const GridGeometry> held_geometry = shared_grid_geometry(grid_n);
  const GridGeometry& geometry = *held_geometry;
  const DiskGrid& grid = geometry.grid();
  // The keyframes this build codes (`own`, of `keyframes`) and those its fit solves over (`fit`):
  // all of them, or a segment's and its margins.
  const size_t own_first = segment ? segment->first : 0, own_end = segment ? segment->end : keyframes.size();
  const size_t fit_first = segment ? segment->fit_first : 0, fit_end = segment ? segment->fit_end : keyframes.size();
  if (!(fit_first <= own_first && own_first < own_end && own_end <= fit_end && fit_end <= keyframes.size())) {
    throw Error(ErrorCode::kInvalidArgument, "build: a segment's keyframes outside its fit's or the capture's");
  }
  const std::vector<int> fitted(keyframes.begin() + static_cast<long>(fit_first), keyframes.begin() + static_cast<long>(fit_end));
  const size_t keys = own_end - own_first, fit_keys = fitted.size(), own_offset = own_first - fit_first;
  bool any_holes = false;
  for (size_t i = 0; i < capture.frames.size(); ++i) any_holes = any_holes || maps.summaries[i].holes_filled > 0;
  const bool store_holes = any_holes && !settings.keep_holes_filled;
  // Textures: every keyframe's, or (a capture without images or vertex colours) none; some but not
  // all is an error.
  bool store_texture = settings.texture && (!segment || segment->textures);
  for (int k : keyframes) {
    const bool has = maps.has_texture(k);
    if (store_texture && !has) {
      if (k != keyframes.front()) {
        throw Error(
            ErrorCode::kMissingTexture,
            maps.summaries[static_cast<size_t>(k)].name +
                ": this keyframe has no texture while others have (--no-texture encodes geometry only)");
      }
      store_texture = false;
    }
  }
  // Another N's build of the same keyframes on the same disk: its textures are these.
  if (textures_from) {
    const std::vector<Keyframe>& theirs = textures_from->shape().keyframes;
    bool same = !segment && theirs.size() == keyframes.size() && textures_from->size() > 0 && store_texture == !textures_from->texture(0)->empty();
    for (size_t k = 0; same && k < keyframes.size(); ++k) same = theirs[k].time == capture.frames[static_cast<size_t>(keyframes[k])].time;
    if (!same) textures_from = nullptr;
  }
  int texture_size = settings.texture_size;
  if (store_texture && textures_from) {
    texture_size = textures_from->texture(0)->width;
  } else if (store_texture && texture_size == 0) {
    const int first = keyframes.front();
    const FrameSummary& summary = maps.summaries[static_cast<size_t>(first)];
    const std::filesystem::path& texture = maps.textures[static_cast<size_t>(first)];
    if (!texture.empty() && summary.has_uvs) {
      const Image image = read_image(texture);
      texture_size = auto_texture_size(maps.frame(first)->map.surface, image.width, image.height);
    } else {
      texture_size = auto_texture_size_for_colours(summary.vertices);
    }
  }
  report.texture_size = store_texture ? texture_size : 0;
  // The registered surfaces in the face frame first: the fixed-frame nodes are the union of the
  // keyframes' folds, since the keyframes are blended together. Each goes to the store as it is
  // made (1.25 MB at N = 257, and a long capture has hundreds) and is read back for each later use.
  const auto surfaces = std::make_shared<SurfaceStore>(settings.spill_keyframes ? SurfaceStore::Mode::kSpill : SurfaceStore::Mode::kMemory);
  SurfaceStore& local = *surfaces;
  local.reset(fit_keys);
  std::vector<std::vector<int32_t>> folds(keys);
  Sequence shape;
  shape.grid_n = grid_n;
  shape.representation = frames.representation;
  shape.spline = settings.spline;
  shape.fps = capture.fps;
  shape.first_time = frames.first_time;
  shape.last_time = frames.last_time;
  shape.units = capture.units;
  shape.pose_centre = frames.pose_centre;
  shape.keyframes.resize(keys);
  for (size_t k = 0; k < keys; ++k) {
    const auto index = static_cast<size_t>(keyframes[own_first + k]);
    shape.keyframes[k].time = capture.frames[index].time;
    shape.keyframes[k].pose = selection[index].pose;
  }
  // The keyframes' arrays go to the store as they are made (settings.spill_keyframes): a long
  // capture's hundreds of keyframes are not held until the file is written.
  auto stored = std::make_unique<StoredSequence>(std::move(shape), settings.spill_keyframes ? SpillMode::kSpill : SpillMode::kMemory);
  parallel_for(
      static_cast<int>(fit_keys), settings.threads,
      [&](int k) {
        const auto index = static_cast<size_t>(fitted[static_cast<size_t>(k)]);
        const std::shared_ptr<const MappedFrame> frame = maps.frame(static_cast<int>(index));
        const MappedFrame& f = *frame;
        const InverseDiskMap inverse(f.map);
        const std::vector<Vec2> points = frames.registrations.sample_points(static_cast<int>(index), grid.nodes);
        const RigidPose to_face = selection[index].pose.inverse();
        std::vector<Vec3> positions = resample_positions(inverse, points);
        for (Vec3& p : positions) p = to_face.apply(p);
        local.put(static_cast<size_t>(k), std::move(positions));
        const auto own = static_cast<size_t>(k) - own_offset;  // wraps past keys for a margin's keyframe
        if (own >= keys) return;
        stored->put_hole_level(own, store_holes ? hole_level(f.prepared, f.map, points) : std::vector<double>());
        if (!store_texture) {
          stored->put_texture(own, Image());
        } else if (textures_from) {
          stored->put_texture(own, Image(*textures_from->texture(own)));
        } else {
          stored->put_texture(own, sampler.frame_texture(f, static_cast<int>(index), texture_size));
        }
      },
      [&](int done, int total) {
        if (settings.progress) settings.progress("keyframes", done, total);
      });
  if (settings.keyframe_fit) {
    // The keyframes' surfaces replaced by the spline's least-squares fit to every frame.
    KeyframeFitInput fit;
    fit.keyframes = fitted;
    for (const CaptureFrame& f : capture.frames) fit.times.push_back(f.time);
    for (int k : fitted) fit.poses.push_back(selection[static_cast<size_t>(k)].pose);
    fit.spline = settings.spline;
    fit.pose_centre = frames.pose_centre;
    fit.weight = settings.keyframe_fit_weight;
    fit.noise_factor = settings.keyframe_fit_noise;
    fit.threads = settings.threads;
    fit.surface = [&](int i, std::span<const Vec2> nodes) { return sampler.sample_surface(i, nodes); };
    fit.noise = [&](int i) { return frames.selection.noise_at(i); };
    fit_keyframes(fit, geometry, local);
  }
  parallel_for(static_cast<int>(keys), settings.threads,
               [&](int k) { folds[static_cast<size_t>(k)] = folded_nodes(geometry, *local.get(own_offset + static_cast<size_t>(k))); });
  std::vector<int32_t> own_folds;
  for (const auto& f : folds) own_folds.insert(own_folds.end(), f.begin(), f.end());
  std::sort(own_folds.begin(), own_folds.end());
  own_folds.erase(std::unique(own_folds.begin(), own_folds.end()), own_folds.end());
  // A segment codes with the fixed nodes of the whole capture, which its folds are part of.
  const std::vector<int32_t>& fixed = segment && segment->fixed_nodes ? *segment->fixed_nodes : own_folds;
  if (!std::includes(fixed.begin(), fixed.end(), own_folds.begin(), own_folds.end())) {
    throw Error(ErrorCode::kInvalidArgument, "build: the fixed nodes given miss folds of this segment's keyframes");
  }
  report.keyframe_folds = own_folds;
  parallel_for(static_cast<int>(keys), settings.threads, [&](int k) {
    stored->put_fields(static_cast<size_t>(k),
                       keyframe_fields(geometry, *local.get(own_offset + static_cast<size_t>(k)), stored->shape().representation, fixed));
  });
  report.peak_keyframes_in_memory = std::max(report.peak_keyframes_in_memory, local.peak_held());
  report.keyframes_spilled_bytes += local.spilled_bytes();
  report.seconds_keyframes = seconds_since(start);
  if (kept) *kept = {surfaces, fixed};
  return stored;
}

}  // namespace facemorph
