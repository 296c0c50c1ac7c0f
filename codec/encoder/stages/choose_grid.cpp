// The grid's size N (--grid auto): the smallest whose resampling floor on the reference frame
// meets a target set by the capture's noise and the spline's error between keyframes, capped by the
// captured mesh's density, and raised where the worst region, resampled or decoded, would be
// (spec/method.md §7.6).
#include "codec/encoder/stages/choose_grid.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/util/elapsed.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/plan_keyframes.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

namespace facemorph {

namespace {

// --grid auto: the sizes tried, and the resampling floor a keyframe may add (spec/method.md §7.6).
// The floor falls as 1/N², so steps of ~1.14-1.25 in N give the rule steps of at most ~1.6 in
// floor and in nodes (G has ~0.79 N² nodes). The rungs past 97 (113, 161, 225) halve the old steps
// of 1.33-1.5 (1.8-2.2x the nodes), where the coarsest N whose worst region met its share was up to
// twice the nodes it needed (decimated ICT's single frame through D: p99 1.014% at 97, 0.417% at 129).
constexpr int kGridCandidates[] = {33, 41, 49, 57, 65, 81, 97, 113, 129, 161, 193, 225, 257};
constexpr double kGridFloorTarget = 2e-4;
constexpr double kGridNoiseShare = 1.0;
// Half the error the spline makes between keyframes: where bytes spent on a finer grid and on more
// keyframes buy the same error (equal slopes; measured on Medusa, spec/method.md §7.6).
constexpr double kGridErrorShare = 0.5;
// Past this many of G's nodes in the disk area of a captured vertex of the denser quarter, G samples
// the captured mesh more finely than it was captured: its facets, not the face, which a held-out
// frame (another sampling of the face) does not share. The quarter, not the median: an adaptive mesh
// (ICT decimated) puts its vertices where the detail is. Measured (spec/method.md §7.6): a 1.9k-vertex
// face stops paying for nodes past N = 97 (2.4 such nodes; 129: 4.2), decimated ICT still pays at
// N = 257 (2.0).
constexpr double kGridNodesPerVertex = 3.0;
constexpr double kGaussianP99 = 2.576;

}  // namespace

std::span<const int> grid_ladder() { return kGridCandidates; }

int density_grid_cap(double vertex_disk_area) {
  if (!(vertex_disk_area > 0)) return std::end(kGridCandidates)[-1];
  int cap = kGridCandidates[0];
  for (int n : kGridCandidates) {
    const double h = 2.0 / (n - 1);  // G's spacing: one node per h² of the disk
    if (vertex_disk_area / (h * h) <= kGridNodesPerVertex) cap = n;
  }
  return cap;
}

double quartile_vertex_disk_area(const std::vector<Vec2>& disk, const std::vector<Face>& faces) {
  if (disk.empty()) return 0;
  std::vector<double> area(disk.size(), 0.0);
  for (const Face& f : faces) {
    const Vec2 a = disk[static_cast<size_t>(f[0])], b = disk[static_cast<size_t>(f[1])], c = disk[static_cast<size_t>(f[2])];
    const double third = std::abs((b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y())) / 6.0;
    for (int k = 0; k < 3; ++k) area[static_cast<size_t>(f[static_cast<size_t>(k)])] += third;
  }
  const auto quartile = area.begin() + static_cast<std::ptrdiff_t>(area.size() / 4);
  std::nth_element(area.begin(), quartile, area.end());
  return *quartile;
}

GridChoice choose_grid_size(GridChoiceInput input) {
  GridChoice choice;
  // A grid fine enough to resolve a capture's per-frame noise spends its nodes on noise the
  // keyframe fit averages away: the floor need not go below the median frame noise. (A floor
  // measured against a noisy frame is mostly that frame's unresolved noise: on a 0.16%-noise
  // capture, N = 193 → 97 left the decoded error against the noise-free surface unchanged while
  // the fields took a quarter of the bytes; spec/method.md §7.6.)
  std::vector<double>& noise = input.noise;
  std::nth_element(noise.begin(), noise.begin() + static_cast<std::ptrdiff_t>(noise.size() / 2), noise.end());
  choice.median_noise = std::isfinite(noise[noise.size() / 2]) ? noise[noise.size() / 2] : 0.0;
  // Nor below half the error the spline makes between the chosen keyframes: errors add in
  // quadrature, so such a floor adds up to 12% to it, and below that a finer grid costs more bytes
  // for the error it removes than more keyframes would (spec/method.md §7.6).
  // Where the selection predicts nothing (one frame, every frame a keyframe), the error it holds a
  // frame to stands in for the prediction, as it does for the field rounding (stage_settings.cpp): a
  // frame nothing is predicted for is coded as a sequence's whose keyframes left exactly that, not
  // at the fixed floor, ten times finer (spec/method.md §7.6, "A single frame"). The worst-region
  // bound below, read through the reconstruction, keeps the coarse N this allows honest, and the
  // field precision stage holds the rounding to what it leaves of the 1% (round_fields.cpp): without
  // that bound this rule was withdrawn twice (single frames of Medusa and ICT at 1.01-1.19% p99).
  const bool predicted = input.mean_predicted_error > 0;
  const double noise_term = input.noise_decides ? kGridNoiseShare * choice.median_noise : 0.0,
               interpolation_term = kGridErrorShare * (predicted ? input.mean_predicted_error : input.error_bound);
  choice.target = std::max({kGridFloorTarget, noise_term, interpolation_term});
  choice.term = choice.target == interpolation_term ? (predicted ? "interpolation" : "error bound")
                : choice.target == noise_term        ? "noise"
                                                     : "floor";
  // The RMS terms ask for no more than the captured mesh's density holds (density_grid_cap); the
  // worst region may ask for more: it is a bound every decoded frame must meet, not a trade.
  choice.density_cap = density_grid_cap(input.vertex_disk_area);
  // A floor measured against a noisy frame has that frame's noise in its worst region too: the
  // 99th percentile of |x| for Gaussian noise of RMS σ is 2.576σ, which no grid removes.
  const double worst_target = choice.worst_target =
      std::max(kGridWorstTarget, input.noise_decides ? kGaussianP99 * choice.median_noise : 0.0);
  int rms_met_at = 0;  // the candidate where the RMS terms were done (met or capped)
  bool rms_met = false;
  for (int n : kGridCandidates) {
    const GridFloor floor = input.floor(n);
    choice.floors.emplace_back(n, floor.rms);
    choice.floor_p99s.emplace_back(n, floor.p99);
    choice.n = n;
    if (rms_met_at == 0 && (floor.rms <= choice.target || n >= choice.density_cap)) {
      rms_met_at = n;
      rms_met = floor.rms <= choice.target;
    }
    if (rms_met_at == 0) continue;
    // The worst region as a decoder shows it: the reference's fields at this N rebuilt by the
    // Laplace-Beltrami reconstruction, which the resampling floor does not see where the equations
    // reach another surface than the sampled one or none (spec/method.md §7.6; on every capture
    // measured the two agreed within 0.004% of the diagonal). The larger of the two, since the
    // representation is chosen after N and a keyframe whose fields do not reconstruct is stored as
    // positions, which decode as sampled. Measured only from where the RMS terms are done, coarse to
    // fine, as each costs a reconstruction.
    double worst = floor.p99;
    if (input.decoded) {
      const GridFloor decoded = input.decoded(n);
      choice.decoded.emplace_back(n, decoded);
      worst = std::max(worst, decoded.p99);
    }
    if (worst <= worst_target) break;
  }
  if (choice.n > rms_met_at && rms_met_at > 0) {
    choice.term = "worst region";
  } else if (rms_met_at > 0 && !rms_met) {
    choice.term = "density";
  }
  return choice;
}

namespace {

GridFloor floor_of(const TriangleMesh& reference, const DiskGrid& grid, const std::vector<Vec3>& positions, int threads) {
  const SurfaceDistance floor = surface_distance(reference, grid_mesh(grid, positions), threads);
  return GridFloor{.rms = floor.rms / floor.diagonal, .p99 = floor.p99 / floor.diagonal};
}

// The reference frame on G of one size: sampled once for both of its floors. One size after
// another (the grid choice's search reads each floor before it picks the next size), so each
// sampling and surface distance runs on `threads` threads itself: on one they were the longest
// stretch of the encode with the other cores idle (0.75 s of ict24's 22 s).
class ReferenceOnGrid {
 public:
  ReferenceOnGrid(const PlanFrames& frames, const MappedFrame& reference, int reference_index, int threads)
      : frames_(frames), reference_(reference), index_(reference_index), threads_(threads) {}

  // Its surface against G's surface sampled from it.
  GridFloor resampled(int n) {
    at(n);
    return floor_of(reference_.map.surface, *grid_, sampled_, threads_);
  }

  // Its surface against G's surface rebuilt from the fields of the sampled one: computed as the
  // keyframes' are (build_keyframes.cpp: 16-bit, its folds as fixed nodes) and decoded as the field
  // precision stage decodes a keyframe, unrounded (the rounding's share of the worst region is the
  // room the bound leaves, and its steps are chosen on G after N). Where they do not converge, the
  // field precision stage's decode of the same keyframe throws too and the encode stores every
  // keyframe as positions (build_reconstructable) unless the fields were asked for: then the
  // resampled floor is what the file shows; else (or a non-finite iterate) infinite: the candidate
  // fails.
  GridFloor decoded(int n, Representation representation, bool positions_fallback) {
    at(n);
    const std::shared_ptr<const GridGeometry> geometry = shared_grid_geometry(n);
    const GridFields fields = keyframe_fields(*geometry, sampled_, representation, folded_nodes(*geometry, sampled_));
    Reconstructor reconstructor(geometry);
    try {
      return floor_of(reference_.map.surface, geometry->grid(), decode_keyframe_exactly(reconstructor, fields), threads_);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::kNotConverged && e.code() != ErrorCode::kNumerical) throw;
      constexpr double kNever = std::numeric_limits<double>::infinity();
      // build_reconstructable falls back to positions for an iteration that does not converge
      // only; a non-finite one fails the encode.
      const bool stored_as_positions = positions_fallback && e.code() == ErrorCode::kNotConverged;
      GridFloor floor = stored_as_positions ? resampled(n) : GridFloor{.rms = kNever, .p99 = kNever};
      floor.reconstructed = false;
      return floor;
    }
  }

 private:
  // G's nodes and faces alone: the resampled floors (13 sizes on ICT) need no stiffness matrix,
  // which shared_grid_geometry builds (3% of a 2k-vertex ICT encode), only the decoded ones do.
  void at(int n) {
    if (grid_ && grid_->n == n) return;
    grid_ = make_disk_grid(n);
    sampled_ = frames_.sampler.sample_surface(reference_, index_, grid_->nodes, threads_);
  }

  const PlanFrames& frames_;
  const MappedFrame& reference_;
  int index_;
  int threads_;
  std::optional<DiskGrid> grid_;
  std::vector<Vec3> sampled_;
};

}  // namespace

EncodeReport::DecodedFloor decoded_fields_floor(const PlanSettings& settings, const PlanFrames& frames, int n) {
  const std::shared_ptr<const MappedFrame> reference = frames.maps.frame(settings.reference_frame);
  ReferenceOnGrid on_grid(frames, *reference, settings.reference_frame, settings.threads);
  const GridFloor floor = on_grid.decoded(n, Representation::kHLT, false);
  return {n, floor.rms, floor.p99, floor.reconstructed};
}

std::vector<double> keyframe_floor_p99s(const PlanFrames& frames, const std::vector<int>& keyframes, int n, int threads) {
  const DiskGrid grid = make_disk_grid(n);  // nodes and faces alone (ReferenceOnGrid::at)
  // Each keyframe on a thread: one after another they were a serial stretch of every N and disk
  // the choice by bytes tries (0.7 s of ict24's encode, the other thread idle).
  std::vector<double> floors(keyframes.size());
  parallel_for(static_cast<int>(keyframes.size()), threads, [&](int k) {
    const int i = keyframes[static_cast<size_t>(k)];
    const std::shared_ptr<const MappedFrame> frame = frames.maps.frame(i);
    floors[static_cast<size_t>(k)] = floor_of(frame->map.surface, grid, frames.sampler.sample_surface(*frame, i, grid.nodes), 1).p99;
  });
  return floors;
}

int choose_grid(const PlanSettings& settings, const PlanFrames& frames, EncodeReport& report, const KeyframeSelection* chosen) {
  if (settings.grid > 0) return settings.grid;
  const auto start = std::chrono::steady_clock::now();
  const SelectionSamples& selection = frames.selection;
  const auto count = static_cast<int>(frames.frames.size());
  // Refused before anything is measured where the samples the noise reads are gone.
  static_cast<void>(selection.samples());
  GridChoiceInput input;
  for (int k = 0; k < count; ++k) input.noise.push_back(selection.noise_at(k) / selection.frames()[static_cast<size_t>(k)].diagonal);
  // Not on a whole head (a radially spread disk, spec/method.md §7.11) whose frames share no
  // interior landmarks with the reference: there the found landmarks' disagreement from frame to
  // frame reads as noise (fmsynth --head --landmarks auto: 1.27% of the diagonal, 0.085% with its
  // landmarks), and the N = 33 it asked for decoded at 1.57 mm, N = 129 at 0.62.
  const bool unmatched = 2 * report.frames_without_interior_landmarks > count - 1;
  input.noise_decides = report.radial_equalising == 0 || !unmatched;
  input.mean_predicted_error = chosen ? mean_predicted_error(*chosen) : 0.0;
  input.error_bound = chosen ? unpredicted_error_bound(settings.selection) : 0.0;
  const int reference_index = settings.reference_frame;
  const std::shared_ptr<const MappedFrame> reference = frames.maps.frame(reference_index);
  // The conformal disk is the one G samples unless a reparametrisation spreads it (§7.11): then no cap.
  if (report.radial_equalising == 0 && !settings.density_equalising) {
    input.vertex_disk_area = quartile_vertex_disk_area(reference->map.disk, reference->map.surface.faces);
  }
  ReferenceOnGrid on_grid(frames, *reference, reference_index, settings.threads);
  input.floor = [&](int n) { return on_grid.resampled(n); };
  // Positions (asked for) decode as sampled; otherwise the fields as hl+t would store them, which
  // choose_representation keeps unless they blend apart. Where the representation is open,
  // choose_by_bytes may store positions after all (spec/method.md §7.14); they decode as sampled, so
  // the resampled floor bounded here holds for them.
  if (settings.representation != Representation::kXYZ) {
    const Representation representation = settings.representation.value_or(Representation::kHLT);
    const bool positions_fallback = !settings.representation;  // as build_reconstructable falls back
    input.decoded = [&, representation, positions_fallback](int n) { return on_grid.decoded(n, representation, positions_fallback); };
  }
  const double input_area = input.vertex_disk_area;
  GridChoice choice = choose_grid_size(std::move(input));
  report.grid_floors = std::move(choice.floors);
  report.grid_floor_p99s = std::move(choice.floor_p99s);
  report.grid_decoded_floors.clear();
  for (const auto& [n, floor] : choice.decoded) report.grid_decoded_floors.push_back({n, floor.rms, floor.p99, floor.reconstructed});
  report.grid_density_cap = choice.density_cap;
  report.grid_worst_target = choice.worst_target;
  report.grid_vertex_area = input_area;
  report.median_noise = choice.median_noise;
  report.grid_target = choice.target;
  report.grid_term = std::move(choice.term);
  report.seconds_grid = seconds_since(start);
  return choice.n;
}

}  // namespace facemorph
