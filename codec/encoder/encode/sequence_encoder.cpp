// The encoder: every frame mapped and registered, keyframes chosen, keyframes stored on G.
#include "facemorph/encoder/sequence_encoder.hpp"

#include "facemorph/encoder/residual_fit.hpp"
#include "facemorph/encoder/selection_store.hpp"
#include "facemorph/encoder/stored_sequence.hpp"

#include "codec/encoder/encode/spill_bytes.hpp"
#include "codec/encoder/keyframes/banded_cholesky.hpp"

#include "codec/decoder/geometry/elementary.hpp"
#include "facemorph/meshkit/distance.hpp"
#include "facemorph/encoder/face_orientation.hpp"
#include "facemorph/encoder/frame.hpp"
#include "facemorph/encoder/frame_pipeline.hpp"
#include "facemorph/encoder/image_io.hpp"
#include "facemorph/encoder/resample.hpp"
#include "facemorph/error.hpp"
#include "facemorph/meshkit/mesh_io.hpp"
#include "facemorph/parallel.hpp"
#include "facemorph/pose.hpp"
#include "facemorph/spline.hpp"

#include <Eigen/Cholesky>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <functional>
#include <chrono>
#include <deque>
#include <limits>
#include <map>
#include <numbers>
#include <cmath>
#include <numeric>
#include <optional>

namespace facemorph {

namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// --grid auto: the sizes tried, and the resampling floor a keyframe may add (spec/method.md §7.6).
// The floor falls as 1/N², so steps of ~1.2-1.5 in N give the rule steps of at most ~2.2 in floor.
constexpr int kGridCandidates[] = {33, 41, 49, 57, 65, 81, 97, 129, 193, 257};
constexpr double kGridFloorTarget = 2e-4;
constexpr double kGridNoiseShare = 1.0;
// Half the error the spline makes between keyframes: where bytes spent on a finer grid and on more
// keyframes buy the same error (equal slopes; measured on Medusa, spec/method.md §7.6).
constexpr double kGridErrorShare = 0.5;

// The mean of the selection's predicted errors between keyframes (fraction of the diagonal); 0 when
// none was predicted (every frame a keyframe).
double mean_predicted_error(const KeyframeSelection& chosen) {
  double sum = 0;
  int count = 0;
  for (double e : chosen.predicted_error) {
    if (e > 0) {
      sum += e;
      ++count;
    }
  }
  return count == 0 ? 0.0 : sum / count;
}

double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double length2 = ab.squaredNorm();
  const double s = length2 > 0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + s * ab)).norm();
}

// Crossing-number test of a point against a closed polygon.
bool inside_polygon(const Vec2& p, const std::vector<Vec2>& polygon) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Vec2 &a = polygon[i], &b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) && p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) inside = !inside;
  }
  return inside;
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
    const Vec2 a = surface.uvs[static_cast<size_t>(f[0])], b = surface.uvs[static_cast<size_t>(f[1])], c = surface.uvs[static_cast<size_t>(f[2])];
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

// What of frame k its neighbours' motion does not explain: its surface (selection grid, face frame)
// against the cubic through the four nearest other frames in time (k−2, k−1, k+1, k+2; one-sided
// at the ends), RMS by area, over the stencil's noise gain √(1 + Σ w²). For independent noise of
// RMS σ per frame this is σ; smooth motion leaks in only through its fourth derivative (1.7% of a
// sinusoid of 11 frames a period). Infinity with fewer than 5 frames.
double frame_noise(const SelectionFrames& frames, const std::vector<double>& node_weights, int k) {
  const int count = static_cast<int>(frames.size());
  if (count < 5) return std::numeric_limits<double>::infinity();
  const int first = std::clamp(k - 2, 0, count - 5);
  std::vector<int> others;
  for (int j = first; j < first + 5; ++j) {
    if (j != k) others.push_back(j);
  }
  const auto time = [&](int j) { return frames.outline(static_cast<size_t>(j)).time; };
  const double t = time(k);
  std::vector<double> w;
  double gain = 1;
  std::vector<std::shared_ptr<const SelectionFrame>> neighbours;  // their samples, held while used
  for (int a : others) {
    double l = 1;
    for (int b : others) {
      if (b != a) l *= (t - time(b)) / (time(a) - time(b));
    }
    w.push_back(l);
    gain += l * l;
    neighbours.push_back(frames.sampled(static_cast<size_t>(a)));
  }
  const std::shared_ptr<const SelectionFrame> frame = frames.sampled(static_cast<size_t>(k));
  double sum = 0, total = 0;
  for (size_t v = 0; v < node_weights.size(); ++v) {
    Vec3 r = frame->local_at(v);
    for (size_t i = 0; i < others.size(); ++i) r -= w[i] * neighbours[i]->local_at(v);
    sum += node_weights[v] * r.squaredNorm();
    total += node_weights[v];
  }
  return std::sqrt(sum / std::max(total, 1e-300) / gain);
}

}  // namespace

DiskLandmarks disk_landmarks(const Capture& capture, size_t reference, const DiskMap& reference_map, size_t frame, const DiskMap& frame_map) {
  return disk_landmarks(capture.landmark_names, capture.landmarks[reference], reference_map, capture.landmarks[frame], frame_map);
}

DiskLandmarks disk_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const DiskMap& reference_map,
                             const std::vector<Vec3>& frame, const DiskMap& frame_map) {
  DiskLandmarks landmarks;
  const PointToMesh on_reference(reference_map.surface), on_frame(frame_map.surface);
  for (size_t l = 0; l < names.size(); ++l) {
    const Vec3 &p = reference[l], &q = frame[l];
    if (!p.allFinite() || !q.allFinite()) continue;
    Vec2 wp = disk_point(reference_map, on_reference.closest(p)), wq = disk_point(frame_map, on_frame.closest(q));
    const bool rim = names[l].rfind("rim_", 0) == 0;
    if (rim) {
      // A marker on the rim interpolates along a boundary chord: put it on the circle.
      wp.normalize();
      wq.normalize();
    }
    landmarks.reference.push_back(wp);
    landmarks.frame.push_back(wq);
    landmarks.on_rim.push_back(rim ? 1 : 0);
  }
  return landmarks;
}

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
      for (size_t k = 0; k < outline.size(); ++k) distance = std::min(distance, distance_to_segment(p, outline[k], outline[(k + 1) % outline.size()]));
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

std::unique_ptr<SpilledItems<std::vector<Vec3>>> SequenceEncoder::make_landmark_store() const {
  return std::make_unique<SpilledItems<std::vector<Vec3>>>(
      options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory, "the frames' landmarks", "landmarks of frame",
      [](const std::vector<Vec3>& points) {
        spill::Writer w;
        w.array(points);
        return w.take();
      },
      [](const char* bytes, size_t size) {
        spill::Reader r(bytes, size, "the frames' landmarks: a stored frame");
        std::vector<Vec3> points = r.array<Vec3>();
        if (!r.done()) throw Error(ErrorCode::kInternal, "the frames' landmarks: a stored frame has bytes left over");
        return points;
      });
}

SequenceEncoder::SequenceEncoder(Capture capture, EncodeOptions options)
    : capture_(std::move(capture)), options_(std::move(options)), store_(std::make_unique<FrameStore>()) {
  const int count = frame_count();
  if (count == 0) throw Error(ErrorCode::kInvalidArgument, "the capture has no frames");
  if (capture_.landmarks.empty()) capture_.landmarks.resize(capture_.frames.size(), std::vector<Vec3>(capture_.landmark_names.size(), Vec3::Constant(std::nan(""))));
  if (capture_.landmarks.size() != capture_.frames.size()) {
    throw Error(ErrorCode::kInvalidArgument, "the capture has landmarks for " + std::to_string(capture_.landmarks.size()) + " of its " +
                                                 std::to_string(count) + " frames");
  }
  // The landmarks leave the capture for a store: 1.8 kB a frame of ICT's 74, which kept in memory
  // grew with the capture for the whole encode.
  landmarks_ = make_landmark_store();
  landmarks_->reset(capture_.landmarks.size());
  for (size_t i = 0; i < capture_.landmarks.size(); ++i) landmarks_->put(i, std::move(capture_.landmarks[i]));
  capture_.landmarks = {};
  source_index_.resize(static_cast<size_t>(count));
  std::iota(source_index_.begin(), source_index_.end(), 0);
  first_time_ = capture_.frames.front().time;
  last_time_ = capture_.frames.back().time;
  given_reference_ = options_.reference_frame;
  check_options(count);
}

void SequenceEncoder::check_options(int count) const {
  if (!(options_.landmark_tolerance > 0)) throw Error(ErrorCode::kInvalidArgument, "the landmark tolerance must be positive");
  if (options_.reference_frame < 0 || options_.reference_frame >= count) {
    throw Error(ErrorCode::kInvalidArgument, "reference frame " + std::to_string(options_.reference_frame) + " is not a frame of the capture");
  }
  if (!(options_.keyframe_fraction > 0 && options_.keyframe_fraction <= 1) && !(options_.max_error > 0)) {
    throw Error(ErrorCode::kInvalidArgument, "the keyframe budget must be in (0, 100%]");
  }
  if (!(options_.keyframe_error_bound >= 0)) throw Error(ErrorCode::kInvalidArgument, "the keyframe error bound must be >= 0");
  if (!(options_.keyframe_fit_weight >= 0) || !(options_.keyframe_fit_noise >= 0)) {
    throw Error(ErrorCode::kInvalidArgument, "the keyframe fit's weight and noise factor must be >= 0");
  }
  if (options_.grid != 0 && (options_.grid < kMinGridSize || options_.grid > kMaxGridSize)) {
    throw Error(ErrorCode::kInvalidArgument, "grid size N must be 0 (auto) or in [" + std::to_string(kMinGridSize) + ", " + std::to_string(kMaxGridSize) + "]");
  }
  const double strength = options_.density_equalising.strength;
  if (!(strength >= 0 && strength <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "density-equalising strength must be in [0, 1], not " + std::to_string(strength));
  }
  const double radial = options_.density_equalising.radial;
  if (radial != kAutoRadial && !(radial >= 0 && radial <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "radial-equalising strength must be auto or in [0, 1], not " + std::to_string(radial));
  }
  // Two reparametrisations of the disk; the flow, asked for, turns the radial map off, so asking for
  // both would silently drop one (a whole head then fails to converge with nothing saying why).
  if (radial != kAutoRadial && radial > 0 && strength > 0) {
    throw Error(ErrorCode::kInvalidArgument, "radial equalising (" + std::to_string(radial) + ") and density equalising (" + std::to_string(strength) +
                                                 ") are two reparametrisations of the disk: ask for one");
  }
  if (options_.texture && options_.texture_size != 0 && (options_.texture_size < 16 || options_.texture_size > 16383)) {
    throw Error(ErrorCode::kInvalidArgument, "texture size must be 0 (auto) or in [16, 16383]");
  }
  if (options_.texture_quality != kAutoTextureQuality && (options_.texture_quality < 0 || options_.texture_quality > 101)) {
    throw Error(ErrorCode::kInvalidArgument, "texture quality must be auto or in [0, 101], not " + std::to_string(options_.texture_quality));
  }
  const TextureQualityOptions& coding = options_.texture_coding;
  if (!(coding.interpolation_share > 0) || !(coding.min_psnr <= coding.max_psnr) || coding.fallback_quality < 0 || coding.fallback_quality > 101) {
    throw Error(ErrorCode::kInvalidArgument, "texture coding: the interpolation share must be positive, min_psnr at most max_psnr, the fallback quality in [0, 101]");
  }
}

void SequenceEncoder::progress(const std::string& stage, int done, int total) const {
  if (options_.progress) options_.progress(stage, done, total);
}

namespace {

std::string length_text(double value, const std::string& units) {
  char text[64];
  std::snprintf(text, sizeof text, "%.3g %s", value, units.c_str());
  return text;
}

}  // namespace

SequenceEncoder::FrameFailure SequenceEncoder::failure_of(const Error& e, const std::string& name) {
  // Stages name their frame; the report names it once.
  std::string reason = e.what();
  if (reason.rfind(name + ": ", 0) == 0) reason.erase(0, name.size() + 2);
  return {e.code(), reason};
}

bool SequenceEncoder::ignore_far_landmarks(const TriangleMesh& mesh, size_t index, std::vector<Vec3>& points, std::vector<std::string>& warnings) const {
  // A capture without landmarks (or a frame without any) needs no closest-point structure.
  if (mesh.positions.empty() || mesh.faces.empty() || std::none_of(points.begin(), points.end(), [](const Vec3& p) { return p.allFinite(); })) return false;
  const PointToMesh surface(mesh);
  const double diagonal = bounding_box_diagonal(mesh.positions);
  const std::string& name = capture_.frames[index].mesh.string();
  bool ignored = false;
  for (size_t l = 0; l < capture_.landmark_names.size(); ++l) {
    Vec3& point = points[l];
    if (!point.allFinite()) continue;
    const double distance = surface.distance(point);
    if (distance <= options_.landmark_tolerance * diagonal) continue;
    char share[32];
    std::snprintf(share, sizeof share, "%.3g%%", 100 * distance / diagonal);
    const std::string what = "landmark '" + capture_.landmark_names[l] + "' lies " + length_text(distance, capture_.units) + " (" + share +
                             " of the frame's diagonal) off its surface, farther than the " + length_text(100 * options_.landmark_tolerance, "%") +
                             " allowed";
    if (options_.strict) throw Error(ErrorCode::kInvalidArgument, name + ": " + what);
    warnings.push_back(name + ": " + what + "; ignored");
    point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    ignored = true;
  }
  return ignored;
}

void SequenceEncoder::drop_frames(const std::vector<FrameFailure>& failures) {
  std::vector<size_t> kept;
  for (size_t i = 0; i < failures.size(); ++i) {
    if (failures[i].code == ErrorCode::kOk) {
      kept.push_back(i);
      continue;
    }
    report_.dropped.push_back({source_index_[i], capture_.frames[i].mesh.string(), capture_.frames[i].time, failures[i].reason});
    // Dropped at registration, the frame was mapped: its summary still counts in what was found.
    if (summaries_.size() == failures.size() && !summaries_[i].name.empty()) dropped_summaries_[source_index_[i]] = summaries_[i];
  }
  if (kept.size() == failures.size()) return;
  if (kept.empty()) {
    const DroppedFrame& first = report_.dropped.front();
    const auto it = std::find_if(failures.begin(), failures.end(), [](const FrameFailure& f) { return f.code != ErrorCode::kOk; });
    throw Error(it->code, "no frame of the capture could be encoded (" + std::to_string(failures.size()) + " dropped); the first, " +
                              first.name + ": " + first.reason);
  }
  // The reference moves to the nearest frame kept (the earlier of two as near).
  const auto reference = static_cast<size_t>(options_.reference_frame);
  size_t new_reference = 0;
  for (size_t k = 0; k < kept.size(); ++k) {
    const double d = std::abs(capture_.frames[kept[k]].time - capture_.frames[reference].time);
    if (d < std::abs(capture_.frames[kept[new_reference]].time - capture_.frames[reference].time)) new_reference = k;
  }
  if (kept[new_reference] != reference) {
    report_.warnings.push_back(capture_.frames[reference].mesh.string() + ": the reference frame was dropped; " +
                               capture_.frames[kept[new_reference]].mesh.string() + " is the reference instead");
  }
  options_.reference_frame = static_cast<int>(new_reference);
  auto compact = [&](auto& items) {
    if (items.size() != failures.size()) return;
    std::remove_reference_t<decltype(items)> out;
    out.reserve(kept.size());
    for (size_t i : kept) out.push_back(std::move(items[i]));
    items = std::move(out);
  };
  compact(capture_.frames);
  if (landmarks_->size() == failures.size()) landmarks_->keep(kept);
  compact(source_index_);
  compact(summaries_);
  if (store_ && store_->size() == failures.size()) store_->keep(kept);
  if (pinned_index_ >= 0) {
    // The pinned frame keeps its pin under its new index (a dropped one loses it).
    const auto it = std::find(kept.begin(), kept.end(), static_cast<size_t>(pinned_index_));
    pinned_index_ = it == kept.end() ? -1 : static_cast<int>(it - kept.begin());
    if (pinned_index_ < 0) pinned_.reset();
  }
  compact(textures_);
  compact(without_interior_);
  if (registrations_ && registrations_->size() == failures.size()) registrations_->keep(kept);
}

std::optional<Vec3> find_vertical_hint(const Capture& capture, int reference, bool largest_component,
                                       const std::function<std::vector<Vec3>(size_t)>& landmarks) {
  // The first frame from the reference on that lacks its pose landmarks and whose own surface says
  // clearly which way is up: its up direction settles the frames whose surfaces do not.
  const size_t count = capture.frames.size();
  for (size_t step = 0; step < count; ++step) {
    const size_t index = (static_cast<size_t>(reference) + step) % count;
    const FrameLandmarks given = frame_landmarks(capture.landmark_names, landmarks(index));
    if (given.centre && given.up) continue;
    try {
      PrepareOptions prepare;
      prepare.keep_largest_component = largest_component;
      const PreparedFrame p = prepare_frame(read_mesh(capture.mesh_path(index), {.allow_missing_texture = true}), capture.frames[index].mesh.string(), prepare);
      return find_face(p.mesh, nullptr, capture.frames[index].mesh.string()).vertical;
    } catch (const Error&) {
      // This frame does not say; the next may. Its own mapping reports why.
    }
  }
  return std::nullopt;
}

const char* EncodeReport::main_orientation_method() const {
  const auto most = std::max_element(orientation_methods.begin(), orientation_methods.end());
  return face_finding_method_name(static_cast<FaceFindingMethod>(most - orientation_methods.begin()));
}

void SequenceEncoder::count_found_landmarks(const FrameSummary& f, bool given_rim) {
  if (f.found) {
    ++report_.orientation_found;
    report_.weakest_up_evidence = std::min(report_.weakest_up_evidence, f.found->up_evidence);
    report_.up_from_hint += f.found->up_from_hint;
    report_.worst_mirror_error = std::max(report_.worst_mirror_error, f.found->mirror_error);
    ++report_.orientation_methods[static_cast<size_t>(f.found->method)];
    report_.lowest_face_confidence = std::min(report_.lowest_face_confidence, f.found->confidence);
  }
  if (!given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers)) report_.rim_markers_found = true;
}

void SequenceEncoder::adopt_found_landmarks() {
  auto name_index = [&](const std::string& name) {
    int index = capture_.landmark_index(name);
    if (index >= 0) return static_cast<size_t>(index);
    capture_.landmark_names.push_back(name);
    return capture_.landmark_names.size() - 1;
  };
  const bool given_rim = std::any_of(capture_.landmark_names.begin(), capture_.landmark_names.end(),
                                     [](const std::string& name) { return name.rfind("rim_", 0) == 0; });
  // No rim markers given: each normalised frame's rim points at the same disk angles.
  auto takes_rim = [&](const FrameSummary& f) { return !given_rim && f.found_rim.size() == static_cast<size_t>(kFoundRimMarkers); };
  // The names first, in the order they always came (the pose's, then the rim's): the registration
  // takes the landmarks in the names' order.
  size_t tip = 0, up = 0;
  if (std::any_of(summaries_.begin(), summaries_.end(), [](const FrameSummary& f) { return f.found.has_value(); })) {
    tip = name_index("nose_tip");
    up = name_index("nose_bridge");
  }
  std::vector<size_t> rim;
  if (std::any_of(summaries_.begin(), summaries_.end(), takes_rim)) {
    for (int k = 0; k < kFoundRimMarkers; ++k) rim.push_back(name_index("rim_" + std::to_string(k)));
  }
  // Then each frame's points read, set and stored once.
  for (size_t i = 0; i < summaries_.size(); ++i) {
    const FrameSummary& f = summaries_[i];
    if (!f.found && !takes_rim(f)) continue;
    std::vector<Vec3> points = landmarks(static_cast<int>(i));
    if (f.found) {
      points[tip] = f.found->nose_tip;
      points[up] = f.found->up;
    }
    if (takes_rim(f)) {
      for (size_t k = 0; k < rim.size(); ++k) points[rim[k]] = f.found_rim[k];
    }
    count_found_landmarks(f, given_rim);
    landmarks_->put(i, std::move(points));
  }
}

void SequenceEncoder::map_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  // Each frame is read, mapped, summarised and put in the store by one thread, then released: the
  // maps in memory at once are one per thread (frame_store.hpp).
  store_ = std::make_unique<FrameStore>(options_.spill_frames ? FrameStore::Mode::kSpill : FrameStore::Mode::kMemory);
  store_->reset(static_cast<size_t>(count));
  pinned_index_ = -1;
  pinned_.reset();
  summaries_.assign(static_cast<size_t>(count), {});
  textures_.assign(static_cast<size_t>(count), {});
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<std::vector<std::string>> warnings(static_cast<size_t>(count));
  std::optional<Vec3> vertical_hint = vertical_hint_;
  if (options_.find_landmarks && !vertical_hint_set_) {
    const FrameStore::Hold held = store_->hold();  // the frame being prepared
    vertical_hint = find_vertical_hint(capture_, options_.reference_frame, options_.largest_component,
                                       [&](size_t i) { return landmarks(static_cast<int>(i)); });
  }
  if (!options_.find_landmarks) vertical_hint.reset();
  parallel_for(
      count, options_.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        const std::string name = capture_.frames[index].mesh.string();
        const FrameStore::Hold held = store_->hold();
        MappedFrame mapped;
        // The frame's landmarks from their store and back: outside the try, as the map's put below
        // (a full disk is no fault of the frame).
        std::vector<Vec3> points = this->landmarks(i);
        bool ignored = false;
        try {
          const TriangleMesh mesh = read_mesh(capture_.mesh_path(index), {.allow_missing_texture = !options_.texture});
          ignored = ignore_far_landmarks(mesh, index, points, warnings[index]);
          const FrameLandmarks landmarks = frame_landmarks(capture_.landmark_names, points);
          if ((!landmarks.centre || !landmarks.up) && !options_.find_landmarks) {
            throw Error(ErrorCode::kInvalidArgument, name + ": frame " + std::to_string(source_index_[index]) +
                                                         " lacks the landmarks nose_tip and nose_bridge (or between_eyes) that fix its disk's pose");
          }
          textures_[index] = mesh.texture;
          MapFrameOptions map_options;
          map_options.keep_largest_component = options_.largest_component;
          map_options.repair_non_manifold = !options_.strict;  // --strict refuses what repairs would change
          map_options.conformal = options_.conformal;
          map_options.find_orientation = options_.find_landmarks;
          map_options.vertical_hint = vertical_hint;
          mapped = map_frame(mesh, name, landmarks, map_options);
        } catch (const Error& e) {
          if (options_.strict) throw;
          failures[index] = failure_of(e, name);
          return;
        }
        FrameSummary& summary = summaries_[index];
        summary.name = mapped.name;
        summary.vertices = mapped.prepared.mesh.vertex_count();
        summary.holes_filled = static_cast<int>(mapped.prepared.report.holes.size());
        summary.repair = mapped.prepared.report.summary();
        summary.repair_totals = mapped.prepared.report.totals();
        summary.conformal_method = mapped.map.report.method;
        summary.conformal_fallback_reason = mapped.map.report.fallback_reason;
        summary.has_uvs = mapped.map.surface.has_uvs();
        summary.has_colours = mapped.map.surface.has_colours();
        summary.found = mapped.found;
        summary.found_rim = mapped.found_rim;
        // Outside the try: a map the store cannot write ends the encode (it is no fault of the frame).
        if (ignored) landmarks_->put(index, std::move(points));
        store_->put(index, std::move(mapped));
      },
      [&](int done, int total) { progress("mapping", done, total); });
  for (size_t i = 0; i < warnings.size(); ++i) {
    report_.warnings.insert(report_.warnings.end(), warnings[i].begin(), warnings[i].end());
    if (!warnings[i].empty()) warnings_by_frame_[source_index_[i]] = std::move(warnings[i]);
  }
  drop_frames(failures);
  adopt_found_landmarks();
  pin_reference();
  report_.reference_frame = source_index_[static_cast<size_t>(options_.reference_frame)];
  report_.seconds_mapping = seconds_since(start);
}

std::vector<TrackedPoints> SequenceEncoder::track_frames() {
  const auto start = std::chrono::steady_clock::now();
  const auto count = static_cast<size_t>(frame_count());
  const auto reference = static_cast<size_t>(options_.reference_frame);
  report_.tracked_frames = 0;
  std::vector<TrackedPoints> tracked;
  // Which frames share too few interior landmarks with the reference, the reference's read once.
  const std::vector<Vec3> reference_points = landmarks(static_cast<int>(reference));
  std::vector<char> needs(count, 0);
  for (size_t i = 0; i < count; ++i) needs[i] = i != reference && needs_tracked_points(capture_.landmark_names, reference_points, landmarks(static_cast<int>(i)));
  const bool needed = std::find(needs.begin(), needs.end(), 1) != needs.end();
  if (!options_.track_landmarks || !needed) return tracked;
  const int size = options_.tracking.image_size;
  // Each frame's map read back from the store while its images are drawn (frame() is thread-safe).
  tracked = track_sequence(
      count, reference, [&](size_t i) { return disk_features(this->frame(static_cast<int>(i))->map, size); }, options_.tracking, options_.threads);
  std::vector<double> round_trips;
  double kept = 0;
  report_.tracked_points_fewest = std::numeric_limits<int>::max();
  for (size_t i = 0; i < count; ++i) {
    if (!needs[i]) continue;
    ++report_.tracked_frames;
    kept += static_cast<double>(tracked[i].reference.size());
    report_.tracked_points_fewest = std::min(report_.tracked_points_fewest, static_cast<int>(tracked[i].reference.size()));
    round_trips.insert(round_trips.end(), tracked[i].round_trip.begin(), tracked[i].round_trip.end());
  }
  report_.tracking_grid_points = tracked[reference].tried;
  report_.tracked_points_mean = report_.tracked_frames > 0 ? kept / report_.tracked_frames : 0.0;
  if (report_.tracked_frames == 0) report_.tracked_points_fewest = 0;
  std::sort(round_trips.begin(), round_trips.end());
  if (!round_trips.empty()) {
    report_.tracked_round_trip_median = round_trips[round_trips.size() / 2];
    report_.tracked_round_trip_p90 = round_trips[round_trips.size() * 9 / 10];
  }
  report_.seconds_tracking = seconds_since(start);
  return tracked;
}

void SequenceEncoder::register_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  const auto reference = static_cast<size_t>(options_.reference_frame);
  const std::shared_ptr<const MappedFrame> reference_frame = pin_reference();
  set_reference_geometry(*reference_frame, landmarks(static_cast<int>(reference)));
  registrations_ = std::make_unique<RegistrationStore>(options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
  registrations_->reset(static_cast<size_t>(count), geodesic_frame_ ? geodesic_frame_->partition : nullptr);
  const std::vector<TrackedPoints> tracked = track_frames();
  const std::vector<Vec3> reference_points = landmarks(static_cast<int>(reference));
  std::vector<FrameFailure> failures(static_cast<size_t>(count));
  std::vector<char>& without_interior = without_interior_;
  without_interior.assign(static_cast<size_t>(count), 0);
  parallel_for(
      count, options_.threads,
      [&](int i) {
        const auto index = static_cast<size_t>(i);
        // What the stores give back and take is no fault of the frame (a full disk): outside the try,
        // so that it ends the encode instead of dropping frames.
        const std::shared_ptr<const MappedFrame> frame = this->frame(i);
        const std::vector<Vec3> frame_points = this->landmarks(i);
        const bool needs = needs_tracked_points(capture_.landmark_names, reference_points, frame_points);
        const std::string& name = frame->name;
        DiskRegistration registered;
        try {
          // The frame's landmarks on the two disks, made here and dropped once registered (kept, they
          // were 2 kB a frame for the whole encode).
          DiskLandmarks landmarks = facemorph::disk_landmarks(capture_.landmark_names, reference_points, reference_frame->map, frame_points, frame->map);
          const bool took_tracked = !tracked.empty() && needs && !tracked[index].reference.empty();
          if (took_tracked) add_tracked_points(landmarks, tracked[index]);
          without_interior[index] = !took_tracked && index != reference && needs;
          if (landmarks.reference.size() < 3) {
            throw Error(ErrorCode::kInvalidArgument, name + ": frame " + std::to_string(source_index_[index]) + " shares only " +
                                                         std::to_string(landmarks.reference.size()) + " landmarks with the reference frame (3 needed)");
          }
          try {
            // A frame registered through tracked points: a smoothing thin plate, not one through every point.
            RegistrationOptions registration = options_.registration;
            if (took_tracked) registration.smoothing = std::max(registration.smoothing, options_.tracking.registration_smoothing);
            registered = register_disks(landmarks, registration, geodesic_frame_.get());
          } catch (const Error& e) {
            throw Error(e.code(), name + ": registration: " + e.what());
          }
        } catch (const Error& e) {
          // The reference cannot be dropped here: every other frame is already registered to it.
          if (options_.strict || index == reference) throw;
          failures[index] = failure_of(e, name);
          return;
        }
        registrations_->put(index, std::move(registered));
      },
      [&](int done, int total) { progress("registering", done, total); });
  // Over the frames kept (a frame dropped here is registered neither way).
  report_.frames_without_interior_landmarks = 0;
  for (size_t i = 0; i < without_interior.size(); ++i) report_.frames_without_interior_landmarks += failures[i].code == ErrorCode::kOk && without_interior[i];
  auto_representation_ = Representation::kHLT;  // until choose_representation measures otherwise
  report_.representation = representation();
  drop_frames(failures);
  std::sort(report_.dropped.begin(), report_.dropped.end(), [](const DroppedFrame& a, const DroppedFrame& b) { return a.index < b.index; });
  report_.seconds_registration = seconds_since(start);
}

void SequenceEncoder::set_reference_geometry(const MappedFrame& reference, const std::vector<Vec3>& points) {
  const DensityEqualisingOptions& equalising = options_.density_equalising;
  const double half = half_area_radius(reference.map);
  double radial = equalising.radial == kAutoRadial ? (half < kCrowdedHalfAreaRadius ? 1.0 : 0.0) : equalising.radial;
  if (equalising.strength > 0) radial = 0;  // the flow, as asked
  reparametrisation_ = radial > 0 ? DiskReparametrisation::radial(reference.map, radial) : DiskReparametrisation(reference.map, equalising);
  report_.density_equalising = reparametrisation_.report();
  report_.density_equalising.half_area_radius_before = half;
  report_.radial_equalising = radial;
  geodesic_frame_.reset();
  if (options_.registration.method == RegistrationMethod::kFrame) {
    // The reference's frame, once: its landmarks on its own disk are the graph's points, and every
    // frame's Φ maps that frame's partition (paper §5). Frames lacking a landmark simply leave f̄
    // unconstrained there.
    const DiskLandmarks own = facemorph::disk_landmarks(capture_.landmark_names, points, reference.map, points, reference.map);
    try {
      geodesic_frame_ = std::make_shared<const GeodesicFrame>(make_geodesic_frame(reference.map, own.reference, own.on_rim));
    } catch (const Error& e) {
      throw Error(e.code(), reference.name + ": the reference frame's geodesic frame: " + e.what());
    }
  }
}

std::vector<Vec3> SequenceEncoder::landmarks(int i) const {
  std::vector<Vec3> points = *landmarks_->get(static_cast<size_t>(i));
  // Names adopted after the frame's points were stored (adopt_found_landmarks) it lacks.
  points.resize(capture_.landmark_names.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  return points;
}

DiskLandmarks SequenceEncoder::frame_disk_landmarks(int i) const {
  const int reference = options_.reference_frame;
  return facemorph::disk_landmarks(capture_.landmark_names, landmarks(reference), frame(reference)->map, landmarks(i), frame(i)->map);
}

std::shared_ptr<const DiskRegistration> SequenceEncoder::registration(int i) const {
  if (!registrations_) throw Error(ErrorCode::kInternal, "the frames are not registered yet");
  return registrations_->get(static_cast<size_t>(i));
}

std::vector<Vec2> SequenceEncoder::sample_points(int i, std::span<const Vec2> nodes) const {
  std::vector<Vec2> points = reparametrisation_(nodes);
  const std::shared_ptr<const DiskRegistration> f = registration(i);
  for (Vec2& p : points) p = (*f)(p);
  return points;
}

std::shared_ptr<const MappedFrame> SequenceEncoder::frame(int i) const {
  if (i == pinned_index_) return pinned_;
  return store_->get(static_cast<size_t>(i));
}

std::shared_ptr<const MappedFrame> SequenceEncoder::pin_reference() {
  if (pinned_index_ != options_.reference_frame) {
    pinned_.reset();  // first: the old one need not be held beside the new
    pinned_ = store_->get(static_cast<size_t>(options_.reference_frame));
    pinned_index_ = options_.reference_frame;
  }
  return pinned_;
}

bool SequenceEncoder::has_texture(int i) const {
  const auto index = static_cast<size_t>(i);
  const FrameSummary& f = summaries_[index];
  return (!textures_[index].empty() && f.has_uvs) || f.has_colours;
}

Image SequenceEncoder::frame_texture(int i, int size) const { return frame_texture(*frame(i), i, size); }

Image SequenceEncoder::frame_texture(const MappedFrame& f, int i, int size) const {
  Image image;
  const std::optional<TextureSource> source = frame_texture_source(f.map, textures_[static_cast<size_t>(i)], image);
  if (!source) throw Error(ErrorCode::kMissingTexture, f.name + ": the frame has neither a texture image with UVs nor vertex colours");
  return resample_texture(InverseDiskMap(f.map), *source, size, sampler(i));
}

std::vector<Vec3> SequenceEncoder::sample_surface(int i, std::span<const Vec2> nodes) const { return sample_surface(*frame(i), i, nodes); }

std::vector<Vec3> SequenceEncoder::sample_surface(const MappedFrame& frame, int i, std::span<const Vec2> nodes) const {
  return resample_positions(InverseDiskMap(frame.map), sample_points(i, nodes));
}

GridGeometry SequenceEncoder::set_selection_weights() {
  GridGeometry geometry(make_disk_grid(kSelectionGrid));
  const auto nodes = static_cast<size_t>(geometry.interior_count());
  node_weights_.resize(nodes);
  for (size_t v = 0; v < nodes; ++v) node_weights_[v] = geometry.mass()[static_cast<Eigen::Index>(v)];
  return geometry;
}

void SequenceEncoder::sample_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  const auto reference = static_cast<size_t>(options_.reference_frame);
  const GridGeometry geometry = set_selection_weights();
  const size_t nodes = node_weights_.size();
  selection_.assign(static_cast<size_t>(count), {});
  samples_.reset();  // the samples of the frames as sampled before, if any
  samples_ = std::make_unique<SelectionStore>(selection_, options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory, kSelectionCacheBytes);
  samples_released_ = false;
  released_noise_.clear();
  // A frame's registered surface on the nodes, in the capture frame, and its normals.
  auto sample = [&](size_t index, std::vector<Eigen::Vector3f>& normal) {
    SelectionFrame& s = selection_[index];
    s.time = capture_.frames[index].time;
    const std::shared_ptr<const MappedFrame> frame = this->frame(static_cast<int>(index));
    s.diagonal = bounding_box_diagonal(frame->map.surface.positions);
    std::vector<Vec3> all = sample_surface(*frame, static_cast<int>(index), geometry.grid().nodes);
    std::vector<Vec3> tu, tv, normals;
    geometry.frames(all, tu, tv, normals);
    normal.resize(normals.size());
    for (size_t v = 0; v < normals.size(); ++v) normal[v] = normals[v].cast<float>();
    all.resize(nodes);
    return all;
  };
  std::vector<Eigen::Vector3f> reference_normal;
  const std::vector<Vec3> reference_world = sample(reference, reference_normal);
  parallel_for(count, options_.threads, [&](int i) {
    const auto index = static_cast<size_t>(i);
    std::vector<Eigen::Vector3f> normal;
    const std::vector<Vec3> world = index == reference ? reference_world : sample(index, normal);
    if (index == reference) normal = reference_normal;
    // The head pose: the rigid motion taking the reference's registered surface onto this frame's,
    // fitted over every node (weighted by area). The reference's frame is the face frame.
    SelectionFrame& s = selection_[index];
    s.pose = index == reference ? RigidPose{} : fit_rigid_pose(reference_world, world, node_weights_);
    const RigidPose to_face = s.pose.inverse();
    std::vector<Eigen::Vector3f> local(nodes);
    for (size_t v = 0; v < nodes; ++v) local[v] = to_face.apply(world[v]).cast<float>();
    // The reference's local vectors stay in its outline too: pose_centre reads them after the
    // samples are released.
    if (index == reference) s.local = local;
    samples_->put(index, std::move(local), std::move(normal));
  });
  report_.peak_selection_samples_in_memory = 0;
  report_.seconds_selection = seconds_since(start);
}

std::vector<size_t> blend_trial_pairs(const std::vector<int>& keyframes) {
  std::vector<size_t> pairs;
  for (size_t k = 0; k + 1 < keyframes.size(); ++k) {
    if (keyframes[k + 1] - keyframes[k] >= 2) pairs.push_back(k);
  }
  if (pairs.size() <= static_cast<size_t>(kBlendTrials)) return pairs;
  std::vector<size_t> spread;
  for (int t = 0; t < kBlendTrials; ++t) spread.push_back(pairs[static_cast<size_t>(t) * (pairs.size() - 1) / static_cast<size_t>(kBlendTrials - 1)]);
  return spread;
}

Representation representation_for(const BlendComparison& blend) {
  return blend.trials > 0 && blend.fields_error > kFieldsBlendMargin * blend.positions_error ? Representation::kXYZ : Representation::kHLT;
}

void SequenceEncoder::adopt_representation(Representation representation, const BlendComparison& blend) {
  auto_representation_ = representation;
  report_.blend = blend;
  report_.representation = this->representation();
}

void SequenceEncoder::choose_representation(const KeyframeSelection& chosen, int grid) {
  const auto start = std::chrono::steady_clock::now();
  auto_representation_ = Representation::kHLT;
  report_.blend = {};
  const std::vector<int>& keyframes = chosen.keyframes;
  const bool unmatched = 2 * report_.frames_without_interior_landmarks > frame_count() - 1;
  // On a radially reparametrised disk (a whole head) hl+t's fixed-point iteration diverges: the
  // tangential part of Δ_h S, large where the map stretches the disk unevenly, turns with the frame
  // it is carried in (measured on fmsynth --head at radial strengths 0.25 to 1: no keyframe converged).
  // Positions decode without iterating, and the container holds them (spec/method.md §7.11).
  if (!options_.representation && report_.radial_equalising > 0) {
    auto_representation_ = Representation::kXYZ;
  } else if (!options_.representation && unmatched && keyframes.size() >= 2) {
    // The frame midway between each pair of keyframes with frames between them (blend_trial_pairs).
    const std::vector<size_t> pairs = blend_trial_pairs(keyframes);
    std::vector<double> times;
    for (int k : keyframes) times.push_back(capture_.frames[static_cast<size_t>(k)].time);
    const KeyframeSpline spline(times, options_.spline);
    std::vector<int> midway, needed_keys;
    std::vector<char> needed(keyframes.size(), 0);
    for (size_t k : pairs) {
      midway.push_back((keyframes[k] + keyframes[k + 1]) / 2);
      for (int32_t key : spline.weights(capture_.frames[static_cast<size_t>(midway.back())].time).keys) needed[static_cast<size_t>(key)] = 1;
    }
    for (size_t k = 0; k < keyframes.size(); ++k) {
      if (needed[k]) needed_keys.push_back(static_cast<int>(k));
    }
    if (!pairs.empty()) {
      const auto geometry = std::make_shared<const GridGeometry>(make_disk_grid(grid));
      // A frame's registered surface on G in the face frame (as build samples a keyframe).
      auto local_surface = [&](int i) {
        std::vector<Vec3> surface = sample_surface(i, geometry->grid().nodes);
        const RigidPose to_face = selection_[static_cast<size_t>(i)].pose.inverse();
        for (Vec3& p : surface) p = to_face.apply(p);
        return surface;
      };
      std::vector<std::vector<Vec3>> keys(keyframes.size());
      std::vector<BlendTrial> trials(pairs.size());
      parallel_for(static_cast<int>(needed_keys.size() + pairs.size()), options_.threads, [&](int j) {
        const auto index = static_cast<size_t>(j);
        if (index < needed_keys.size()) {
          const auto k = static_cast<size_t>(needed_keys[index]);
          keys[k] = local_surface(keyframes[k]);
        } else {
          const size_t t = index - needed_keys.size();
          trials[t].time = capture_.frames[static_cast<size_t>(midway[t])].time;
          trials[t].surface = local_surface(midway[t]);
        }
      });
      report_.blend = compare_blends(geometry, times, options_.spline, keys, trials, options_.threads);
      auto_representation_ = representation_for(report_.blend);
    }
  }
  report_.representation = representation();
  report_.seconds_representation = seconds_since(start);
}

Vec3 SequenceEncoder::pose_centre() const {
  const SelectionFrame& reference = selection_[static_cast<size_t>(options_.reference_frame)];
  Vec3 sum = Vec3::Zero();
  double total = 0;
  for (size_t v = 0; v < node_weights_.size(); ++v) {
    sum += node_weights_[v] * reference.local_at(v);
    total += node_weights_[v];
  }
  return sum / total;
}

void SequenceEncoder::release_selection_samples(const std::vector<int>& keyframes) {
  for (int k : keyframes) released_noise_[k] = noise_at(k);
  note_selection_samples();
  samples_.reset();
  samples_released_ = true;
}

void SequenceEncoder::note_selection_samples() {
  if (!samples_) return;
  report_.peak_selection_samples_in_memory = std::max(report_.peak_selection_samples_in_memory, samples_->peak_held());
  report_.selection_spilled_bytes = samples_->spilled_bytes();
}

std::shared_ptr<const SelectionFrame> SequenceEncoder::selection_frame(int i) const {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released (sample_frames again)");
  return samples_->sampled(static_cast<size_t>(i));
}

double SequenceEncoder::noise_at(int k) const {
  if (!samples_released_) return frame_noise(*samples_, node_weights_, k);
  const auto it = released_noise_.find(k);
  if (it == released_noise_.end()) throw Error(ErrorCode::kInternal, "frame " + std::to_string(k) + " is no keyframe the selection's samples were released for");
  return it->second;
}

KeyframeSelection SequenceEncoder::select_keyframes() const {
  if (samples_released_) throw Error(ErrorCode::kInternal, "select_keyframes: the selection's samples were released (sample_frames again)");
  SelectionOptions selection;
  selection.fraction = options_.keyframe_fraction;
  selection.max_error = options_.max_error;
  selection.error_bound = options_.keyframe_error_bound;
  selection.sparse_interval = options_.sparse_frame_interval;
  selection.spline = options_.spline;
  selection.pose_centre = pose_centre();
  selection.residuals = options_.residual_frames;
  return facemorph::select_keyframes(*samples_, node_weights_, selection);
}

std::vector<ResidualFrame> SequenceEncoder::residual_frames(const KeyframeSelection& chosen) const {
  if (!options_.residual_frames) return {};
  std::vector<double> key_times;
  for (int k : chosen.keyframes) key_times.push_back(capture_.frames.at(static_cast<size_t>(k)).time);
  return residuals_on_file_times(chosen.residuals, key_times, first_time_, capture_.fps);
}

int SequenceEncoder::choose_grid(const KeyframeSelection* chosen) {
  if (options_.grid > 0) return options_.grid;
  if (samples_released_) throw Error(ErrorCode::kInternal, "choose_grid: the selection's samples were released (sample_frames again)");
  // The smallest N whose resampling floor on the reference frame is within the target; the
  // largest candidate when none is (a crowded face: spec/method.md §7.6).
  report_.grid_floors.clear();
  // A grid fine enough to resolve a capture's per-frame noise spends its nodes on noise the
  // keyframe fit averages away: the floor need not go below the median frame noise. (A floor
  // measured against a noisy frame is mostly that frame's unresolved noise: on a 0.16%-noise
  // capture, N = 193 → 97 left the decoded error against the noise-free surface unchanged while
  // the fields took a quarter of the bytes; spec/method.md §7.6.)
  std::vector<double> noise;
  for (int k = 0; k < frame_count(); ++k) noise.push_back(frame_noise(*samples_, node_weights_, k) / selection_[static_cast<size_t>(k)].diagonal);
  std::nth_element(noise.begin(), noise.begin() + static_cast<std::ptrdiff_t>(noise.size() / 2), noise.end());
  report_.median_noise = std::isfinite(noise[noise.size() / 2]) ? noise[noise.size() / 2] : 0.0;
  // Nor below half the error the spline makes between the chosen keyframes: errors add in
  // quadrature, so such a floor adds up to 12% to it, and below that a finer grid costs more bytes
  // for the error it removes than more keyframes would (spec/method.md §7.6).
  // Not on a whole head (a radially spread disk, spec/method.md §7.11) whose frames share no
  // interior landmarks with the reference: there the found landmarks' disagreement from frame to
  // frame reads as noise (fmsynth --head --landmarks auto: 1.27% of the diagonal, 0.085% with its
  // landmarks), and the N = 33 it asked for decoded at 1.57 mm, N = 129 at 0.62.
  const bool unmatched = 2 * report_.frames_without_interior_landmarks > frame_count() - 1;
  const bool noise_decides = report_.radial_equalising == 0 || !unmatched;
  const double noise_term = noise_decides ? kGridNoiseShare * report_.median_noise : 0.0, interpolation_term = chosen ? kGridErrorShare * mean_predicted_error(*chosen) : 0.0;
  report_.grid_target = std::max({kGridFloorTarget, noise_term, interpolation_term});
  report_.grid_term = report_.grid_target == interpolation_term ? "interpolation" : report_.grid_target == noise_term ? "noise" : "floor";
  const double target = report_.grid_target;
  const std::shared_ptr<const MappedFrame> reference = frame(options_.reference_frame);
  for (int n : kGridCandidates) {
    const DiskGrid grid = make_disk_grid(n);
    const std::vector<Vec3> sampled = sample_surface(*reference, options_.reference_frame, grid.nodes);
    const SurfaceDistance floor = surface_distance(reference->map.surface, grid_mesh(grid, sampled));
    report_.grid_floors.emplace_back(n, floor.rms / floor.diagonal);
    if (floor.rms / floor.diagonal <= target) return n;
  }
  return kGridCandidates[std::size(kGridCandidates) - 1];
}

Sequence SequenceEncoder::build(const std::vector<int>& keyframes, int grid_n) { return build_stored(keyframes, grid_n)->to_sequence(); }

std::unique_ptr<StoredSequence> SequenceEncoder::build_stored(const std::vector<int>& keyframes, int grid_n, const KeyframeSegment* segment) {
  const auto start = std::chrono::steady_clock::now();
  if (keyframes.empty()) throw Error(ErrorCode::kInvalidArgument, "no keyframes to build");
  const GridGeometry geometry(make_disk_grid(grid_n));
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
  for (const FrameSummary& f : summaries_) any_holes = any_holes || f.holes_filled > 0;
  const bool store_holes = any_holes && !options_.keep_holes_filled;
  // Textures: every keyframe's, or (a capture without images or vertex colours) none; some but not
  // all is an error.
  bool store_texture = options_.texture && (!segment || segment->textures);
  for (int k : keyframes) {
    const bool has = has_texture(k);
    if (store_texture && !has) {
      if (k != keyframes.front()) {
        throw Error(ErrorCode::kMissingTexture,
                    summaries_[static_cast<size_t>(k)].name + ": this keyframe has no texture while others have (--no-texture encodes geometry only)");
      }
      store_texture = false;
    }
  }
  int texture_size = options_.texture_size;
  if (store_texture && texture_size == 0) {
    const auto first = static_cast<size_t>(keyframes.front());
    if (!textures_[first].empty() && summaries_[first].has_uvs) {
      const Image image = read_image(textures_[first]);
      texture_size = auto_texture_size(frame(keyframes.front())->map.surface, image.width, image.height);
    } else {
      texture_size = auto_texture_size_for_colours(summaries_[first].vertices);
    }
  }
  report_.texture_size = store_texture ? texture_size : 0;
  // The registered surfaces in the face frame first: the fixed-frame nodes are the union of the
  // keyframes' folds, since the keyframes are blended together. Each goes to the store as it is
  // made (1.25 MB at N = 257, and a long capture has hundreds) and is read back for each later use.
  SurfaceStore local(options_.spill_keyframes ? SurfaceStore::Mode::kSpill : SurfaceStore::Mode::kMemory);
  local.reset(fit_keys);
  std::vector<std::vector<int32_t>> folds(keys);
  Sequence shape;
  shape.grid_n = grid_n;
  shape.representation = representation();
  shape.spline = options_.spline;
  shape.fps = capture_.fps;
  shape.first_time = first_time_;
  shape.last_time = last_time_;
  shape.units = capture_.units;
  shape.pose_centre = pose_centre();
  shape.keyframes.resize(keys);
  for (size_t k = 0; k < keys; ++k) {
    const auto index = static_cast<size_t>(keyframes[own_first + k]);
    shape.keyframes[k].time = capture_.frames[index].time;
    shape.keyframes[k].pose = selection_[index].pose;
  }
  // The keyframes' arrays go to the store as they are made (options().spill_keyframes): a long
  // capture's hundreds of keyframes are not held until the file is written.
  auto stored = std::make_unique<StoredSequence>(std::move(shape), options_.spill_keyframes ? SpillMode::kSpill : SpillMode::kMemory);
  parallel_for(
      static_cast<int>(fit_keys), options_.threads,
      [&](int k) {
        const auto index = static_cast<size_t>(fitted[static_cast<size_t>(k)]);
        const std::shared_ptr<const MappedFrame> frame = this->frame(static_cast<int>(index));
        const MappedFrame& f = *frame;
        const InverseDiskMap inverse(f.map);
        const std::vector<Vec2> points = sample_points(static_cast<int>(index), grid.nodes);
        const RigidPose to_face = selection_[index].pose.inverse();
        std::vector<Vec3> positions = resample_positions(inverse, points);
        for (Vec3& p : positions) p = to_face.apply(p);
        local.put(static_cast<size_t>(k), std::move(positions));
        const auto own = static_cast<size_t>(k) - own_offset;  // wraps past keys for a margin's keyframe
        if (own >= keys) return;
        stored->put_hole_level(own, store_holes ? hole_level(f.prepared, f.map, points) : std::vector<double>());
        stored->put_texture(own, store_texture ? frame_texture(f, static_cast<int>(index), texture_size) : Image());
      },
      [&](int done, int total) { progress("keyframes", done, total); });
  if (options_.keyframe_fit) fit_keyframes(fitted, geometry, local);
  parallel_for(static_cast<int>(keys), options_.threads,
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
  report_.keyframe_folds = own_folds;
  parallel_for(static_cast<int>(keys), options_.threads, [&](int k) {
    stored->put_fields(static_cast<size_t>(k), keyframe_fields(geometry, *local.get(own_offset + static_cast<size_t>(k)), stored->shape().representation, fixed));
  });
  report_.peak_keyframes_in_memory = std::max(report_.peak_keyframes_in_memory, local.peak_held());
  report_.keyframes_spilled_bytes += local.spilled_bytes();
  report_.seconds_keyframes = seconds_since(start);
  return stored;
}

void SequenceEncoder::fit_keyframes(const std::vector<int>& keyframes, const GridGeometry& geometry, SurfaceStore& local) const {
  const std::vector<Vec2>& nodes = geometry.grid().nodes;
  // Per node of G, the keyframe values P_k minimising
  //   Σ_j |Σ_k c_k(t_j) P_k − X_j|² + μ Σ_k |P_k − X_k|²
  // over the frames j within the keyframes' span, X_j frame j's registered surface in the face frame
  // of the pose the decoder blends at t_j (at a keyframe, its own pose). The weights c_k(t_j) are
  // shared by every node, so this is one keys × keys normal matrix (banded, positive definite: each
  // keyframe's own frame has weight 1 + μ) and a right-hand side per node coordinate.
  const auto keys = static_cast<Eigen::Index>(keyframes.size());
  const int count = frame_count();
  if (keys < 2 || keys >= count || local.size() != keyframes.size()) return;
  const double mu = options_.keyframe_fit_weight;
  std::vector<double> times;
  std::vector<RigidPose> poses;
  for (int k : keyframes) {
    times.push_back(capture_.frames[static_cast<size_t>(k)].time);
    poses.push_back(selection_[static_cast<size_t>(k)].pose);
  }
  const KeyframeSpline spline(times, options_.spline);
  const std::vector<Vec3> rotations = unwrap_rotations(poses);
  const Vec3 centre = pose_centre();
  const auto n = static_cast<Eigen::Index>(3 * nodes.size());
  auto flat = [n](std::vector<Vec3>& v) { return Eigen::Map<Eigen::VectorXd>(v.data()->data(), n); };
  auto flat_const = [n](const std::vector<Vec3>& v) { return Eigen::Map<const Eigen::VectorXd>(v.data()->data(), n); };
  std::vector<int> held;
  for (int j = keyframes.front() + 1; j < keyframes.back(); ++j) {
    if (!std::binary_search(keyframes.begin(), keyframes.end(), j)) held.push_back(j);
  }
  // The normal matrix from the weights alone: every keyframe's own frame (weight 1 + μ) and each
  // held frame's few keyframes. It couples keyframes a frame's weights reach together, a band of a
  // few; `last_use[k]`: the last held frame whose weights reach keyframe k (−1: none).
  std::vector<SplineWeights> weights(held.size());
  int band = 0;
  for (size_t h = 0; h < held.size(); ++h) {
    weights[h] = spline.weights(capture_.frames[static_cast<size_t>(held[h])].time);
    for (int32_t a : weights[h].keys) {
      for (int32_t b : weights[h].keys) band = std::max(band, std::abs(a - b));
    }
  }
  SymmetricBand normal(static_cast<int>(keys), band);
  std::vector<long> last_use(static_cast<size_t>(keys), -1);
  for (Eigen::Index k = 0; k < keys; ++k) normal.at(static_cast<int>(k), static_cast<int>(k)) += 1 + mu;
  for (size_t h = 0; h < held.size(); ++h) {
    const SplineWeights& w = weights[h];
    for (size_t a = 0; a < w.keys.size(); ++a) {
      last_use[static_cast<size_t>(w.keys[a])] = static_cast<long>(h);
      // Every ordered pair, each entry once (the band holds A(i, j) and A(j, i) as one number); a
      // key may appear twice in one frame's weights.
      for (size_t b = 0; b < w.keys.size(); ++b) {
        if (w.keys[a] >= w.keys[b]) normal.at(w.keys[a], w.keys[b]) += w.weights[a] * w.weights[b];
      }
    }
  }
  const BandedCholesky factor(normal);
  // The right-hand side, column k = Σ_j c_k(t_j) X_j + (1 + μ) X_k, made as the held frames are
  // sampled in time order (32 at a time, on the threads), and solved as it comes: once no later
  // frame reaches column k, forward substitution turns it into y_k = (column k − Σ L(k, i) y_i) /
  // L(k, k) over the `band` y's before it, and y_k goes to the store. Memory holds the columns
  // begun and not finished and the last `band` y's, a few surfaces whatever the keyframes' count
  // (a whole right-hand side was 1.25 MB a keyframe at N = 257).
  SurfaceStore forward(local.mode());
  forward.reset(keyframes.size());
  std::map<Eigen::Index, Eigen::VectorXd> open;  // columns begun
  std::deque<Eigen::VectorXd> recent;            // y_{k − band} .. y_{k − 1}
  Eigen::Index next = 0;                         // the next column to finish
  const auto finish_columns = [&](long through) {  // every held frame up to `through` added
    for (; next < keys && last_use[static_cast<size_t>(next)] <= through; ++next) {
      Eigen::VectorXd y = open.count(next) ? std::move(open[next]) : Eigen::VectorXd::Zero(n);
      open.erase(next);
      y += (1 + mu) * flat_const(*local.get(static_cast<size_t>(next)));
      factor.forward(static_cast<int>(next), y, recent);
      std::vector<Vec3> stored(nodes.size());
      flat(stored) = y;
      forward.put(static_cast<size_t>(next), std::move(stored));
      recent.push_back(std::move(y));
      if (static_cast<int>(recent.size()) > band) recent.pop_front();
    }
  };
  finish_columns(-1);
  const int chunk = 32;
  std::vector<std::vector<Vec3>> samples(chunk);
  for (size_t begin = 0; begin < held.size(); begin += chunk) {
    const int size = static_cast<int>(std::min(held.size() - begin, static_cast<size_t>(chunk)));
    parallel_for(size, options_.threads, [&](int c) {
      const size_t h = begin + static_cast<size_t>(c);
      const RigidPose to_face = blend_poses(poses, rotations, weights[h], centre).inverse();
      std::vector<Vec3> positions = sample_surface(held[h], nodes);
      for (Vec3& p : positions) p = to_face.apply(p);
      samples[static_cast<size_t>(c)] = std::move(positions);
    });
    for (int c = 0; c < size; ++c) {
      const SplineWeights& w = weights[begin + static_cast<size_t>(c)];
      const auto x = flat(samples[static_cast<size_t>(c)]);
      for (size_t a = 0; a < w.keys.size(); ++a) {
        // last_use keeps a column open until its last frame is in; a frame reaching one already
        // solved would be lost from it.
        if (w.keys[a] < next) throw Error(ErrorCode::kInternal, "keyframe fit: a frame reaches a keyframe already solved");
        Eigen::VectorXd& column = open[w.keys[a]];
        if (column.size() == 0) column = Eigen::VectorXd::Zero(n);
        column += w.weights[a] * x;
      }
    }
    finish_columns(static_cast<long>(begin) + size - 1);
  }
  finish_columns(static_cast<long>(held.size()));
  // Back substitution from the last keyframe: P_k = (y_k − Σ L(i, k) P_i) / L(k, k) over the
  // `band` keyframes after it, each fitted surface then bounded against the keyframe's own frame.
  const Eigen::VectorXd& mass = geometry.mass();
  std::deque<Eigen::VectorXd> after;  // P_{k + 1} .. P_{k + band}
  for (Eigen::Index k = keys - 1; k >= 0; --k) {
    Eigen::VectorXd fitted = flat_const(*forward.get(static_cast<size_t>(k)));
    factor.backward(static_cast<int>(k), fitted, after);
    std::vector<Vec3> own = *local.get(static_cast<size_t>(k));  // a copy to move: the stored one is read-only
    double moved = 0, total = 0;
    for (Eigen::Index v = 0; v < mass.size(); ++v) {
      moved += mass[v] * (fitted.segment<3>(3 * v) - own[static_cast<size_t>(v)]).squaredNorm();
      total += mass[v];
    }
    moved = std::sqrt(moved / total);
    const double noise = noise_at(keyframes[static_cast<size_t>(k)]);
    // A move beyond κ times the frame's own noise would fit the spline's systematic error between
    // keyframes rather than the capture's noise: shrink it back to that (a clean capture's keyframes
    // stay its frames). Fewer than 5 frames give no estimate of the noise, so nothing bounds the
    // move: the keyframe stays its frame.
    const double scale = std::isfinite(noise) ? std::min(1.0, options_.keyframe_fit_noise * noise / std::max(moved, 1e-300)) : 0.0;
    flat(own) += scale * (fitted - flat(own));
    local.put(static_cast<size_t>(k), std::move(own));
    after.push_front(std::move(fitted));
    if (static_cast<int>(after.size()) > band) after.pop_back();
  }
}

namespace {

// --field-error auto, the fields' rounding target: two fifths of the spline's mean predicted error,
// where rounding error and more keyframes buy held-out error at about the same price in bytes
// (spec/method.md §5.3). The rounding's node displacement is mostly along the surface and reaches the point-to-surface error at
// about half its size, so it may be larger than a quadrature rule on displacements would allow.
double auto_field_error(const KeyframeSelection& chosen) {
  constexpr double kShare = 0.4, kLowest = 5e-5, kHighest = 2e-3;
  const double mean = mean_predicted_error(chosen);
  return mean == 0 ? 1e-4 : std::clamp(kShare * mean, kLowest, kHighest);
}

}  // namespace

FieldCoding SequenceEncoder::round_fields(Sequence& sequence, const KeyframeSelection& chosen) {
  return StoredSequence::around(sequence, SpillMode::kMemory, [&](StoredSequence& stored) { return round_fields(stored, chosen); });
}

FieldPrecisionOptions SequenceEncoder::field_precision(const KeyframeSelection& chosen) const {
  FieldPrecisionOptions precision = options_.field_precision;
  precision.spill = options_.spill_keyframes;
  precision.threads = options_.threads;
  if (options_.auto_field_error) precision.target_error = auto_field_error(chosen);
  return precision;
}

FieldCoding SequenceEncoder::round_fields(StoredSequence& keys, const KeyframeSelection& chosen) {
  const auto start = std::chrono::steady_clock::now();
  FieldCoding coding = choose_field_coding(keys, field_precision(chosen), &report_.field_precision);
  report_.seconds_precision = seconds_since(start);
  return coding;
}

std::vector<int> SequenceEncoder::choose_texture_qualities(const Sequence& sequence, const std::vector<int>& keyframes) {
  return choose_texture_qualities(*StoredSequence::of(Sequence(sequence), SpillMode::kMemory), keyframes);
}

std::vector<int> SequenceEncoder::choose_texture_qualities(const StoredSequence& stored, const std::vector<int>& keyframes) {
  const auto start = std::chrono::steady_clock::now();
  report_.texture_qualities.clear();
  report_.texture_interpolation_psnr.clear();
  const Sequence& sequence = stored.shape();
  if (stored.size() == 0 || stored.texture(0)->empty()) return {};
  const size_t keys = sequence.keyframes.size();
  if (keyframes.size() != keys) throw Error(ErrorCode::kInvalidArgument, "choose_texture_qualities: the keyframes are not the sequence's");
  std::vector<int> qualities(keys, options_.texture_quality);
  if (options_.texture_quality == kAutoTextureQuality) {
    // The blend's error at the frame midway between each pair of neighbouring keyframes, against
    // that frame's own texture on the disk (sampled as a keyframe's would be).
    std::vector<double> times;
    for (const Keyframe& key : sequence.keyframes) times.push_back(key.time);
    const KeyframeSpline spline(times, sequence.spline);
    const int size = stored.texture(0)->width;
    std::vector<double> interval_mse(keys - 1, -1.0);
    parallel_for(static_cast<int>(keys) - 1, options_.threads, [&](int k) {
      const int middle = (keyframes[static_cast<size_t>(k)] + keyframes[static_cast<size_t>(k) + 1]) / 2;
      const auto m = static_cast<size_t>(middle);
      if (middle == keyframes[static_cast<size_t>(k)] || !has_texture(middle)) return;
      const Image own = frame_texture(middle, size);
      const SplineWeights w = spline.weights(capture_.frames[m].time);
      std::vector<std::shared_ptr<const Image>> held;  // the keyframes' textures the blend reads, one frame's at a time
      std::vector<const Image*> images;
      for (int32_t key : w.keys) images.push_back(held.emplace_back(stored.texture(static_cast<size_t>(key))).get());
      interval_mse[static_cast<size_t>(k)] = disk_texture_mse(own, blend_images(images, w.weights));
    });
    const std::vector<double> targets = texture_error_targets(interval_mse, options_.texture_coding);
    parallel_for(static_cast<int>(keys), options_.threads, [&](int k) {
      const double target = targets[static_cast<size_t>(k)];
      qualities[static_cast<size_t>(k)] = target < 0 ? options_.texture_coding.fallback_quality
                                                      : texture_quality_for(options_.texture_codec, *stored.texture(static_cast<size_t>(k)), target);
    });
    for (double mse : interval_mse) report_.texture_interpolation_psnr.push_back(mse < 0 ? 0.0 : psnr_of_mse(mse));
  }
  report_.texture_qualities = qualities;
  report_.seconds_texture = seconds_since(start);
  return qualities;
}

void SequenceEncoder::share_textures(Sequence& sequence, const std::vector<int>& keyframes) {
  StoredSequence::around(sequence, SpillMode::kMemory, [&](StoredSequence& stored) { share_textures(stored, keyframes); });
}

void SequenceEncoder::share_textures(StoredSequence& stored, const std::vector<int>& keyframes) {
  const size_t keys = stored.size();
  report_.texture_shared_with.assign(keys, -1);
  report_.texture_share_psnr.assign(keys, 0.0);
  if (!options_.share_textures || keys == 0 || stored.texture(0)->empty()) return;
  if (keyframes.size() != keys) throw Error(ErrorCode::kInvalidArgument, "share_textures: the keyframes are not the sequence's");
  // Each keyframe's captured image by its pixels (a file read once however many frames name it);
  // vertex colours have none.
  std::map<std::filesystem::path, uint64_t> pixels_of_file;
  std::vector<std::optional<uint64_t>> image(keys);
  for (size_t k = 0; k < keys; ++k) {
    const auto i = static_cast<size_t>(keyframes[k]);
    if (textures_[i].empty() || !summaries_[i].has_uvs) continue;
    auto it = pixels_of_file.find(textures_[i]);
    if (it == pixels_of_file.end()) it = pixels_of_file.emplace(textures_[i], image_content_hash(read_image(textures_[i]))).first;
    image[k] = it->second;
  }
  std::map<uint64_t, int> keyframes_of_image;
  bool any = false;
  for (const std::optional<uint64_t>& pixels : image) any = any || (pixels && ++keyframes_of_image[*pixels] > 1);
  if (!any) return;  // no two keyframes were painted from one image
  std::map<uint64_t, std::vector<size_t>> owners;  // per image, the keyframes showing their own texture of it
  // What sharing may cost a keyframe: its texture coding's coarsest (min_psnr, 30 dB by default).
  // Keyframes painted from one image differ only where their registrations place the skin apart
  // (a slide of a texel or two at feature edges), which PSNR counts as error though the skin is the
  // same; a frame whose UVs changed, or whose registration failed, differs far more.
  const double allowed = mse_of_psnr(options_.texture_coding.min_psnr);
  for (size_t k = 0; k < keys; ++k) {
    if (!image[k]) continue;
    std::vector<size_t>& same_image = owners[*image[k]];
    // The nearest in time first: its registration drifted least from k's.
    for (auto owner = same_image.rbegin(); owner != same_image.rend(); ++owner) {
      const std::shared_ptr<const Image> owner_texture = stored.texture(*owner);
      const double mse = disk_texture_mse(*owner_texture, *stored.texture(k));
      if (mse <= allowed) {
        stored.put_texture(k, Image(*owner_texture));
        report_.texture_shared_with[k] = static_cast<int>(*owner);
        report_.texture_share_psnr[k] = psnr_of_mse(mse);
        break;
      }
    }
    if (report_.texture_shared_with[k] < 0) same_image.push_back(k);
  }
}

Sequence encode_capture(const Capture& capture, const EncodeOptions& options, EncodeReport* report) {
  return encode_capture_stored(capture, options, report)->to_sequence();
}

std::unique_ptr<StoredSequence> encode_capture_stored(Capture capture, const EncodeOptions& options, EncodeReport* report_out) {
  SequenceEncoder encoder(std::move(capture), options);
  encoder.map_frames();
  encoder.register_frames();
  encoder.sample_frames();
  return encode_sampled(encoder, report_out);
}

namespace {

void report_selection(EncodeReport& report, const KeyframeSelection& chosen) {
  report.keyframes = chosen.keyframes;
  report.selection_history = chosen.history;
  report.keyframe_budget = chosen.budget;
  report.sparse = chosen.sparse;
  report.median_frame_interval = chosen.median_interval;
  report.budget_mean_error = chosen.budget_mean_error;
  report.budget_worst_error = chosen.budget_worst_error;
}

void release_samples(SequenceEncoder& encoder, const std::vector<int>& keyframes) {
  encoder.release_selection_samples(keyframes);
#ifdef __GLIBC__
  // The samples were thousands of 78 KB blocks across the threads' heaps: handed back to the system
  // here, so that the keyframe steps' arrays take their place rather than add to them.
  malloc_trim(0);
#endif
}

}  // namespace

KeyframeSelection plan_keyframes(SequenceEncoder& encoder) {
  const auto start = std::chrono::steady_clock::now();
  const KeyframeSelection chosen = encoder.select_keyframes();
  EncodeReport& report = encoder.report();
  report_selection(report, chosen);
  report.grid = encoder.choose_grid(&chosen);
  encoder.choose_representation(chosen, report.grid);
  release_samples(encoder, chosen.keyframes);
  report.seconds_planning = seconds_since(start);
  return chosen;
}

void adopt_keyframe_plan(SequenceEncoder& encoder, const KeyframeSelection& chosen, int grid, Representation representation, const BlendComparison& blend) {
  const std::vector<int>& keys = chosen.keyframes;
  const int frames = encoder.frame_count();
  const bool increasing = std::adjacent_find(keys.begin(), keys.end(), std::greater_equal<int>()) == keys.end();
  if (keys.empty() || keys.front() != 0 || keys.back() != frames - 1 || !increasing || chosen.predicted_error.size() != static_cast<size_t>(frames)) {
    throw Error(ErrorCode::kInvalidArgument, "the keyframes planned are not a selection of this encode's " + std::to_string(frames) + " frames");
  }
  report_selection(encoder.report(), chosen);
  encoder.report().grid = grid;
  encoder.adopt_representation(representation, blend);
  release_samples(encoder, keys);
}

void finish_report(SequenceEncoder& encoder, const KeyframeSelection& chosen, const StoredSequence& sequence, EncodeReport* report_out) {
  EncodeReport& report = encoder.report();
  for (int i = 0; i < encoder.frame_count(); ++i) {
    const FrameSummary& frame = encoder.frame_summary(i);
    const std::shared_ptr<const DiskRegistration> f = encoder.registration(i);
    const DiskRegistration& registration = *f;
    EncodedFrameReport r;
    r.name = frame.name;
    r.time = encoder.capture().frames[static_cast<size_t>(i)].time;
    r.vertices = frame.vertices;
    r.holes_filled = frame.holes_filled;
    r.repair = frame.repair;
    r.repair_totals = frame.repair_totals;
    r.keyframe = std::binary_search(chosen.keyframes.begin(), chosen.keyframes.end(), i);
    r.fallback = registration.fallback;
    r.fallback_reason = registration.fallback_reason;
    r.conformal_fallback_reason = frame.conformal_fallback_reason;
    r.conformal_method = frame.conformal_method;
    r.energy_moebius = registration.energy_moebius;
    r.energy = registration.energy;
    r.predicted_error = chosen.predicted_error[static_cast<size_t>(i)];
    r.diagonal = encoder.selection_frames()[static_cast<size_t>(i)].diagonal;
    report.registration_fallbacks += r.fallback != RegistrationFallback::kNone;
    report.frames.push_back(std::move(r));
  }
  report.peak_frames_in_memory = encoder.frame_store().peak_held();
  report.spilled_bytes = encoder.frame_store().spilled_bytes();
  report.peak_keyframes_in_memory = std::max(report.peak_keyframes_in_memory, report.field_precision.peak_keyframes_in_memory);
  report.keyframes_spilled_bytes += report.field_precision.spilled_bytes;
  report.keyframes_spilled_bytes += sequence.spilled_bytes();
  if (report_out) *report_out = std::move(report);
}

std::unique_ptr<StoredSequence> encode_sampled(SequenceEncoder& encoder, EncodeReport* report_out) {
  const KeyframeSelection chosen = plan_keyframes(encoder);
  EncodeReport& report = encoder.report();
  std::unique_ptr<StoredSequence> sequence = encoder.build_stored(chosen.keyframes, report.grid);
  if (encoder.options().predicted_fields) report.field_coding = encoder.round_fields(*sequence, chosen);
  // Residual frames fitted to the keyframes as the file holds them (residual_fit.hpp).
  if (encoder.options().residual_frames) sequence->set_residuals(fit_decoded_residuals(encoder, *sequence, chosen.keyframes, SelectionOptions().residual_step, &report.residual_fit));
  encoder.choose_texture_qualities(*sequence, chosen.keyframes);
  encoder.share_textures(*sequence, chosen.keyframes);
  finish_report(encoder, chosen, *sequence, report_out);
  return sequence;
}

}  // namespace facemorph
