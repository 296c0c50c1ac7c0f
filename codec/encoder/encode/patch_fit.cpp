// Fitting a frame patch against what the decoder shows (spec/method.md §7.19).
#include "codec/encoder/encode/patch_fit.hpp"

#include "codec/core/container/file_layout.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/decoder/sequence/hole_cut.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/decoder_team.hpp"
#include "codec/encoder/encode/patch_measure.hpp"
#include "codec/encoder/encode/patch_solve.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/byte_writer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>

namespace facemorph {

TriangleMesh shown_mesh(const DiskGrid& grid, const std::vector<Vec3>& positions, const std::vector<double>& hole_level) {
  return hole_level.empty() ? grid_mesh(grid, positions) : cut_holes(grid, positions, hole_level);
}

std::vector<Vec3> patched_positions(const DiskGrid& grid, const ShownFrame& shown, const FramePatch& patch) {
  std::vector<Vec3> out = shown.positions;
  if (patch.nodes.empty()) return out;
  // One patch alone at its own time: frame_patch_displacements with the patch on both sides.
  const std::vector<Vec3> d = frame_patch_displacements({patch.time - 1, patch.time + 1}, {patch}, patch.time, grid.nodes);
  for (size_t n = 0; n < out.size(); ++n) out[n] += shown.pose.rotation * d[n];
  return out;
}

namespace {

// The patch moving the lattice nodes near samples whose offset passes `threshold` (capture units),
// fitted in two rounds (the second against the surface the first moved), rounded to `step` (units).
// `first`: the sums of measure.samples() on options.lattice.
FramePatch fit_at_threshold(const PatchMeasure& measure, const PatchNormalSums& first, double t, double threshold, double step,
                            const PatchFitOptions& options) {
  const ShownFrame& shown = measure.shown();
  const std::vector<OffsetSample>& first_samples = measure.samples();
  const int lattice = options.lattice;
  std::vector<int> index(static_cast<size_t>(lattice) * static_cast<size_t>(lattice), -1);
  for (const OffsetSample& s : first_samples) {
    if (s.offset.norm() <= threshold) continue;
    const int i = patch_cell_of(s.w.x(), lattice).first, j = patch_cell_of(s.w.y(), lattice).first;
    for (const int node : {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1})
      index[static_cast<size_t>(node)] = 0;
  }
  std::vector<int32_t> nodes;
  for (size_t n = 0; n < index.size(); ++n) {
    if (index[n] < 0) continue;
    index[n] = static_cast<int>(nodes.size());
    nodes.push_back(static_cast<int32_t>(n));
  }
  FramePatch patch{.time = t, .lattice = lattice, .nodes = {}, .displacements = {}};
  if (nodes.empty()) return patch;
  const int unknowns = static_cast<int>(nodes.size());
  // Capture coordinates while fitting; the file holds the face frame's (the pose's rotation undone).
  std::vector<Vec3> total = first.solve(index, unknowns, options.smoothing);
  FramePatch trial = patch;
  trial.nodes = nodes;
  const Eigen::Matrix3d to_face = shown.pose.rotation.transpose();
  for (const Vec3& d : total) trial.displacements.push_back(to_face * d);
  const TriangleMesh moved = measure.patched(trial);
  const std::vector<OffsetSample> second = measure.samples_of(moved);
  const std::vector<Vec3> more = PatchNormalSums(second, lattice, &index).solve(index, unknowns, options.smoothing);
  for (int p = 0; p < unknowns; ++p) {
    const Vec3 code = (to_face * (total[static_cast<size_t>(p)] + more[static_cast<size_t>(p)]) / step).array().round();
    if (code.isZero()) continue;
    patch.nodes.push_back(nodes[static_cast<size_t>(p)]);
    patch.displacements.push_back(code * step);
  }
  return patch;
}

}  // namespace

namespace {

// fit_frame_patch with the frame's measure (built once for all the lattices and steps it tries).
PatchFit fit_measured(const PatchMeasure& measure, double t, const PatchFitOptions& options) {
  const double diagonal = measure.diagonal();
  PatchFit best;
  best.patch = FramePatch{.time = t, .lattice = options.lattice, .nodes = {}, .displacements = {}};
  best.p99_before = best.p99_after = measure.p99_before() / diagonal;
  if (best.p99_before <= options.bound) return best;
  // The search measures approximately (PatchMeasure::approximate); a patch it takes is measured
  // exactly, and one the exact measure puts over the bound is passed over for the next try.
  const auto exact_meets = [&](const FramePatch& patch, double& p99) {
    p99 = measure.exact(patch) / diagonal;
    ++best.exact_checks;
    best.approximate_misses += p99 > options.bound;
    return p99 <= options.bound;
  };
  FramePatch nearest;  // of the tries none of which met the bound, the lowest approximate p99
  double nearest_p99 = best.p99_before;
  bool met = false;
  // Every threshold's first solve sums the same samples: gathered once.
  const PatchNormalSums first(measure.samples(), options.lattice);
  for (const double share : {1.0, 0.9, 0.8, 0.65, 0.5, 0.4, 0.3}) {
    const double threshold = share * options.bound;
    FramePatch patch = fit_at_threshold(measure, first, t, threshold * diagonal, options.step_units, options);
    const double approximate = measure.approximate(patch) / diagonal;
    double exact = 0;
    if (approximate <= options.bound && exact_meets(patch, exact)) {
      best.patch = std::move(patch);
      best.p99_after = exact;
      best.threshold = threshold;
      met = true;
      break;
    }
    if (approximate < nearest_p99) {
      nearest = std::move(patch);
      nearest_p99 = approximate;
      best.threshold = threshold;
    }
  }
  if (!met) {
    if (!nearest.nodes.empty()) {
      const double exact = measure.exact(nearest) / diagonal;
      if (exact < best.p99_after) {
        best.patch = std::move(nearest);
        best.p99_after = exact;
      }
    }
    return best;
  }
  return best;
}

}  // namespace

PatchFit fit_frame_patch(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, double t,
                         const PatchFitOptions& options) {
  const TriangleMesh before = shown_mesh(grid, shown.positions, shown.hole_level);
  return fit_measured(PatchMeasure(grid, shown, captured, before), t, options);
}

std::vector<uint8_t> patch_payload(const FramePatch& patch, double step_units) {
  format::ByteWriter w;
  file_layout::write_varint(w, static_cast<int64_t>(patch.nodes.size()));
  int32_t previous = -1;
  for (size_t n = 0; n < patch.nodes.size(); ++n) {
    file_layout::write_varint(w, patch.nodes[n] - previous - 1);
    previous = patch.nodes[n];
    for (int c = 0; c < 3; ++c) file_layout::write_varint(w, std::llround(patch.displacements[n][c] / step_units));
  }
  return w.take();
}

DecodeOptions shown_decode() {
  DecodeOptions o;
  o.texture = false;
  o.ignore_sane_range = true;
  o.continue_correction = false;  // each frame a function of t alone, as measured
  o.reconstruct.throw_on_failure = false;
  return o;
}

namespace {

// A frame between keyframes: its capture index, its time on the file's lattice, what it measured.
struct HeldFrame {
  int frame = 0;
  double time = 0;
  double diagonal = 0;
  double p99 = 0;  // decoded without patches, of the diagonal
};

}  // namespace

std::vector<char> frames_beside_pins(const std::vector<double>& key_times, const std::vector<FramePatch>& patches,
                                     const std::vector<double>& pins, const std::vector<double>& times) {
  std::vector<char> beside(times.size(), 0);
  const auto before = [](const FramePatch& f, double t) { return f.time < t; };
  const auto after = [](double t, const FramePatch& f) { return t < f.time; };
  for (size_t i = 0; i < times.size(); ++i) {
    const int interval = residual_interval(key_times, times[i]);
    const auto at = std::lower_bound(patches.begin(), patches.end(), times[i], before);
    if (interval < 0 || (at != patches.end() && at->time == times[i])) continue;  // a keyframe's, or holds a patch
    for (const double pin : pins) {
      if (residual_interval(key_times, pin) != interval) continue;
      // No patch strictly between the frame and the pin: the pin is its neighbour on that side.
      const double lo = std::min(pin, times[i]), hi = std::max(pin, times[i]);
      if (std::upper_bound(patches.begin(), patches.end(), lo, after) == std::lower_bound(patches.begin(), patches.end(), hi, before)) {
        beside[i] = 1;
        break;
      }
    }
  }
  return beside;
}

std::vector<FramePatch> fit_frame_patches(const Capture& capture, StoredSequence& stored, const std::vector<int>& keyframes, double bound,
                                          PatchFitReport* report_out, int threads, size_t kept_frames_memory) {
  const auto start = std::chrono::steady_clock::now();
  PatchFitReport report;
  stored.set_patches({});
  const SequenceOutline& outline = stored.outline();
  const std::vector<double>& key_times = outline.times;
  if (key_times.size() != keyframes.size())
    throw Error(ErrorCode::kInvalidArgument, "fit_frame_patches: the keyframes are not the stored sequence's");
  const auto read_frame = [&](int j) { return read_mesh(capture.mesh_path(static_cast<size_t>(j)), {.allow_missing_texture = true}); };
  // The fit measures against the captured meshes themselves; where they are not at hand (a staged
  // encode assembling parts made elsewhere) the file goes without patches, as before 2.4.
  for (const int j : {keyframes.front(), keyframes.back()}) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(capture.mesh_path(static_cast<size_t>(j)), ec)) {
      if (report_out) *report_out = report;
      return {};
    }
  }
  // Every frame strictly between two keyframes, at its time on the file's lattice.
  std::vector<HeldFrame> held;
  for (int j = keyframes.front() + 1; keyframes.size() >= 2 && j < keyframes.back(); ++j) {
    const double t = residual_time(residual_time_code(capture.frames[static_cast<size_t>(j)].time, outline.first_time, outline.fps),
                                   outline.first_time, outline.fps);
    if (residual_interval(key_times, t) < 0 || (!held.empty() && !(t > held.back().time))) continue;
    held.push_back({j, t, 0, 0});
  }
  if (held.empty()) {
    if (report_out) *report_out = report;
    return {};
  }
  // The captured frames' diagonals first: the rounding step is the smallest one's, set before any
  // fit. And the vertices their faces use, which the kept distances take.
  std::vector<size_t> anchors(held.size());
  parallel_for(static_cast<int>(held.size()), threads, [&](int i) {
    const TriangleMesh captured = read_frame(held[static_cast<size_t>(i)].frame);
    held[static_cast<size_t>(i)].diagonal = bounding_box_diagonal(captured.positions);
    std::vector<char> used(captured.positions.size(), 0);
    for (const Face& f : captured.faces)
      for (const int32_t v : f) used[static_cast<size_t>(v)] = 1;
    anchors[static_cast<size_t>(i)] = static_cast<size_t>(std::count(used.begin(), used.end(), 1));
  });
  double smallest = held.front().diagonal;
  for (const HeldFrame& f : held) smallest = std::min(smallest, f.diagonal);
  const double step = std::exp2(std::floor(std::log2(kPatchStepShare * bound * smallest)));
  const std::shared_ptr<const KeyframeSource> source(std::shared_ptr<void>(), &stored);  // not owned
  DecoderTeam team(source, threads, held.size());
  const DiskGrid& grid = team.first().geometry().grid();
  const DecodeOptions options = shown_decode();
  const auto show = [&](SequenceDecoder& decoder, double t) {
    DecodedFrame f = decoder.decode(t, options);
    return ShownFrame{std::move(f.grid_positions), std::move(f.hole_level), f.pose};
  };
  // Each frame is decoded and measured once, and kept with its distances (UnpatchedDistances) for
  // the pinning rounds where they fit in kept_frames_memory; past it, each round decodes and
  // measures the frames it measures again (the same frames: each a function of t alone).
  size_t kept_bytes = 0;
  for (const size_t a : anchors)
    kept_bytes += grid.nodes.size() * (sizeof(Vec3) + 2 * sizeof(double)) + a * (sizeof(int32_t) + sizeof(double));
  const bool keep = kept_bytes <= kept_frames_memory;
  struct KeptFrame {
    ShownFrame shown;
    UnpatchedDistances distances;
  };
  std::vector<KeptFrame> kept(keep ? held.size() : 0);
  // Pass 1, as each frame is measured: a patch for each frame over the bound.
  std::vector<PatchFit> fits(held.size());
  team.for_each(held.size(), [&](SequenceDecoder& decoder, size_t h) {
    ShownFrame shown = show(decoder, held[h].time);
    const TriangleMesh captured = read_frame(held[h].frame);
    const TriangleMesh before = shown_mesh(grid, shown.positions, shown.hole_level);
    const PatchMeasure measure(grid, shown, captured, before);
    held[h].p99 = measure.p99_before() / held[h].diagonal;
    if (held[h].p99 > bound) {
      PatchFit& best = fits[h];
      best.p99_after = held[h].p99;
      // The coarse step first; a frame it cannot bring under the bound tries finer ones (a power of
      // two apart: the chunk then codes every patch in the finest, whose codes take the same bytes).
      for (int finer = 0; finer < kPatchFinerSteps && best.p99_after > kPatchBoundMargin * bound; ++finer) {
        for (const int lattice : kPatchLattices) {
          PatchFit fit = fit_measured(measure, held[h].time,
                                      {.lattice = lattice, .bound = kPatchBoundMargin * bound, .step_units = std::ldexp(step, -finer)});
          if (!fit.patch.nodes.empty() && fit.p99_after < best.p99_after) best = std::move(fit);
          if (best.p99_after <= kPatchBoundMargin * bound) break;
        }
      }
    }
    if (keep) kept[h] = {std::move(shown), measure.distances()};
  });
  for (const HeldFrame& f : held) report.worst_before = std::max(report.worst_before, f.p99);
  std::vector<FramePatch> patches;
  std::vector<double> after(held.size());
  std::vector<char> patched(held.size(), 0);
  for (size_t h = 0; h < held.size(); ++h) {
    after[h] = held[h].p99;
    if (held[h].p99 <= bound) continue;
    ++report.frames_over;
    if (fits[h].patch.nodes.empty()) {
      ++report.frames_unmet;
      continue;
    }
    report.frames_unmet += fits[h].p99_after > bound;
    report.exact_checks += fits[h].exact_checks;
    report.approximate_misses += fits[h].approximate_misses;
    after[h] = fits[h].p99_after;
    patched[h] = 1;
    patches.push_back(std::move(fits[h].patch));
  }
  // frame h's p99 with the patches interpolated in t (PatchMeasure::exact: only what they move is
  // searched again).
  const auto p99_with_patches = [&](size_t h, const ShownFrame& shown, const UnpatchedDistances* distances) {
    const std::vector<Vec3> d = frame_patch_displacements(key_times, patches, held[h].time, grid.nodes);
    if (d.empty()) return held[h].p99;
    std::vector<Vec3> positions = shown.positions;
    for (size_t n = 0; n < d.size(); ++n) positions[n] += shown.pose.rotation * d[n];
    const TriangleMesh captured = read_frame(held[h].frame);
    const TriangleMesh before = shown_mesh(grid, shown.positions, shown.hole_level);
    const double p99 = distances ? PatchMeasure(grid, shown, captured, before, *distances).exact_at(positions)
                                 : PatchMeasure(grid, shown, captured, before).exact_at(positions);
    return p99 / held[h].diagonal;
  };
  // Pass 2: the frames between, with the patches interpolated in t; those made worse than the bound
  // and than their own p99 are pinned by empty patches (all of a round's at once, so that the result
  // does not depend on the order the threads measure in), until none is. A round after the first
  // measures only the frames beside its new pins (frames_beside_pins): the others' patches are as
  // the round before measured them.
  std::vector<double> times(held.size());
  for (size_t h = 0; h < held.size(); ++h) times[h] = held[h].time;
  std::vector<char> again(held.size(), 1);
  for (bool pinned = !patches.empty(); pinned;) {
    pinned = false;
    std::vector<size_t> moved;
    for (size_t h = 0; h < held.size(); ++h)
      if (again[h] && !patched[h] && residual_interval(key_times, held[h].time) >= 0) moved.push_back(h);
    std::vector<char> worse(held.size(), 0);
    const auto measure_moved = [&](size_t h, const ShownFrame& shown, const UnpatchedDistances* distances) {
      const double p99 = p99_with_patches(h, shown, distances);
      if (p99 <= bound || p99 <= held[h].p99)
        after[h] = p99;
      else
        worse[h] = 1;
    };
    if (keep) {
      parallel_for(static_cast<int>(moved.size()), threads, [&](int i) {
        const KeptFrame& k = kept[moved[static_cast<size_t>(i)]];
        measure_moved(moved[static_cast<size_t>(i)], k.shown, &k.distances);
      });
    } else {
      team.for_each(moved.size(), [&](SequenceDecoder& decoder, size_t i) { measure_moved(moved[i], show(decoder, held[moved[i]].time), nullptr); });
    }
    std::vector<double> pins;
    for (size_t h = 0; h < held.size(); ++h) {
      if (!worse[h]) continue;
      const auto at =
          std::upper_bound(patches.begin(), patches.end(), held[h].time, [](double t, const FramePatch& f) { return t < f.time; });
      patches.insert(at, FramePatch{.time = held[h].time, .lattice = kPatchLattices[0], .nodes = {}, .displacements = {}});
      pins.push_back(held[h].time);
      after[h] = held[h].p99;
      patched[h] = 1;
      ++report.frames_pinned;
      pinned = true;
    }
    again = frames_beside_pins(key_times, patches, pins, times);
  }
  for (const FramePatch& p : patches) {
    report.frames_patched += !p.nodes.empty();
    report.nodes += p.nodes.size();
  }
  for (double p99 : after) report.worst_after = std::max(report.worst_after, p99);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (report_out) *report_out = report;
  return patches;
}

}  // namespace facemorph
