// The grid's size N (--grid auto): the smallest whose resampling floor on the reference frame
// meets a target set by the capture's noise and the spline's error between keyframes
// (spec/method.md §7.6).
#include "codec/encoder/stages/choose_grid.hpp"

#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "format/error.hpp"
#include "codec/meshkit/geometry/distance.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

namespace facemorph {

namespace {

// --grid auto: the sizes tried, and the resampling floor a keyframe may add (spec/method.md §7.6).
// The floor falls as 1/N², so steps of ~1.2-1.5 in N give the rule steps of at most ~2.2 in floor.
constexpr int kGridCandidates[] = {33, 41, 49, 57, 65, 81, 97, 129, 193, 257};
constexpr double kGridFloorTarget = 2e-4;
constexpr double kGridNoiseShare = 1.0;
// Half the error the spline makes between keyframes: where bytes spent on a finer grid and on more
// keyframes buy the same error (equal slopes; measured on Medusa, spec/method.md §7.6).
constexpr double kGridErrorShare = 0.5;

}  // namespace

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
  const double noise_term = input.noise_decides ? kGridNoiseShare * choice.median_noise : 0.0,
               interpolation_term = kGridErrorShare * input.mean_predicted_error;
  choice.target = std::max({kGridFloorTarget, noise_term, interpolation_term});
  choice.term = choice.target == interpolation_term ? "interpolation" : choice.target == noise_term ? "noise" : "floor";
  for (int n : kGridCandidates) {
    const double floor = input.floor(n);
    choice.floors.emplace_back(n, floor);
    choice.n = n;
    if (floor <= choice.target) return choice;
  }
  return choice;
}

int SequenceEncoder::choose_grid(const KeyframeSelection* chosen) {
  if (options_.grid > 0) return options_.grid;
  if (samples_released_) throw Error(ErrorCode::kInternal, "choose_grid: the selection's samples were released (sample_frames again)");
  GridChoiceInput input;
  for (int k = 0; k < frame_count(); ++k) input.noise.push_back(noise_at(k) / selection_[static_cast<size_t>(k)].diagonal);
  // Not on a whole head (a radially spread disk, spec/method.md §7.11) whose frames share no
  // interior landmarks with the reference: there the found landmarks' disagreement from frame to
  // frame reads as noise (fmsynth --head --landmarks auto: 1.27% of the diagonal, 0.085% with its
  // landmarks), and the N = 33 it asked for decoded at 1.57 mm, N = 129 at 0.62.
  const bool unmatched = 2 * report_.frames_without_interior_landmarks > frame_count() - 1;
  input.noise_decides = report_.radial_equalising == 0 || !unmatched;
  input.mean_predicted_error = chosen ? mean_predicted_error(*chosen) : 0.0;
  const std::shared_ptr<const MappedFrame> reference = frame(options_.reference_frame);
  input.floor = [&](int n) {
    const DiskGrid grid = make_disk_grid(n);
    const std::vector<Vec3> sampled = sample_surface(*reference, options_.reference_frame, grid.nodes);
    const SurfaceDistance floor = surface_distance(reference->map.surface, grid_mesh(grid, sampled));
    return floor.rms / floor.diagonal;
  };
  GridChoice choice = choose_grid_size(std::move(input));
  report_.grid_floors = std::move(choice.floors);
  report_.median_noise = choice.median_noise;
  report_.grid_target = choice.target;
  report_.grid_term = std::move(choice.term);
  return choice.n;
}

}  // namespace facemorph
