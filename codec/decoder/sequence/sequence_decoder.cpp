// Playing a sequence back at any t (spec/method.md §7): blend, reconstruct, cut holes, place.
#include "codec/decoder/sequence/sequence_decoder.hpp"

#include "codec/decoder/sequence/hole_cut.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace facemorph {

namespace {

// Σ w_i · values of the i-th key of `weights`, for arrays of one length; `zero` is T's zero (Eigen
// leaves T{} unset).
template <typename T, typename Get>
std::vector<T> blend(const SplineWeights& weights, const T& zero, Get&& get) {
  std::vector<T> out(get(size_t{0}).size(), zero);
  for (size_t i = 0; i < weights.keys.size(); ++i) {
    const auto& values = get(i);
    const double w = weights.weights[i];
    for (size_t j = 0; j < out.size(); ++j) out[j] += w * values[j];
  }
  return out;
}

}  // namespace

SequenceDecoder::SequenceDecoder(std::shared_ptr<const Sequence> sequence) : SequenceDecoder(memory_source(std::move(sequence))) {}

SequenceDecoder::SequenceDecoder(std::shared_ptr<const KeyframeSource> source)
    : source_(source ? std::move(source) : throw Error(ErrorCode::kInvalidArgument, "sequence decoder: no source")),
      spline_(source_->outline().times, source_->outline().spline),
      reconstructor_(source_->grid_geometry()),
      rotation_vectors_(unwrap_rotations(source_->outline().poses)),
      keyframe_surfaces_(source_->outline().keyframe_count()),
      keyframe_failures_(source_->outline().keyframe_count()) {
  const int keys = residual_max_keys(spline_, source_->outline().residuals);
  if (source_->surfaces_kept() < static_cast<size_t>(keys)) {
    throw Error(ErrorCode::kLimit, "sequence decoder: the source lets a decoder keep " + std::to_string(source_->surfaces_kept()) +
                                       " keyframe surfaces; a frame of its spline needs up to " + std::to_string(keys));
  }
}

ReconstructSuspension& SequenceDecoder::suspension_for(bool keyframe, size_t k, double t, const ReconstructOptions& o) {
  Pending& p = pending_;
  const bool same = p.keyframe == keyframe && (keyframe ? p.k == k : p.t == t) && p.max_iterations == o.max_iterations &&
                    p.anderson_depth == o.anderson_depth && p.stall_iterations == o.stall_iterations && p.tolerance == o.tolerance &&
                    p.damping == o.damping;
  if (!same) {
    p.state.clear();  // another reconstruction's: it starts over when next needed
    p.keyframe = keyframe;
    p.k = k;
    p.t = t;
    p.max_iterations = o.max_iterations;
    p.anderson_depth = o.anderson_depth;
    p.stall_iterations = o.stall_iterations;
    p.tolerance = o.tolerance;
    p.damping = o.damping;
  }
  return p.state;
}

std::shared_ptr<const std::vector<Vec3>> SequenceDecoder::keyframe_surface(size_t k, const GridFields& fields,
                                                                           const ReconstructOptions& options, WorkMeter& work) {
  if (!keyframe_failures_[k].empty()) throw Error(ErrorCode::kCorrupt, keyframe_failures_[k]);
  std::shared_ptr<const std::vector<Vec3>>& surface = keyframe_surfaces_[k];
  if (surface) {
    surface_order_.erase(std::find(surface_order_.begin(), surface_order_.end(), k));
    surface_order_.insert(surface_order_.begin(), k);
    return surface;
  }
  // Cold, from the harmonic surface: the keyframe's own fields, exactly what the encoder stored (so a
  // surface dropped and made again is the same surface).
  ReconstructOptions cold = options;
  cold.start = nullptr;
  cold.work = &work;
  cold.suspended = &suspension_for(true, k, 0, options);
  reconstructor_.forget_warm_start();
  if (!cold.suspended->held()) ++keyframe_reconstructions_;  // one going on is counted once
  try {
    surface = std::make_shared<const std::vector<Vec3>>(reconstructor_.reconstruct(fields, cold).positions);
  } catch (const Error& e) {
    if (work.stopped() || (e.code() != ErrorCode::kNotConverged && e.code() != ErrorCode::kNumerical)) throw;
    // The encoder reconstructed every keyframe it wrote: one that does not is a corrupt file.
    keyframe_failures_[k] = source_->name() + ": keyframe " + std::to_string(k) + " cannot be reconstructed (a corrupt file): " + e.what();
    throw Error(ErrorCode::kCorrupt, keyframe_failures_[k]);
  }
  surface_order_.insert(surface_order_.begin(), k);
  // The caller holds the surfaces of this frame's keys, so dropping the oldest frees only others'.
  while (surface_order_.size() > source_->surfaces_kept()) {
    keyframe_surfaces_[surface_order_.back()].reset();
    surface_order_.pop_back();
  }
  return surface;
}

std::vector<Vec3> SequenceDecoder::predicted_start(double t, const std::vector<Vec3>& start, const DecodeOptions& options) const {
  // Only from frames of the same clip: within two of the capture's frame periods of t and of each
  // other. A jump in t (seeking, another rate) starts from the spline alone, as any first frame.
  const double near = 2 / outline().fps;
  const auto& h = history_;
  if (!options.continue_correction || h.count == 0 || !(std::abs(t - h.time[0]) <= near) || t == h.time[0]) return {};
  std::vector<Vec3> guess = start;
  const std::vector<Vec3>& d1 = h.correction[0];
  if (h.count >= 2 && std::abs(h.time[0] - h.time[1]) <= near && h.time[0] != h.time[1]) {
    // δ(t) ≈ δ₁ + (t − t₁)/(t₁ − t₂) (δ₁ − δ₂): the correction continued linearly.
    const double s = (t - h.time[0]) / (h.time[0] - h.time[1]);
    const std::vector<Vec3>& d2 = h.correction[1];
    for (size_t v = 0; v < guess.size(); ++v) guess[v] += d1[v] + s * (d1[v] - d2[v]);
  } else {
    for (size_t v = 0; v < guess.size(); ++v) guess[v] += d1[v];
  }
  return guess;
}

void SequenceDecoder::remember_correction(double t, const ReconstructResult& result, const std::vector<Vec3>& start) {
  if (!result.converged) {
    history_.count = 0;  // no correction to continue from a surface that did not settle
    return;
  }
  std::swap(history_.correction[0], history_.correction[1]);
  history_.time[1] = history_.time[0];
  std::vector<Vec3>& d = history_.correction[0];
  d.resize(start.size());
  for (size_t v = 0; v < start.size(); ++v) d[v] = result.positions[v] - start[v];
  history_.time[0] = t;
  history_.count = std::min(history_.count + 1, 2);
}

ReconstructResult SequenceDecoder::reconstruct_frame(double t, const GridFields& fields, ReconstructOptions options, WorkMeter& work) {
  options.work = &work;
  options.suspended = &suspension_for(false, 0, t, options);
  return reconstructor_.reconstruct(fields, options);
}

namespace {

// "t = 1.45 s" for messages.
std::string time_text(double t) {
  char text[48];
  std::snprintf(text, sizeof text, "t = %.6g s", t);
  return text;
}

}  // namespace

DecodedFrame SequenceDecoder::decode(double t, const DecodeOptions& options) {
  if (!std::isfinite(t)) throw Error(ErrorCode::kInvalidArgument, "decode: t is not finite");
  WorkMeter work(options.max_work.value_or(source_->work_limit()), source_->name() + ": " + time_text(t));
  try {
    return decode_metered(t, options, work);
  } catch (const Error& e) {
    // A failure names the file and t (the work meter's and the range's already do); what the
    // source threw names the file and the chunk, and gets t after the file's name.
    if (work.stopped() || e.code() == ErrorCode::kOutOfRange) throw;
    const std::string name = source_->name(), message = e.what();
    if (message.rfind(name + ": ", 0) == 0) throw Error(e.code(), name + ": " + time_text(t) + ": " + message.substr(name.size() + 2));
    throw Error(e.code(), name + ": " + time_text(t) + ": " + message);
  }
}

DecodedFrame SequenceDecoder::decode_metered(double t, const DecodeOptions& options, WorkMeter& work) {
  const auto [lo, hi] = spline_.sane_range();  // TimeRange
  if ((t < lo || t > hi) && !options.ignore_sane_range) {
    if (!options.clamp_to_sane_range) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "t = %.4g s is outside the range this sequence can serve, [%.4g, %.4g] s (keyframes span [%.4g, %.4g] s)", t, lo, hi,
                    outline().times.front(), outline().times.back());
      throw Error(ErrorCode::kOutOfRange, text);
    }
    t = std::clamp(t, lo, hi);
  }
  const SequenceOutline& outline = source_->outline();
  DecodedFrame frame;
  frame.time = t;
  // The shape blends with the residuals' correction (format 2.3); the head pose with the spline's
  // own weights, so that a residual reshapes the face without moving the head.
  const SplineWeights spline_weights = spline_.weights(t);
  frame.weights = outline.residuals.empty() ? spline_weights : residual_weights(spline_, outline.residuals, t);
  const SplineWeights& w = frame.weights;

  // The keyframes this frame blends, held for the call (the source may drop them from its cache).
  std::vector<std::shared_ptr<const Keyframe>> held;
  std::vector<const GridFields*> keys;
  for (int32_t k : w.keys) {
    held.push_back(source_->keyframe(static_cast<size_t>(k), work));
    keys.push_back(&held.back()->fields);
  }
  const GridFields fields = combine_fields(keys, w.weights);
  // Start from the spline of the keyframes' own surfaces: they are the fixed points of their
  // fields, so the blend is close wherever t lies.
  std::vector<std::shared_ptr<const std::vector<Vec3>>> surfaces;
  for (size_t i = 0; i < w.keys.size(); ++i)
    surfaces.push_back(keyframe_surface(static_cast<size_t>(w.keys[i]), held[i]->fields, options.reconstruct, work));
  const std::vector<Vec3> start = blend<Vec3>(w, Vec3::Zero(), [&](size_t i) -> const std::vector<Vec3>& { return *surfaces[i]; });
  // Playing a clip, the previous frames tell how far the reconstruction lands from that spline:
  // the correction δ = S − start is smooth in t (and zero at keyframes), so continuing it from the
  // last two frames starts closer still (N = 257 sample at 30 fps: 5.4 -> 4.1 steps a frame).
  const std::vector<Vec3> guess = predicted_start(t, start, options);
  ReconstructOptions ro = options.reconstruct;
  ro.start = guess.empty() ? &start : &guess;
  ro.throw_on_failure = false;
  ReconstructResult result = reconstruct_frame(t, fields, ro, work);
  remember_correction(t, result, start);
  frame.iterations = result.iterations;
  frame.converged = result.converged;
  frame.change = result.change;
  if (!result.converged) {
    // Blended fields need not be the fields of any surface (between keyframes they are not:
    // Gauss-Codazzi does not blend), and where the iteration then keeps moving — measured on
    // Medusa with cubic splines whose weights overshoot: a region near an eyelid swinging by
    // ~1% of the face — its iterate is no surface to show. The spline of the keyframes' own
    // surfaces is: the start, which the encoder's keyframe selection measured.
    if (options.reconstruct.throw_on_failure && !options.fall_back_to_start) {
      throw Error(ErrorCode::kNotConverged,
                  "the reconstruction did not converge (last change " + std::to_string(result.change) + " of the rim diameter)");
    }
    if (options.fall_back_to_start) {
      result.positions = start;
      frame.fell_back = true;
    }
  }

  // Frame patches (format 2.4): the displacement, in the face frame, where the blend misses the
  // captured shape; added after the correction history is kept, so the next frame's start is the
  // reconstruction's own (a patch moves the surface shown, not the fields).
  const DiskGrid& grid = reconstructor_.geometry().grid();
  const std::vector<Vec3> patch = frame_patch_displacements(outline.times, outline.patches, t, grid.nodes);
  for (size_t v = 0; v < patch.size(); ++v) result.positions[v] += patch[v];
  frame.pose = blend_poses(outline.poses, rotation_vectors_, spline_weights, outline.pose_centre);
  frame.grid_positions.resize(result.positions.size());
  for (size_t v = 0; v < result.positions.size(); ++v) frame.grid_positions[v] = frame.pose.apply(result.positions[v]);
  // A file can pass every check of its own numbers and still decode to overflow (a λ that grows
  // the surface past float range, weights that cancel badly): no frame leaves the decoder with a
  // number a float cannot hold (spec/container.md §10.4). The mesh's points lie between these.
  constexpr double kFloatMax = 3.4028234663852886e38;
  for (const Vec3& p : frame.grid_positions) {
    if (!(std::abs(p.x()) < kFloatMax && std::abs(p.y()) < kFloatMax && std::abs(p.z()) < kFloatMax)) {
      throw Error(ErrorCode::kCorrupt,
                  "the file decodes to positions beyond float range or not finite (a corrupt file)");  // decode() adds t
    }
  }

  if (outline.has_holes) {
    frame.hole_level = blend<double>(w, 0.0, [&](size_t i) -> const std::vector<double>& { return held[i]->hole_level; });
  }
  if (options.cut_holes && outline.has_holes) {
    frame.mesh = cut_holes(grid, frame.grid_positions, frame.hole_level);
  } else {
    frame.mesh = grid_mesh(grid, frame.grid_positions);
  }
  if (options.texture && outline.has_texture()) {
    std::vector<std::shared_ptr<const Image>> textures;
    std::vector<const Image*> images;
    for (int32_t k : w.keys) {
      textures.push_back(source_->texture(static_cast<size_t>(k), work));
      images.push_back(textures.back().get());
    }
    frame.texture = blend_images(images, w.weights);
  }
  return frame;
}

}  // namespace facemorph
