// fmbench kernels: the registrations' thin-plate kernels (spec/method.md §7.1, *Evaluating d*)
// against the code they replaced, in the same run: a frame's points moved by one GMF step, as
// sample_points moves every node of G. Three ways over the same points and centres:
// - std::log: the kernel as it was before stop 77, one point at a time, glibc's logarithm;
// - one point: ThinPlateDisplacement::operator(), a block of one;
// - blocks: ThinPlateDisplacement::displace, vectorised (AVX2 where the CPU has it).
// The fastest of --rounds is kept for each. Exits non-zero when the blocks and the single points
// differ in a bit (the files depend on that), or std::log's results are more than 1e-12 away.
#include "tools/bench_kernels.hpp"

#include "codec/encoder/registration/registration.hpp"
#include "tools/tool_support.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace facemorph::tools {
namespace {

// d(x) summed as thin_plate.cpp did before stop 77: std::log, the centre skipped at r² < 1e-300.
Vec2 std_log_displacement(const ThinPlateDisplacement& d, const Vec2& x) {
  Vec2 out = d.offset + d.linear * x;
  for (size_t i = 0; i < d.centres.size(); ++i) {
    const double r2 = (x - d.centres[i]).squaredNorm();
    if (r2 < 1e-300) continue;
    out += (0.5 * r2 * std::log(r2)) * d.weights.row(static_cast<Eigen::Index>(i)).transpose();
  }
  return out;
}

template <typename Run>
double fastest_seconds(int rounds, Run&& run) {
  double best = INFINITY;
  for (int r = 0; r < rounds; ++r) {
    const auto start = std::chrono::steady_clock::now();
    run();
    best = std::min(best, seconds_since(start));
  }
  return best;
}

}  // namespace

void add_kernel_command(CLI::App& app, KernelBenchOptions& options) {
  CLI::App* cmd = app.add_subcommand("kernels", "The registrations' thin-plate kernels: blocks against one point and against std::log");
  cmd->add_option("--points", options.points, "Points moved (a frame's nodes of G)")->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--centres", options.centres, "Centres of the GMF step")->check(CLI::Range(1, 100000))->capture_default_str();
  cmd->add_option("--rounds", options.rounds, "Timed rounds; the fastest is kept")->check(CLI::Range(1, 100))->capture_default_str();
  cmd->add_option("--json", options.json_out, "Also write the results as JSON to this file ('-': standard output)");
}

int run_kernel_bench(const KernelBenchOptions& options) {
  // A step like a registration's: centres inside the disk, weights of a smooth field's size.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1, 1);
  const auto disk_point = [&] {
    Vec2 p;
    do p = Vec2(unit(rng), unit(rng));
    while (p.squaredNorm() > 1);
    return p;
  };
  ThinPlateDisplacement d;
  d.weights.resize(options.centres, 2);
  for (int i = 0; i < options.centres; ++i) {
    d.centres.push_back(disk_point());
    d.weights.row(i) = 0.01 * Eigen::RowVector2d(unit(rng), unit(rng));
  }
  d.offset = Vec2(0.001, -0.002);
  d.linear << 0.01, 0.002, -0.003, 0.005;
  std::vector<Vec2> points(static_cast<size_t>(options.points));
  for (Vec2& p : points) p = disk_point();

  std::vector<Vec2> by_std_log(points.size()), by_point(points.size());
  std::vector<double> x(points.size()), y(points.size());
  const double std_log_s = fastest_seconds(options.rounds, [&] {
    for (size_t p = 0; p < points.size(); ++p) by_std_log[p] = points[p] + std_log_displacement(d, points[p]);
  });
  const double point_s = fastest_seconds(options.rounds, [&] {
    for (size_t p = 0; p < points.size(); ++p) by_point[p] = points[p] + d(points[p]);
  });
  const double block_s = fastest_seconds(options.rounds, [&] {
    for (size_t p = 0; p < points.size(); ++p) x[p] = points[p].x(), y[p] = points[p].y();
    d.displace(x, y);
  });
  size_t bits_differ = 0;
  double from_std_log = 0;
  for (size_t p = 0; p < points.size(); ++p) {
    bits_differ += x[p] != by_point[p].x() || y[p] != by_point[p].y();
    from_std_log = std::max(from_std_log, (Vec2(x[p], y[p]) - by_std_log[p]).cwiseAbs().maxCoeff());
  }
  const double kernels = static_cast<double>(points.size()) * static_cast<double>(options.centres);
  const auto ns = [&](double seconds) { return 1e9 * seconds / kernels; };
  std::printf("%d points, %d centres: ns a kernel (the fastest of %d rounds)\n", options.points, options.centres, options.rounds);
  std::printf("  std::log, one point at a time   %7.3f\n", ns(std_log_s));
  std::printf("  one point (a block of one)      %7.3f  %.2fx std::log's time\n", ns(point_s), point_s / std_log_s);
  std::printf("  blocks (displace)               %7.3f  %.2fx std::log's time\n", ns(block_s), block_s / std_log_s);
  std::printf("  blocks against one point: %zu points differ in a bit; against std::log at most %.3g (disk units)\n", bits_differ,
              from_std_log);
  if (!options.json_out.empty()) {
    write_json(options.json_out, {{"benchmark", "kernels"},
                                  {"points", options.points},
                                  {"centres", options.centres},
                                  {"ns_per_kernel", {{"std_log", ns(std_log_s)}, {"one_point", ns(point_s)}, {"blocks", ns(block_s)}}},
                                  {"blocks_over_std_log", block_s / std_log_s},
                                  {"points_differing_from_one_point", bits_differ},
                                  {"max_difference_from_std_log", from_std_log}});
  }
  if (bits_differ > 0 || !(from_std_log <= 1e-12)) {
    std::fprintf(stderr, "fmbench kernels: the blocks disagree (%zu points differ from one point, %.3g from std::log)\n", bits_differ,
                 from_std_log);
    return 1;
  }
  return 0;
}

}  // namespace facemorph::tools
