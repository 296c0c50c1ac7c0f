// fmbench kernels (see bench_kernels.cpp).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace facemorph::tools {

struct KernelBenchOptions {
  int points = 257 * 257;  // one frame sampled at G's nodes, N = 257
  int centres = 130;       // about an ICT registration's: landmarks and boundary samples every 5°
  int rounds = 5;
  std::string json_out;
};

void add_kernel_command(CLI::App& app, KernelBenchOptions& options);
int run_kernel_bench(const KernelBenchOptions& options);

}  // namespace facemorph::tools
