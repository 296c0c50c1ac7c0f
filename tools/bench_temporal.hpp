// fmbench temporal (see bench_temporal.cpp).
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace facemorph::tools {

struct TemporalBenchOptions {
  std::vector<std::string> inputs;
  std::string keyframes = "10%";
  std::string registration = "all";    // a comma-separated list of moebius, gmf, frame; or all
  std::string spline = "catmull-rom";  // one kind, or "all" to compare them
  std::string representation = "hl+t";
  std::string grid = "auto";
  int texture_size = 256;
  std::string data = "../shared/data";
  std::string json_out, plots;
  double density_equalising = 0;  // strength of the reference disk's density-equalising reparametrisation
  int limit = 0;                  // at most this many frames per capture (0: all)
  bool no_targets = false;        // skip the keyframes-for-1%-and-0.5% searches
  bool quiet = false;
};

void add_temporal_command(CLI::App& app, TemporalBenchOptions& options);
int run_temporal_bench(const TemporalBenchOptions& options);

}  // namespace facemorph::tools
