// fmbench --capture: the rate of a whole capture against what its users would use instead (see
// bench_capture.cpp).
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace facemorph::tools {

struct CaptureBenchOptions {
  std::vector<std::string> captures;  // folders, or synth, medusa, ict (bench_sequence.hpp), or all
  std::string fmv;                    // measure this file instead of the bench's own encode (one capture)
  std::string json_out, report;       // report: Markdown; its pictures and curves go beside it
  std::string data = "../shared/data";
  bool quick = false;          // the smoke test: small capture, few candidates, about a minute
  bool geometry_only = false;  // with fmv: only its geometry error (no mapping, no baselines)
  std::string against;         // with geometry_only: also how far fmv decodes from this file of the same capture, frame by frame
  bool quiet = false;
  bool residual_frames = true;  // the encode with residual frames where they pay (fmenc's default; --no-residual-frames)
};

// The options go on the top level: fmbench --capture DIR [--fmv F] [--json F] [--report F] [--quick].
void add_capture_options(CLI::App& app, CaptureBenchOptions& options);
int run_capture_bench(const CaptureBenchOptions& options);

}  // namespace facemorph::tools
