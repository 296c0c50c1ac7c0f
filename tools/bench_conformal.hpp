// fmbench conformal (see bench_conformal.cpp).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace facemorph::tools {

struct ConformalBenchOptions {
  std::vector<std::string> inputs;
  std::string method = "both";
  std::string data = "../shared/data";
  std::string mesh_out, disk_out, pictures, json_out;
  bool quiet = false;
  bool sweep = false;  // --sweep: every frame through the encoder's map, failures caught and counted
  int threads = 0;
};

void add_conformal_command(CLI::App& app, ConformalBenchOptions& options);
int run_conformal_bench(const ConformalBenchOptions& options);

}  // namespace facemorph::tools
