// Fitting a frame patch against what the decoder shows (spec/method.md §7.19).
#include "codec/encoder/encode/patch_fit.hpp"

#include "codec/core/container/file_layout.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/decoder/sequence/hole_cut.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/byte_writer.hpp"

#include <Eigen/Sparse>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

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

// A point of one surface, where on the disk it lies and the offset to the other surface.
struct OffsetSample {
  Vec2 w;
  Vec3 offset;  // to the captured surface, capture coordinates
};

// Each captured vertex to the shown surface and each shown vertex to the captured one, as
// surface_distance measures them (vertices no face uses are left out), with the disk point of the
// shown side (the shown mesh's UV is (w + 1) / 2).
std::vector<OffsetSample> offset_samples(const TriangleMesh& shown, const TriangleMesh& captured) {
  std::vector<OffsetSample> samples;
  const auto disk = [&](int face, int corner) {
    return Vec2(2 * shown.uvs[static_cast<size_t>(shown.uv_faces[static_cast<size_t>(face)][static_cast<size_t>(corner)])] - Vec2(1, 1));
  };
  const PointToMesh to_shown(shown), to_captured(captured);
  std::vector<uint8_t> used(captured.positions.size(), 0);
  for (const Face& f : captured.faces)
    for (int32_t v : f) used[static_cast<size_t>(v)] = 1;
  for (size_t v = 0; v < captured.positions.size(); ++v) {
    if (!used[v]) continue;
    const SurfacePoint s = to_shown.closest(captured.positions[v]);
    if (s.face < 0) continue;
    const Face& f = shown.faces[static_cast<size_t>(s.face)];
    Vec3 point = Vec3::Zero();
    Vec2 w = Vec2::Zero();
    for (int k = 0; k < 3; ++k) {
      point += s.bary[k] * shown.positions[static_cast<size_t>(f[static_cast<size_t>(k)])];
      w += s.bary[k] * disk(s.face, k);
    }
    samples.push_back({w, captured.positions[v] - point});
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
    const Face& f = captured.faces[static_cast<size_t>(s.face)];
    Vec3 point = Vec3::Zero();
    for (int k = 0; k < 3; ++k) point += s.bary[k] * captured.positions[static_cast<size_t>(f[static_cast<size_t>(k)])];
    samples.push_back({vertex_w[v], point - shown.positions[v]});
  }
  return samples;
}

// The lattice cell holding coordinate x (as frame_patch's bilinear interpolation takes it).
std::pair<int, double> cell_of(double x, int lattice) {
  const double f = (x + 1) / 2 * (lattice - 1);
  const int i = std::clamp(static_cast<int>(std::floor(f)), 0, lattice - 2);
  return {i, f - i};
}

// Least squares over the moving nodes (`index`: node -> unknown, or -1): Σ |bilinear(D)(w) − offset|²
// over the samples touching them, plus smoothing × (samples a moving node) × Σ over lattice edges
// |D_a − D_b|² (a still node counts as 0), so a patch fades to 0 at its border.
std::vector<Vec3> solve_displacements(const std::vector<OffsetSample>& samples, const std::vector<int>& index, int unknowns, int lattice,
                                      double smoothing) {
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(unknowns, 3);
  size_t rows = 0;
  for (const OffsetSample& s : samples) {
    const auto [i, a] = cell_of(s.w.x(), lattice);
    const auto [j, b] = cell_of(s.w.y(), lattice);
    const int corner[4] = {j * lattice + i, j * lattice + i + 1, (j + 1) * lattice + i, (j + 1) * lattice + i + 1};
    const double weight[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
    bool touches = false;
    for (int c = 0; c < 4; ++c) touches |= index[static_cast<size_t>(corner[c])] >= 0;
    if (!touches) continue;
    ++rows;
    for (int c = 0; c < 4; ++c) {
      const int p = index[static_cast<size_t>(corner[c])];
      if (p < 0) continue;
      rhs.row(p) += weight[c] * s.offset.transpose();
      for (int e = 0; e < 4; ++e) {
        const int q = index[static_cast<size_t>(corner[e])];
        if (q >= 0) entries.emplace_back(p, q, weight[c] * weight[e]);
      }
    }
  }
  const double mu = smoothing * static_cast<double>(rows) / unknowns + 1e-9;
  for (int b = 0; b < lattice; ++b) {
    for (int a = 0; a < lattice; ++a) {
      const int p = index[static_cast<size_t>(b * lattice + a)];
      for (const int other : {a + 1 < lattice ? b * lattice + a + 1 : -1, b + 1 < lattice ? (b + 1) * lattice + a : -1}) {
        if (other < 0) continue;
        const int q = index[static_cast<size_t>(other)];
        if (p < 0 && q < 0) continue;
        if (p >= 0) entries.emplace_back(p, p, mu);
        if (q >= 0) entries.emplace_back(q, q, mu);
        if (p >= 0 && q >= 0) {
          entries.emplace_back(p, q, -mu);
          entries.emplace_back(q, p, -mu);
        }
      }
    }
  }
  Eigen::SparseMatrix<double> normal(unknowns, unknowns);
  normal.setFromTriplets(entries.begin(), entries.end());
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  const Eigen::MatrixXd x = solver.solve(rhs);
  std::vector<Vec3> out(static_cast<size_t>(unknowns));
  for (int p = 0; p < unknowns; ++p) out[static_cast<size_t>(p)] = x.row(p).transpose();
  return out;
}

// The patch moving the lattice nodes near samples whose offset passes `threshold` (capture units),
// fitted in two rounds (the second against the surface the first moved), rounded to `step` (units).
FramePatch fit_at_threshold(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured,
                            const std::vector<OffsetSample>& first_samples, double t, double threshold, double step,
                            const PatchFitOptions& options) {
  const int lattice = options.lattice;
  std::vector<int> index(static_cast<size_t>(lattice) * static_cast<size_t>(lattice), -1);
  for (const OffsetSample& s : first_samples) {
    if (s.offset.norm() <= threshold) continue;
    const int i = cell_of(s.w.x(), lattice).first, j = cell_of(s.w.y(), lattice).first;
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
  std::vector<Vec3> total = solve_displacements(first_samples, index, unknowns, lattice, options.smoothing);
  FramePatch trial = patch;
  trial.nodes = nodes;
  const Eigen::Matrix3d to_face = shown.pose.rotation.transpose();
  for (const Vec3& d : total) trial.displacements.push_back(to_face * d);
  const std::vector<OffsetSample> second =
      offset_samples(shown_mesh(grid, patched_positions(grid, shown, trial), shown.hole_level), captured);
  const std::vector<Vec3> more = solve_displacements(second, index, unknowns, lattice, options.smoothing);
  for (int p = 0; p < unknowns; ++p) {
    const Vec3 code = (to_face * (total[static_cast<size_t>(p)] + more[static_cast<size_t>(p)]) / step).array().round();
    if (code.isZero()) continue;
    patch.nodes.push_back(nodes[static_cast<size_t>(p)]);
    patch.displacements.push_back(code * step);
  }
  return patch;
}

}  // namespace

PatchFit fit_frame_patch(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, double t,
                         const PatchFitOptions& options) {
  const double diagonal = bounding_box_diagonal(captured.positions);
  const TriangleMesh before = shown_mesh(grid, shown.positions, shown.hole_level);
  PatchFit best;
  best.patch = FramePatch{.time = t, .lattice = options.lattice, .nodes = {}, .displacements = {}};
  best.p99_before = best.p99_after = surface_distance(captured, before).p99 / diagonal;
  if (best.p99_before <= options.bound) return best;
  const std::vector<OffsetSample> samples = offset_samples(before, captured);
  for (const double share : {1.0, 0.9, 0.8, 0.65, 0.5, 0.4, 0.3}) {
    const double threshold = share * options.bound;
    const FramePatch patch = fit_at_threshold(grid, shown, captured, samples, t, threshold * diagonal, options.step_units, options);
    const double p99 = surface_distance(captured, shown_mesh(grid, patched_positions(grid, shown, patch), shown.hole_level)).p99 / diagonal;
    if (p99 < best.p99_after) {
      best.patch = patch;
      best.p99_after = p99;
      best.threshold = threshold;
    }
    if (best.p99_after <= options.bound) break;
  }
  return best;
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

namespace {

DecodeOptions shown_decode() {
  DecodeOptions o;
  o.texture = false;
  o.ignore_sane_range = true;
  o.continue_correction = false;  // each frame a function of t alone, as measured
  o.reconstruct.throw_on_failure = false;
  return o;
}

// A frame between keyframes: its capture index, its time on the file's lattice, what it measured.
struct HeldFrame {
  int frame = 0;
  double time = 0;
  double diagonal = 0;
  double p99 = 0;  // decoded without patches, of the diagonal
};

}  // namespace

std::vector<FramePatch> fit_frame_patches(const Capture& capture, StoredSequence& stored, const std::vector<int>& keyframes, double bound,
                                          PatchFitReport* report_out) {
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
  const std::shared_ptr<const KeyframeSource> source(std::shared_ptr<void>(), &stored);  // not owned
  SequenceDecoder decoder(source);
  const DiskGrid& grid = decoder.geometry().grid();
  const DecodeOptions options = shown_decode();
  const auto show = [&](double t) {
    DecodedFrame f = decoder.decode(t, options);
    return ShownFrame{std::move(f.grid_positions), std::move(f.hole_level), f.pose};
  };
  // Every frame strictly between two keyframes, at its time on the file's lattice.
  std::vector<HeldFrame> held;
  for (int j = keyframes.front() + 1; keyframes.size() >= 2 && j < keyframes.back(); ++j) {
    const double t = residual_time(residual_time_code(capture.frames[static_cast<size_t>(j)].time, outline.first_time, outline.fps),
                                   outline.first_time, outline.fps);
    if (residual_interval(key_times, t) < 0 || (!held.empty() && !(t > held.back().time))) continue;
    const TriangleMesh captured = read_frame(j);
    const ShownFrame shown = show(t);
    const SurfaceDistance d = surface_distance(captured, shown_mesh(grid, shown.positions, shown.hole_level));
    held.push_back({j, t, d.diagonal, d.p99 / d.diagonal});
    report.worst_before = std::max(report.worst_before, held.back().p99);
  }
  std::vector<FramePatch> patches;
  std::vector<double> after(held.size());
  for (size_t h = 0; h < held.size(); ++h) after[h] = held[h].p99;
  if (!held.empty()) {
    double smallest = held.front().diagonal;
    for (const HeldFrame& f : held) smallest = std::min(smallest, f.diagonal);
    const double step = std::exp2(std::floor(std::log2(kPatchStepShare * smallest)));
    // Pass 1: a patch for each frame over the bound.
    std::vector<char> patched(held.size(), 0);
    for (size_t h = 0; h < held.size(); ++h) {
      if (held[h].p99 <= bound) continue;
      ++report.frames_over;
      const TriangleMesh captured = read_frame(held[h].frame);
      const ShownFrame shown = show(held[h].time);
      PatchFit best;
      best.p99_after = held[h].p99;
      for (const int lattice : kPatchLattices) {
        PatchFit fit = fit_frame_patch(grid, shown, captured, held[h].time,
                                       {.lattice = lattice, .bound = kPatchBoundMargin * bound, .step_units = step});
        if (!fit.patch.nodes.empty() && fit.p99_after < best.p99_after) best = std::move(fit);
        if (best.p99_after <= kPatchBoundMargin * bound) break;
      }
      if (best.patch.nodes.empty()) {
        ++report.frames_unmet;
        continue;
      }
      report.frames_unmet += best.p99_after > bound;
      after[h] = best.p99_after;
      patched[h] = 1;
      patches.push_back(std::move(best.patch));
    }
    // Pass 2: the frames between, with the patches interpolated in t; one made worse than the bound
    // and than its own p99 is pinned by an empty patch, until none is.
    for (bool pinned = !patches.empty(); pinned;) {
      pinned = false;
      for (size_t h = 0; h < held.size(); ++h) {
        if (patched[h]) continue;
        const std::vector<Vec3> d = frame_patch_displacements(key_times, patches, held[h].time, grid.nodes);
        if (d.empty()) continue;
        ShownFrame shown = show(held[h].time);
        for (size_t n = 0; n < d.size(); ++n) shown.positions[n] += shown.pose.rotation * d[n];
        const double p99 =
            surface_distance(read_frame(held[h].frame), shown_mesh(grid, shown.positions, shown.hole_level)).p99 / held[h].diagonal;
        if (p99 <= bound || p99 <= held[h].p99) {
          after[h] = p99;
          continue;
        }
        const auto at =
            std::upper_bound(patches.begin(), patches.end(), held[h].time, [](double t, const FramePatch& f) { return t < f.time; });
        patches.insert(at, FramePatch{.time = held[h].time, .lattice = kPatchLattices[0], .nodes = {}, .displacements = {}});
        after[h] = held[h].p99;
        patched[h] = 1;
        ++report.frames_pinned;
        pinned = true;
      }
    }
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
