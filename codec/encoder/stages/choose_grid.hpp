// --grid auto (spec/method.md §7.6): the smallest N of the candidates whose resampling floor on the
// reference frame meets a target set by the capture's noise and the spline's error between keyframes,
// no finer than the captured mesh's own density asks, and whose worst region (the 99th percentile of
// the reference as G samples it and as a decoder rebuilds it from its fields) stays within its
// share of the 1% worst-region target.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <functional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace facemorph {

// The floor's share of the worst-region target (every decoded frame's 99th-percentile point error
// within 1% of the diagonal, design §7): what a keyframe alone shows, with room for the rounding
// (1% less the decoded floor's p99, 0.25% or more where the floor met this share: the field
// precision stage holds it to that, round_fields.cpp; the two add nearly linearly at the worst
// points, spec/method.md §5.3).
// Not less: between keyframes the spline sets the worst region, and a finer grid bought none of it
// (Medusa N = 41 → 57: worst-frame p99 1.735 → 1.713% for 25% more bytes; spec/method.md §7.6).
inline constexpr double kGridWorstTarget = 0.0075;

// G's floor on the reference frame at one N, over the reference's diagonal: its surface against G's
// surface sampled from it (the resampling floor), or against that surface's fields decoded as a
// decoder rebuilds them (the decoded floor).
struct GridFloor {
  double rms = 0;
  double p99 = 0;  // the 99th-percentile point distance: the worst region's
  // false: a decoded floor whose fields did not reconstruct (infinite, or the resampled floor where
  // the keyframes would then be stored as positions)
  bool reconstructed = true;
};

// The sizes --grid auto tries, coarsest first (spec/method.md §7.6); the choice by bytes and the
// density-equalised candidate pick their coarser N among those it measured.
std::span<const int> grid_ladder();

// The largest N the RMS terms may ask for on a capture whose vertices of the denser quarter hold
// `vertex_disk_area` of the unit disk each (quartile_vertex_disk_area): the largest candidate with
// at most kGridNodesPerVertex (3) of G's nodes in that area (at least the smallest candidate; the
// largest for an area of 0: no cap).
int density_grid_cap(double vertex_disk_area);

// The lower quartile over `disk`'s vertices of each one's disk area (a third of its triangles').
double quartile_vertex_disk_area(const std::vector<Vec2>& disk, const std::vector<Face>& faces);

// What the choice reads of the encode.
struct GridChoiceInput {
  std::vector<double> noise;  // each frame's noise estimate over its diagonal (infinite below 5 frames)
  // false: the noise sets no target (a whole head whose frames share no interior landmarks with the
  // reference: their found landmarks' disagreement reads as noise).
  bool noise_decides = true;
  double mean_predicted_error = 0;        // the spline's between the chosen keyframes (fraction of the diagonal); 0: none chosen
  // Where nothing is predicted (mean_predicted_error 0: one frame, every frame a keyframe), the error
  // the selection holds a frame to (unpredicted_error_bound), which takes the prediction's place in
  // the third term; 0: none (no keyframes chosen), the fixed floor alone.
  double error_bound = 0;
  double vertex_disk_area = 0;            // the reference frame's quartile_vertex_disk_area on the disk G samples (0: no cap)
  std::function<GridFloor(int n)> floor;  // the reference's resampling floor on G of size n
  // The reference's decoded floor on G of size n (infinite where its fields do not reconstruct and
  // nothing else would be stored); called only where the RMS terms are done. Empty: the keyframes store positions, which decode
  // as sampled, and the resampling floor is what a decoder shows.
  std::function<GridFloor(int n)> decoded;
};

struct GridChoice {
  int n = 0;
  std::vector<std::pair<int, double>> floors;      // (N, floor RMS) tried, in order
  std::vector<std::pair<int, double>> floor_p99s;  // (N, floor 99th percentile) tried, in order
  std::vector<std::pair<int, GridFloor>> decoded;  // (N, decoded floor) measured, in order
  int density_cap = 0;                             // density_grid_cap of the capture
  double worst_target = 0;                         // the floor's 99th percentile asked for (fraction of the diagonal)
  double median_noise = 0;                         // the frames' median noise (0 where it is not finite)
  double target = 0;                               // the floor asked for (fraction of the diagonal)
  // which term set it: "floor", "noise", "interpolation" or "error bound" (the RMS target met; the
  // third term from the prediction or, where nothing is predicted, the bound), "density" (the
  // density cap reached first) or "worst region" (the 99th percentile, the larger of the resampled
  // and the decoded one, asked for more than either)
  std::string term;
};

// The candidates tried from the coarsest up; the finest where none meets the target (a crowded face).
GridChoice choose_grid_size(GridChoiceInput input);

}  // namespace facemorph
