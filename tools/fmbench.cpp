// fmbench: facemorph's benchmarks. Figures in a table on stdout, and as JSON with --json.
#include "tools/bench_capture.hpp"
#include "tools/bench_conformal.hpp"
#include "tools/bench_kernels.hpp"
#include "tools/bench_reconstruct.hpp"
#include "tools/bench_temporal.hpp"
#include "tools/bench_tracking.hpp"
#include "tools/tool_support.hpp"

int main(int argc, char** argv) {
  facemorph::tools::start_with_huge_pages(argv);  // before anything is allocated: the process may start again
  using namespace facemorph::tools;
  CLI::App app("facemorph benchmarks: quality, size and speed, printed as a table and as JSON.", "fmbench");
  app.require_subcommand(0, 1);
  CaptureBenchOptions capture;
  add_capture_options(app, capture);
  ConformalBenchOptions conformal;
  add_conformal_command(app, conformal);
  ReconstructBenchOptions reconstruct;
  add_reconstruct_command(app, reconstruct);
  TemporalBenchOptions temporal;
  add_temporal_command(app, temporal);
  TrackingBenchOptions tracking;
  add_tracking_command(app, tracking);
  KernelBenchOptions kernels;
  add_kernel_command(app, kernels);
  return guarded_main(app, argc, argv, [&] {
    if (app.got_subcommand("conformal")) return run_conformal_bench(conformal);
    if (app.got_subcommand("reconstruct")) return run_reconstruct_bench(reconstruct);
    if (app.got_subcommand("temporal")) return run_temporal_bench(temporal);
    if (app.got_subcommand("tracking")) return run_tracking_bench(tracking);
    if (app.got_subcommand("kernels")) return run_kernel_bench(kernels);
    if (!capture.captures.empty()) return run_capture_bench(capture);
    throw facemorph::Error(
        facemorph::ErrorCode::kInvalidArgument,
        "nothing to do: give --capture DIR or a command (conformal, reconstruct, temporal, tracking, kernels); --help lists them");
  });
}
