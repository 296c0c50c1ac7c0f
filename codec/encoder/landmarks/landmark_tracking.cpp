// Correspondence between frames by optical flow on disk images of their geometry (spec/method.md §7.14).
#include "codec/encoder/landmarks/landmark_tracking.hpp"

#include "codec/core/geometry/differential.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "format/error.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace facemorph {

namespace {

// Texel coordinates (x right, y down, texel centres at integers) of a disk point, and back.
cv::Point2f to_texel(const Vec2& w, int size) {
  return {static_cast<float>((w.x() + 1) * 0.5 * size - 0.5), static_cast<float>((1 - w.y()) * 0.5 * size - 0.5)};
}
Vec2 to_disk(const cv::Point2f& t, int size) { return {2 * (t.x + 0.5) / size - 1, 1 - 2 * (t.y + 0.5) / size}; }

// Per-channel affine map of float values to 8 bits, from the reference's values inside the disk:
// its 2nd..98th percentiles fill [20, 235], and every frame uses the same map (brightness constancy).
struct Scale {
  float offset = 0, gain = 1;
};
Scale channel_scale(const std::vector<float>& values, int size) {
  std::vector<float> inside;
  inside.reserve(values.size());
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const Vec2 w = to_disk(cv::Point2f(static_cast<float>(x), static_cast<float>(y)), size);
      if (w.norm() < 0.95) inside.push_back(values[static_cast<size_t>(y) * size + x]);
    }
  }
  if (inside.size() < 50) return {};
  auto at = [&](double q) {
    const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(inside.size() - 1));
    std::nth_element(inside.begin(), inside.begin() + k, inside.end());
    return inside[static_cast<size_t>(k)];
  };
  const float lo = at(0.02), hi = at(0.98);
  if (!(hi > lo)) return {127.5f - lo, 1};  // a flat channel: mid-grey
  return {20 - lo * 215 / (hi - lo), 215 / (hi - lo)};
}

// The two channels as one 8-bit, 2-channel image, blurred by a texel first (a scanner's noise
// in H must not be what the flow follows).
cv::Mat to_image(const DiskFeatures& f, const Scale& curvature, const Scale& factor, double blur) {
  cv::Mat channels[2];
  const std::vector<float>* planes[2] = {&f.curvature, &f.log_factor};
  const Scale* scales[2] = {&curvature, &factor};
  for (int c = 0; c < 2; ++c) {
    cv::Mat plane(f.size, f.size, CV_32F);
    std::copy(planes[c]->begin(), planes[c]->end(), plane.ptr<float>());
    // A hole's texels at the darkest level.
    const auto dark = static_cast<float>(-scales[c]->offset / scales[c]->gain);
    if (f.hole.size() == planes[c]->size()) {
      for (size_t i = 0; i < f.hole.size(); ++i) {
        if (f.hole[i]) plane.ptr<float>()[i] = dark;
      }
    }
    cv::Mat blurred = plane;
    if (blur > 0) cv::GaussianBlur(plane, blurred, cv::Size(0, 0), blur);
    blurred.convertTo(channels[c], CV_8U, scales[c]->gain, scales[c]->offset);
  }
  cv::Mat image;
  cv::merge(channels, 2, image);
  return image;
}

struct Flow {
  std::vector<cv::Point2f> at;
  std::vector<uchar> ok;
  std::vector<double> round_trip;  // disk units; infinity where lost
};

Flow lucas_kanade(const cv::Mat& reference, const cv::Mat& frame, const std::vector<cv::Point2f>& from,
                  const std::vector<cv::Point2f>& start, const TrackingOptions& options) {
  const cv::Size window(options.window, options.window);
  const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  Flow flow;
  flow.at = start;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(reference, frame, from, flow.at, flow.ok, error, window, options.pyramid_levels, stop,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> back = from;
  std::vector<uchar> back_ok;
  cv::calcOpticalFlowPyrLK(frame, reference, flow.at, back, back_ok, error, window, options.pyramid_levels, stop,
                           cv::OPTFLOW_USE_INITIAL_FLOW);
  const int size = reference.cols;
  flow.round_trip.assign(from.size(), std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < from.size(); ++i) {
    const Vec2 w = to_disk(flow.at[i], size);
    if (!flow.ok[i] || !back_ok[i] || !w.allFinite() || w.norm() > 0.98) {
      flow.ok[i] = 0;
      continue;
    }
    flow.round_trip[i] = (to_disk(back[i], size) - to_disk(from[i], size)).norm();
  }
  return flow;
}

}  // namespace

std::vector<double> TrackedPoints::confidence() const {
  std::vector<double> c;
  c.reserve(round_trip.size());
  // The scale: half the round trip allowed by default (0.005 disk units).
  for (double e : round_trip) c.push_back(1 / (1 + (e / 0.005) * (e / 0.005)));
  return c;
}

DiskFeatures disk_features(const DiskMap& map, int size, const std::vector<FilledHole>& holes) {
  const TriangleMesh& surface = map.surface;
  const size_t n = surface.positions.size();
  if (size < 16) throw Error(ErrorCode::kInvalidArgument, "disk features: image size " + std::to_string(size) + " is below 16");
  if (n == 0 || map.disk.size() != n || surface.faces.empty())
    throw Error(ErrorCode::kInvalidArgument, "disk features: the map's surface and disk disagree");
  const double diagonal = bounding_box_diagonal(surface.positions);
  std::vector<bool> boundary(n, false);
  for (int v : map.rim) boundary[static_cast<size_t>(v)] = true;
  const Eigen::VectorXd h = mean_curvature(surface.positions, surface.faces, boundary);
  const Eigen::VectorXd lambda = conformal_factor(map);
  std::vector<float> vh(n), vl(n);
  for (size_t v = 0; v < n; ++v) {
    vh[v] = static_cast<float>(h[static_cast<Eigen::Index>(v)] * diagonal);
    vl[v] = static_cast<float>(std::log(std::max(lambda[static_cast<Eigen::Index>(v)] / diagonal, 1e-12)));
  }
  std::vector<uint8_t> fill(n, 0);
  for (size_t v = 0; v < n && !holes.empty(); ++v) {
    const int source = v < map.source_vertex.size() ? map.source_vertex[v] : -1;
    for (const FilledHole& hole : holes) {
      if (source >= hole.first_vertex && source < hole.first_vertex + hole.vertex_count) fill[v] = 1;
    }
  }
  DiskFeatures f;
  f.size = size;
  const auto texels = static_cast<size_t>(size) * static_cast<size_t>(size);
  const float none = std::numeric_limits<float>::quiet_NaN();
  f.curvature.assign(texels, none);
  f.log_factor.assign(texels, none);
  f.hole.assign(texels, 0);
  f.vertices.assign(texels, 0);
  for (const Vec2& w : map.disk) {
    const cv::Point2f t = to_texel(w, size);
    const int x = std::clamp(static_cast<int>(std::lround(t.x)), 0, size - 1),
              y = std::clamp(static_cast<int>(std::lround(t.y)), 0, size - 1);
    uint8_t& c = f.vertices[static_cast<size_t>(y) * size + x];
    if (c < 255) ++c;
  }
  // Each disk triangle's texels, its corners' values interpolated.
  for (const Face& face : surface.faces) {
    cv::Point2f t[3];
    for (int k = 0; k < 3; ++k) t[k] = to_texel(map.disk[static_cast<size_t>(face[k])], size);
    const double area = (t[1].x - t[0].x) * (t[2].y - t[0].y) - (t[1].y - t[0].y) * (t[2].x - t[0].x);
    if (std::abs(area) < 1e-12) continue;
    const uint8_t in_hole = fill[static_cast<size_t>(face[0])] | fill[static_cast<size_t>(face[1])] | fill[static_cast<size_t>(face[2])];
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({t[0].x, t[1].x, t[2].x}))));
    const int x1 = std::min(size - 1, static_cast<int>(std::floor(std::max({t[0].x, t[1].x, t[2].x}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({t[0].y, t[1].y, t[2].y}))));
    const int y1 = std::min(size - 1, static_cast<int>(std::floor(std::max({t[0].y, t[1].y, t[2].y}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        double b[3];
        for (int k = 0; k < 3; ++k) {
          const cv::Point2f &p = t[(k + 1) % 3], &q = t[(k + 2) % 3];
          b[k] = ((q.x - p.x) * (y - p.y) - (q.y - p.y) * (x - p.x)) / area;
        }
        if (b[0] < -1e-9 || b[1] < -1e-9 || b[2] < -1e-9) continue;
        double sh = 0, sl = 0;
        for (int k = 0; k < 3; ++k) {
          sh += b[k] * vh[static_cast<size_t>(face[k])];
          sl += b[k] * vl[static_cast<size_t>(face[k])];
        }
        const size_t at = static_cast<size_t>(y) * size + x;
        f.curvature[at] = static_cast<float>(sh);
        f.log_factor[at] = static_cast<float>(sl);
        f.hole[at] = in_hole;
      }
    }
  }
  // Texels the triangles miss (beyond the rim's chords, outside the disk): the nearest covered
  // texel inward along the ray to the centre.
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const size_t at = static_cast<size_t>(y) * size + x;
      if (!std::isnan(f.curvature[at])) continue;
      const Vec2 w = to_disk(cv::Point2f(static_cast<float>(x), static_cast<float>(y)), size);
      const double r = w.norm();
      float h_value = 0, l_value = 0;
      for (double s = std::min(r, 1.0); s > 0; s -= 0.5 / size) {
        const cv::Point2f t = to_texel(r > 0 ? Vec2(w * (s / r)) : Vec2(w), size);
        const int tx = std::clamp(static_cast<int>(std::lround(t.x)), 0, size - 1),
                  ty = std::clamp(static_cast<int>(std::lround(t.y)), 0, size - 1);
        const size_t from = static_cast<size_t>(ty) * size + tx;
        if (!std::isnan(f.curvature[from])) {
          h_value = f.curvature[from];
          l_value = f.log_factor[from];
          f.hole[at] = f.hole[from];
          break;
        }
      }
      f.curvature[at] = h_value;
      f.log_factor[at] = l_value;
    }
  }
  return f;
}

std::vector<Vec2> tracking_grid(const TrackingOptions& options) {
  std::vector<Vec2> points;
  if (!(options.spacing > 0) || !(options.max_radius > 0)) return points;
  const int steps = static_cast<int>(std::floor(options.max_radius / options.spacing));
  for (int j = steps; j >= -steps; --j) {
    for (int i = -steps; i <= steps; ++i) {
      const Vec2 w(i * options.spacing, j * options.spacing);
      if (w.norm() <= options.max_radius) points.push_back(w);
    }
  }
  return points;
}

TrackedPoints track_points(const DiskFeatures& reference, const DiskFeatures& frame, const std::vector<Vec2>& points,
                           const std::vector<Vec2>& start, const TrackingOptions& options) {
  if (reference.size != frame.size || reference.size < 16)
    throw Error(ErrorCode::kInvalidArgument, "track_points: features of different sizes");
  if (!start.empty() && start.size() != points.size()) throw Error(ErrorCode::kInvalidArgument, "track_points: one start per point needed");
  if (options.window < 3 || options.window % 2 == 0 || options.pyramid_levels < 0) {
    throw Error(ErrorCode::kInvalidArgument, "track_points: the window must be odd and at least 3, the pyramid levels >= 0");
  }
  TrackedPoints out;
  out.tried = static_cast<int>(points.size());
  if (points.empty()) return out;
  const int size = reference.size;
  const Scale curvature = channel_scale(reference.curvature, size);
  Scale factor = channel_scale(reference.log_factor, size);
  // Contrast w about mid-grey: value·g·w + (o − 127.5)·w + 127.5.
  const auto w = static_cast<float>(options.log_factor_weight);
  factor = {(factor.offset - 127.5f) * w + 127.5f, factor.gain * w};
  const cv::Mat a = to_image(reference, curvature, factor, options.blur), b = to_image(frame, curvature, factor, options.blur);
  std::vector<cv::Point2f> from, guess;
  for (const Vec2& p : points) from.push_back(to_texel(p, size));
  // Points whose window the reference's mesh does not resolve are not tracked.
  std::vector<uint8_t> resolved(points.size(), 1);
  if (options.min_window_vertices > 0 && reference.vertices.size() == static_cast<size_t>(size) * size) {
    const int half = options.window / 2;
    for (size_t i = 0; i < points.size(); ++i) {
      const int cx = static_cast<int>(std::lround(from[i].x)), cy = static_cast<int>(std::lround(from[i].y));
      int count = 0;
      for (int y = std::max(0, cy - half); y <= std::min(size - 1, cy + half); ++y) {
        for (int x = std::max(0, cx - half); x <= std::min(size - 1, cx + half); ++x)
          count += reference.vertices[static_cast<size_t>(y) * size + x];
      }
      if (count < options.min_window_vertices) resolved[i] = 0, ++out.unresolved;
    }
  }
  // From the point itself (the disks are normalised alike), and from the start given; the better
  // round trip wins.
  Flow best = lucas_kanade(a, b, from, from, options);
  if (!start.empty()) {
    for (const Vec2& s : start) guess.push_back(to_texel(s, size));
    const Flow warm = lucas_kanade(a, b, from, guess, options);
    for (size_t i = 0; i < from.size(); ++i) {
      if (warm.ok[i] && (!best.ok[i] || warm.round_trip[i] < best.round_trip[i])) {
        best.at[i] = warm.at[i];
        best.ok[i] = 1;
        best.round_trip[i] = warm.round_trip[i];
      }
    }
  }
  std::vector<int> kept;
  for (size_t i = 0; i < from.size(); ++i) {
    if (resolved[i] && best.ok[i] && (!options.check_round_trip || best.round_trip[i] <= options.max_round_trip))
      kept.push_back(static_cast<int>(i));
  }
  out.lost = out.tried - out.unresolved - static_cast<int>(kept.size());
  if (options.check_round_trip && options.min_gain > 0) {
    // The windows' squared differences, at the tracked point and at the point itself.
    cv::Mat fa, fb;
    a.convertTo(fa, CV_32F);
    b.convertTo(fb, CV_32F);
    cv::Mat pa[2], pb[2];
    cv::split(fa, pa);
    cv::split(fb, pb);
    const cv::Size window(options.window, options.window);
    auto difference = [&](const cv::Point2f& at_reference, const cv::Point2f& at_frame) {
      double sum = 0;
      for (int c = 0; c < 2; ++c) {
        cv::Mat r, f;
        cv::getRectSubPix(pa[c], window, at_reference, r);
        cv::getRectSubPix(pb[c], window, at_frame, f);
        sum += cv::norm(r, f, cv::NORM_L2SQR);
      }
      return sum;
    };
    std::vector<int> gained;
    for (int i : kept) {
      const auto k = static_cast<size_t>(i);
      if (difference(from[k], best.at[k]) <= options.min_gain * difference(from[k], from[k])) {
        gained.push_back(i);
      } else {
        ++out.no_gain;
      }
    }
    kept = std::move(gained);
  }
  // The neighbour check: a kept point's displacement against the median of its kept neighbours'.
  std::vector<Vec2> moved(points.size(), Vec2::Zero());
  for (int i : kept) moved[static_cast<size_t>(i)] = to_disk(best.at[static_cast<size_t>(i)], size) - points[static_cast<size_t>(i)];
  const double reach = 2.5 * options.spacing;
  std::vector<int> good;
  for (int i : kept) {
    std::vector<double> dx, dy;
    if (options.check_round_trip) {
      for (int j : kept) {
        if (j == i || (points[static_cast<size_t>(j)] - points[static_cast<size_t>(i)]).norm() > reach) continue;
        dx.push_back(moved[static_cast<size_t>(j)].x());
        dy.push_back(moved[static_cast<size_t>(j)].y());
      }
    }
    if (dx.size() >= 3) {
      std::nth_element(dx.begin(), dx.begin() + static_cast<std::ptrdiff_t>(dx.size() / 2), dx.end());
      std::nth_element(dy.begin(), dy.begin() + static_cast<std::ptrdiff_t>(dy.size() / 2), dy.end());
      const Vec2 median(dx[dx.size() / 2], dy[dy.size() / 2]);
      if ((moved[static_cast<size_t>(i)] - median).norm() > options.max_neighbour_disagreement) {
        ++out.outliers;
        continue;
      }
    }
    good.push_back(i);
  }
  for (int i : good) {
    out.reference.push_back(points[static_cast<size_t>(i)]);
    out.frame.push_back(points[static_cast<size_t>(i)] + moved[static_cast<size_t>(i)]);
    out.round_trip.push_back(best.round_trip[static_cast<size_t>(i)]);
    out.index.push_back(i);
  }
  return out;
}

std::vector<TrackedPoints> track_sequence(size_t count, size_t reference, const std::function<DiskFeatures(size_t)>& features,
                                          const TrackingOptions& options, int threads) {
  std::vector<TrackedPoints> result(count);
  if (count == 0) return result;
  if (reference >= count) throw Error(ErrorCode::kInvalidArgument, "track_sequence: the reference is not a frame");
  const std::vector<Vec2> grid = tracking_grid(options);
  const DiskFeatures own = features(reference);
  TrackedPoints& identity = result[reference];
  identity.reference = identity.frame = grid;
  identity.round_trip.assign(grid.size(), 0.0);
  identity.tried = static_cast<int>(grid.size());
  for (size_t i = 0; i < grid.size(); ++i) identity.index.push_back(static_cast<int>(i));
  // Frames after the reference, then those before it, each in order away from it; drawn a chunk at
  // a time in parallel, tracked one after another (each starts from the one before).
  constexpr size_t kChunk = 16;
  for (const int direction : {+1, -1}) {
    std::vector<Vec2> last = grid;  // where each point was last seen
    std::vector<size_t> order;
    for (auto i = static_cast<std::ptrdiff_t>(reference) + direction; i >= 0 && i < static_cast<std::ptrdiff_t>(count); i += direction)
      order.push_back(static_cast<size_t>(i));
    for (size_t begin = 0; begin < order.size(); begin += kChunk) {
      const size_t end = std::min(order.size(), begin + kChunk);
      std::vector<DiskFeatures> drawn(end - begin);
      parallel_for(static_cast<int>(end - begin), threads,
                   [&](int k) { drawn[static_cast<size_t>(k)] = features(order[begin + static_cast<size_t>(k)]); });
      for (size_t k = begin; k < end; ++k) {
        TrackedPoints t = track_points(own, drawn[k - begin], grid, last, options);
        for (size_t j = 0; j < t.index.size(); ++j) last[static_cast<size_t>(t.index[j])] = t.frame[j];
        result[order[k]] = std::move(t);
      }
    }
  }
  return result;
}

bool needs_tracked_points(const Capture& capture, size_t reference, size_t frame) {
  if (reference >= capture.landmarks.size() || frame >= capture.landmarks.size()) return true;
  return needs_tracked_points(capture.landmark_names, capture.landmarks[reference], capture.landmarks[frame]);
}

bool needs_tracked_points(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const std::vector<Vec3>& frame) {
  int shared = 0;
  for (size_t l = 0; l < names.size(); ++l) {
    const std::string& name = names[l];
    if (name.rfind("rim_", 0) == 0 || name == "nose_tip" || name == "nose_bridge" || name == "between_eyes") continue;
    if (reference[l].allFinite() && frame[l].allFinite()) ++shared;
  }
  return shared < 3;
}

void add_tracked_points(DiskLandmarks& landmarks, const TrackedPoints& tracked) {
  if (tracked.reference.empty()) return;
  const size_t given = landmarks.reference.size();
  if (landmarks.weights.empty()) landmarks.weights.assign(given, 1.0);
  if (landmarks.on_rim.empty()) landmarks.on_rim.assign(given, 0);
  const std::vector<double> confidence = tracked.confidence();
  // A tracked point on top of a given landmark (the nose tip is the disk's centre) would make the
  // pair coincide: the given landmark speaks there.
  double spacing = 1;
  for (size_t i = 0; i < tracked.reference.size(); ++i) {
    for (size_t j = 0; j < i; ++j) spacing = std::min(spacing, (tracked.reference[i] - tracked.reference[j]).norm());
  }
  for (size_t i = 0; i < tracked.reference.size(); ++i) {
    bool near = false;
    for (size_t j = 0; j < given && !near; ++j) near = (landmarks.reference[j] - tracked.reference[i]).norm() < 0.5 * spacing;
    if (near) continue;
    landmarks.reference.push_back(tracked.reference[i]);
    landmarks.frame.push_back(tracked.frame[i]);
    landmarks.weights.push_back(confidence[i]);
    landmarks.on_rim.push_back(0);
  }
}

}  // namespace facemorph
