// --grid auto (spec/method.md §7.6): the smallest N of the candidates whose resampling floor on the
// reference frame meets a target set by the capture's noise and the spline's error between keyframes.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace facemorph {

// What the choice reads of the encode.
struct GridChoiceInput {
  std::vector<double> noise;  // each frame's noise estimate over its diagonal (infinite below 5 frames)
  // false: the noise sets no target (a whole head whose frames share no interior landmarks with the
  // reference: their found landmarks' disagreement reads as noise).
  bool noise_decides = true;
  double mean_predicted_error = 0;  // the spline's between the chosen keyframes (fraction of the diagonal); 0: none chosen
  std::function<double(int n)> floor;  // the reference's resampling floor on G of size n: RMS over its diagonal
};

struct GridChoice {
  int n = 0;
  std::vector<std::pair<int, double>> floors;  // (N, floor) tried, in order
  double median_noise = 0;                     // the frames' median noise (0 where it is not finite)
  double target = 0;                           // the floor asked for (fraction of the diagonal)
  std::string term;                            // which term set it: "floor", "noise" or "interpolation"
};

// The candidates tried from the coarsest up; the finest where none meets the target (a crowded face).
GridChoice choose_grid_size(GridChoiceInput input);

}  // namespace facemorph
