// fmbench tracking (see bench_tracking.cpp).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace facemorph::tools {

struct TrackingBenchOptions {
  std::string capture;                                    // a capture folder with interior landmarks
  int stride = 1;                                         // every stride-th frame
  int image_size = 0, window = 0, levels = 0;             // 0: TrackingOptions' defaults
  double blur = -1, factor_weight = -1, round_trip = -1;  // < 0: the defaults
  bool no_holes = false;                                  // draw the disk images without the filled holes' outlines
  bool chain = false;                                     // track frame to frame instead of from the reference
  bool chain_direct = false;                              // with chain: from the reference again, started where the chain put each point
  bool per_landmark = false;
  std::string variants;          // "spacing,window,round_trip,smoothing[,gain];..." : the selection per variant instead
  bool given_landmarks = false;  // with variants: keep the capture's landmarks (default: withheld)
};

void add_tracking_command(CLI::App& app, TrackingBenchOptions& options);
int run_tracking_bench(const TrackingBenchOptions& options);

}  // namespace facemorph::tools
