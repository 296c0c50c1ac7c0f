// Line plots as pictures for the benches (error against time, rate against distortion): axes,
// ticks with numbers, lines and markers. A 5x7 bitmap font for the numbers; no other dependency.
#pragma once

#include "codec/core/image/image.hpp"

#include <array>
#include <string>
#include <vector>

namespace facemorph::tools {

struct PlotSeries {
  std::vector<double> x, y;
  std::array<uint8_t, 3> color = {40, 90, 200};
  bool line = true;      // join the points
  bool markers = false;  // draw a small square at each point
  std::string label;     // shown in the legend (top right) when not empty
};

struct PlotOptions {
  int width = 900, height = 450;
  std::string x_label, y_label;        // short: the font has digits, letters, space and . % - / ( ) : = +
  std::vector<double> vertical_marks;  // x positions marked by thin vertical lines (e.g. keyframes)
  bool y_from_zero = true;
};

Image line_plot(const std::vector<PlotSeries>& series, const PlotOptions& options);

}  // namespace facemorph::tools
