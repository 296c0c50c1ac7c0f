// fmbench reconstruct (see bench_reconstruct.cpp).
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace facemorph::tools {

struct ReconstructBenchOptions {
  std::vector<std::string> inputs;
  int grid = 256;
  std::string representation = "all";
  std::string data = "../shared/data";
  std::string out, json_out;
  int limit = 0;
  bool speed = false;
  std::vector<double> rotation;
  bool quiet = false;
};

void add_reconstruct_command(CLI::App& app, ReconstructBenchOptions& options);
int run_reconstruct_bench(const ReconstructBenchOptions& options);
nlohmann::json run_decode_speed(bool quiet);
nlohmann::json run_rotation_experiment(int grid_n, double degrees);

}  // namespace facemorph::tools
