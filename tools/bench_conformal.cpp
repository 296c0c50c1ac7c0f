// fmbench conformal: quality and speed of the Riemann conformal map, QIEM against the linear map,
// on meshes, captures (every frame) and in-memory synthetic faces.
#include "tools/bench_conformal.hpp"

#include "codec/core/util/parallel.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"

#include "tools/bench_inputs.hpp"
#include "tools/tool_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

namespace facemorph::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct FrameResult {
  std::string name;
  int vertices = 0, faces = 0, holes = 0;
  double seconds_load = 0, seconds_map = 0;
  double seconds_grid = 0;      // positions onto G (N = 256)
  double seconds_texture = -1;  // texture onto 1024² (-1: the frame has no image)
  ConformalReport report;
  Distortion distortion;
  double lambda2_ratio = 0;  // max λ² / min λ²: how crowded the map is
};

std::string slug(const std::string& text) {
  std::string out;
  for (char c : text) out += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  while (!out.empty() && out.front() == '_') out.erase(out.begin());
  return out.substr(out.size() > 60 ? out.size() - 60 : 0);
}

// The paper's Figure 3 as a bar chart: area share of pulled-back checkerboard angles, 45°..135°.
Image histogram_picture(const std::vector<double>& histogram) {
  Image image(640, 320, 3);
  std::fill(image.pixels.begin(), image.pixels.end(), uint8_t{255});
  const double top = *std::max_element(histogram.begin(), histogram.end());
  const int bins = static_cast<int>(histogram.size());
  for (int b = 0; b < bins; ++b) {
    const int x0 = 20 + b * 600 / bins, x1 = 20 + (b + 1) * 600 / bins - 1;
    const int height = top > 0 ? static_cast<int>(280 * histogram[static_cast<size_t>(b)] / top) : 0;
    for (int x = x0; x <= x1; ++x) {
      for (int y = 300 - height; y < 300; ++y) {
        uint8_t* p = image.at(x, y);
        p[0] = 40, p[1] = 60, p[2] = b == bins / 2 ? 200 : 140;
      }
    }
  }
  for (int x = 20; x < 620; ++x) std::fill_n(image.at(x, 300), 3, uint8_t{0});                                         // axis
  for (int y = 300; y < 310; ++y) std::fill_n(image.at(20 + (bins / 2) * 600 / bins + 300 / bins, y), 3, uint8_t{0});  // 90°
  return image;
}

void write_pictures(const fs::path& dir, const std::string& name, const DiskMap& map) {
  fs::create_directories(dir);
  TriangleMesh surface = map.surface;
  surface.uvs.clear();
  for (const Vec2& w : map.disk) surface.uvs.push_back(0.5 * (w + Vec2(1, 1)));
  surface.uv_faces = surface.faces;
  RenderOptions options;
  options.yaw_degrees = 20;
  write_image(dir / (name + "_surface_checker.png"), render(surface, checkerboard_shader(surface, 16), options));
  TriangleMesh disk = surface;
  for (size_t v = 0; v < disk.positions.size(); ++v) disk.positions[v] = Vec3(map.disk[v].x(), map.disk[v].y(), 0);
  RenderOptions flat;
  flat.shading = false;
  flat.wireframe = map.surface.vertex_count() <= 5000;
  write_image(dir / (name + "_disk.png"), render(disk, checkerboard_shader(disk, 16), flat));
  write_image(dir / (name + "_angle_histogram.png"), histogram_picture(measure_distortion(map).checkerboard_histogram));
}

void write_mesh_pair(const DiskMap& map, const std::string& mesh_out, const std::string& disk_out) {
  if (!mesh_out.empty()) write_mesh(mesh_out, map.surface);
  if (!disk_out.empty()) {
    TriangleMesh disk;
    disk.faces = map.surface.faces;
    for (const Vec2& w : map.disk) {
      disk.positions.emplace_back(w.x(), w.y(), 0);
      disk.uvs.push_back(0.5 * (w + Vec2(1, 1)));
    }
    disk.uv_faces = disk.faces;
    write_mesh(disk_out, disk);
  }
}

json frame_json(const FrameResult& r) {
  const ConformalReport& c = r.report;
  const Distortion& d = r.distortion;
  return {{"frame", r.name},
          {"vertices", r.vertices},
          {"faces", r.faces},
          {"holes_filled", r.holes},
          {"method", conformal_method_name(c.method)},
          {"fallback_reason", c.fallback_reason},
          {"iterations", c.iterations},
          {"factorizations", c.factorizations},
          {"energy", c.energy},
          {"energy_excess", c.energy_excess},
          {"intrinsic_flips", c.intrinsic_flips},
          {"splits",
           {{"chords", c.split_chords}, {"ears", c.split_ears}, {"obtuse_boundary", c.split_obtuse_boundary}, {"caps", c.split_caps}}},
          {"seconds",
           {{"load_and_prepare", r.seconds_load},
            {"precondition", c.seconds_prepare},
            {"initial_map", c.seconds_initial},
            {"flow", c.seconds_flow},
            {"finish", c.seconds_finish},
            {"map_total", r.seconds_map},
            {"resample_positions_N256", r.seconds_grid},
            {"resample_texture_1024", r.seconds_texture}}},
          {"angle_error_degrees", {{"mean", d.mean_degrees}, {"p95", d.p95_degrees}, {"max", d.max_degrees}}},
          {"mu", {{"mean", d.mu_mean}, {"max", d.mu_max}}},
          {"flipped_after", d.flipped},
          {"flipped_before_untangling", c.flipped_triangles},
          {"untangled_vertices", c.untangled_vertices},
          {"checkerboard_within_1_degree", d.checkerboard_within_1_degree},
          {"checkerboard_histogram_45_to_135", d.checkerboard_histogram},
          {"lambda2_max_over_min", r.lambda2_ratio}};
}

}  // namespace

void add_conformal_command(CLI::App& app, ConformalBenchOptions& options) {
  CLI::App* cmd = app.add_subcommand("conformal", "Riemann conformal map: angle distortion, flips, time per stage");
  cmd->add_option("inputs", options.inputs,
                  "Meshes, capture folders (every frame) or synth:N (a synthetic face of N vertices). "
                  "None: synth:20000 synth:50000 synth:100000, the Medusa capture and the ICT face from --data");
  cmd->add_option("--method", options.method, "qiem | linear | both")->capture_default_str();
  cmd->add_option("--data", options.data, "Folder of the shared real data")->capture_default_str();
  cmd->add_option("--mesh-out", options.mesh_out, "Write the mapped surface (validated, hole-filled) of the first input");
  cmd->add_option("--disk-out", options.disk_out, "Write its disk embedding (z = 0; same vertices and faces as --mesh-out)");
  cmd->add_option("--pictures", options.pictures, "Folder for pictures: checkerboard on the face, the disk, the angle histogram");
  cmd->add_option("--json", options.json_out, "Also write the results as JSON to this file ('-': standard output)");
  cmd->footer(
      "Columns: iterations and factorisations of QIEM; seconds to load+validate, for the linear start, the flow, the "
      "whole map; corner-angle error mean/p95/max (degrees); mean |mu|; flipped triangles left; vertices moved to "
      "unflip; lambda^2 max/min (crowding); seconds to resample positions onto G (N=256) and the texture (1024^2, "
      "-1 without an image). Captures: medians over frames (worst for max and lambda), then a line on the worst frame.");
  cmd->add_flag("-q,--quiet", options.quiet, "No progress display");
  cmd->add_flag(
      "--sweep", options.sweep,
      "Every frame of every input through the encoder's map (QIEM with its fallbacks), failures caught: counts by outcome "
      "(qiem, linear, tutte, failed), preconditioning left-overs, time. tools/bench/conformal_sweep.sh makes the standard inputs");
  cmd->add_option("--threads", options.threads, "Worker threads for --sweep (0: one per core)")->capture_default_str();
}

namespace {

struct SweepFrame {
  std::string name;
  std::string outcome;  // "qiem", "linear", "tutte" or "failed"
  std::string reason;   // why QIEM was not used, or why the frame failed
  std::string repair;   // what preparation repaired (RepairReport::summary)
  int caps_left = 0, obtuse_left = 0, vertices = 0;
  double seconds = 0;
};

// fmbench conformal --sweep: what fmenc's mapping stage makes of every frame.
int run_conformal_sweep(const ConformalBenchOptions& options) {
  if (options.inputs.empty())
    throw Error(ErrorCode::kInvalidArgument, "--sweep needs inputs (tools/bench/conformal_sweep.sh makes the standard ones)");
  json results = json::array();
  std::printf("%-40s %6s %6s %6s %6s %6s %9s %9s %8s %8s\n", "input", "frames", "qiem", "linear", "tutte", "failed", "caps left",
              "obtuse l.", "median s", "worst s");
  for (const std::string& input : options.inputs) {
    const BenchSource source = open_bench_source(input);
    std::vector<SweepFrame> frames(source.frames);
    Progress progress("sweep " + fs::path(input).filename().string(), options.quiet);
    parallel_for(
        static_cast<int>(source.frames), options.threads,
        [&](int i) {
          SweepFrame& r = frames[static_cast<size_t>(i)];
          r.name = source.frame_name(static_cast<size_t>(i));
          const auto start = std::chrono::steady_clock::now();
          try {
            const BenchFrame frame = source.frame(static_cast<size_t>(i));
            const MappedFrame mapped = map_frame(frame.mesh, r.name, frame.landmarks);
            const ConformalReport& c = mapped.map.report;
            r.outcome = conformal_method_name(c.method);
            r.reason = c.fallback_reason;
            r.caps_left = c.caps_left;
            r.obtuse_left = c.obtuse_boundary_left;
            r.vertices = mapped.map.surface.vertex_count();
            r.repair = mapped.prepared.report.summary();
          } catch (const Error& e) {
            r.outcome = "failed";
            r.reason = e.what();
          }
          r.seconds = seconds_since(start);
        },
        [&](int done, int total) { progress.update(done, total); });
    progress.finish();
    auto count = [&](const char* outcome) {
      return static_cast<int>(std::count_if(frames.begin(), frames.end(), [&](const SweepFrame& f) { return f.outcome == outcome; }));
    };
    std::vector<double> seconds;
    int caps = 0, obtuse = 0;
    json per_frame = json::array();
    for (const SweepFrame& f : frames) {
      seconds.push_back(f.seconds);
      caps += f.caps_left > 0;
      obtuse += f.obtuse_left > 0;
      per_frame.push_back({{"frame", f.name},
                           {"outcome", f.outcome},
                           {"reason", f.reason},
                           {"caps_left", f.caps_left},
                           {"obtuse_boundary_left", f.obtuse_left},
                           {"vertices", f.vertices},
                           {"seconds", f.seconds},
                           {"repair", f.repair}});
    }
    const std::string label = input.size() > 40 ? "..." + input.substr(input.size() - 37) : input;
    std::printf("%-40s %6zu %6d %6d %6d %6d %9d %9d %8.3f %8.3f\n", label.c_str(), frames.size(), count("qiem"), count("linear"),
                count("tutte"), count("failed"), caps, obtuse, percentile(seconds, 0.5), percentile(seconds, 1.0));
    for (const SweepFrame& f : frames) {
      if (f.outcome != "qiem") std::printf("    %s: %s: %s\n", f.name.c_str(), f.outcome.c_str(), f.reason.c_str());
    }
    // Scans with defects (fmsynth --defects, real scans): repaired before the map, said once.
    const auto repaired = std::count_if(frames.begin(), frames.end(),
                                        [](const SweepFrame& f) { return !f.repair.empty() && f.repair != "valid as captured"; });
    const auto first = std::find_if(frames.begin(), frames.end(),
                                    [](const SweepFrame& f) { return !f.repair.empty() && f.repair != "valid as captured"; });
    if (repaired > 0) std::printf("    %td frames repaired, e.g. %s: %s\n", repaired, first->name.c_str(), first->repair.c_str());
    results.push_back({{"input", input},
                       {"frames", frames.size()},
                       {"qiem", count("qiem")},
                       {"linear", count("linear")},
                       {"tutte", count("tutte")},
                       {"failed", count("failed")},
                       {"frames_repaired", repaired},
                       {"frames_with_caps_left", caps},
                       {"frames_with_obtuse_boundary_left", obtuse},
                       {"median_seconds", percentile(seconds, 0.5)},
                       {"worst_seconds", percentile(seconds, 1.0)},
                       {"per_frame", per_frame}});
  }
  if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "conformal-sweep"}, {"results", results}});
  return 0;
}

}  // namespace

int run_conformal_bench(const ConformalBenchOptions& options) {
  if (options.sweep) return run_conformal_sweep(options);
  std::vector<std::string> inputs = options.inputs;
  if (inputs.empty()) inputs = default_bench_inputs(options.data, /*large_synthetic=*/true);
  std::vector<ConformalMethod> methods;
  if (options.method == "both" || options.method == "qiem") methods.push_back(ConformalMethod::kQiem);
  if (options.method == "both" || options.method == "linear") methods.push_back(ConformalMethod::kLinear);
  if (methods.empty()) throw Error(ErrorCode::kInvalidArgument, "--method must be qiem, linear or both");

  const DiskGrid grid = make_disk_grid(256);
  json results = json::array();
  std::printf("%-34s %-6s %6s %7s %5s %5s %7s %7s %7s %7s %6s %6s %6s %7s %5s %5s %9s %6s %6s\n", "input", "method", "frames", "verts",
              "iters", "fact", "prep s", "init s", "flow s", "total s", "mean°", "p95°", "max°", "|mu|", "flip", "untg", "lam2 rng",
              "grid s", "tex s");
  bool first_output = true;
  for (const std::string& input : inputs) {
    const BenchSource source = open_bench_source(input);
    for (ConformalMethod method : methods) {
      std::vector<FrameResult> frames;
      Progress progress("conformal " + fs::path(input).filename().string(), options.quiet || source.frames < 8);
      for (size_t i = 0; i < source.frames; ++i) {
        FrameResult r;
        r.name = source.frame_name(i);
        auto start = std::chrono::steady_clock::now();
        const BenchFrame input_frame = source.frame(i);
        const double seconds_read = seconds_since(start);
        const TriangleMesh& mesh = input_frame.mesh;
        MapFrameOptions map_options;
        map_options.conformal.method = method;
        const MappedFrame mapped = map_frame(mesh, r.name, input_frame.landmarks, map_options);
        const DiskMap& map = mapped.map;
        r.seconds_load = seconds_read + mapped.seconds_prepare;
        r.seconds_map = mapped.seconds_map;
        r.holes = static_cast<int>(mapped.prepared.report.holes.size());
        r.vertices = map.surface.vertex_count();
        r.faces = map.surface.face_count();
        r.report = map.report;
        r.distortion = measure_distortion(map);
        start = std::chrono::steady_clock::now();
        (void)sample_on_grid(mapped, grid);
        r.seconds_grid = seconds_since(start);
        if (!mesh.texture.empty() && map.surface.has_uvs()) {
          const Image image = read_image(mesh.texture);
          const InverseDiskMap inverse(map);
          start = std::chrono::steady_clock::now();
          (void)resample_texture(map, inverse, image, 1024);
          r.seconds_texture = seconds_since(start);
        }
        const Eigen::VectorXd lambda = conformal_factor(map);
        r.lambda2_ratio = std::pow(lambda.maxCoeff() / lambda.minCoeff(), 2);
        if (i == 0 && method == methods.front()) {
          if (first_output) write_mesh_pair(map, options.mesh_out, options.disk_out);
          if (!options.pictures.empty()) write_pictures(options.pictures, slug(input) + "_" + conformal_method_name(method), map);
        }
        frames.push_back(std::move(r));
        progress.update(static_cast<int>(i + 1), static_cast<int>(source.frames));
      }
      progress.finish();
      first_output = false;

      auto collect = [&](auto&& field) {
        std::vector<double> v;
        for (const FrameResult& r : frames) v.push_back(static_cast<double>(field(r)));
        return v;
      };
      auto median = [&](auto&& field) { return percentile(collect(field), 0.5); };
      auto worst = [&](auto&& field) { return percentile(collect(field), 1.0); };
      int flips = 0, untangled = 0, fallbacks = 0;
      for (const FrameResult& r : frames) {
        flips += r.distortion.flipped;
        untangled += r.report.untangled_vertices;
        fallbacks += !r.report.fallback_reason.empty();
      }
      const bool many = frames.size() > 1;
      std::string label = input.size() > 34 ? "..." + input.substr(input.size() - 31) : input;
      std::printf("%-34s %-6s %6zu %7.0f %5.0f %5.0f %7.3f %7.3f %7.3f %7.3f %6.2f %6.2f %6.1f %7.4f %5d %5d %9.2e %6.3f %6.3f\n",
                  label.c_str(), conformal_method_name(method), frames.size(), median([](auto& r) { return r.vertices; }),
                  median([](auto& r) { return r.report.iterations; }), median([](auto& r) { return r.report.factorizations; }),
                  median([](auto& r) { return r.seconds_load + r.report.seconds_prepare; }),
                  median([](auto& r) { return r.report.seconds_initial; }), median([](auto& r) { return r.report.seconds_flow; }),
                  median([](auto& r) { return r.seconds_map; }), median([](auto& r) { return r.distortion.mean_degrees; }),
                  median([](auto& r) { return r.distortion.p95_degrees; }), worst([](auto& r) { return r.distortion.max_degrees; }),
                  median([](auto& r) { return r.distortion.mu_mean; }), flips, untangled, worst([](auto& r) { return r.lambda2_ratio; }),
                  median([](auto& r) { return r.seconds_grid; }), median([](auto& r) { return r.seconds_texture; }));
      if (many) {
        std::printf("%-34s %-6s worst frame: total %.3f s, mean %.2f°, p95 %.2f°; frames over mean 2.5°: %d, over p95 8°: %d%s\n", "", "",
                    worst([](auto& r) { return r.seconds_map; }), worst([](auto& r) { return r.distortion.mean_degrees; }),
                    worst([](auto& r) { return r.distortion.p95_degrees; }),
                    static_cast<int>(std::count_if(frames.begin(), frames.end(), [](auto& r) { return r.distortion.mean_degrees > 2.5; })),
                    static_cast<int>(std::count_if(frames.begin(), frames.end(), [](auto& r) { return r.distortion.p95_degrees > 8.0; })),
                    fallbacks ? (", " + std::to_string(fallbacks) + " fell back to linear").c_str() : "");
      }
      json entry = {{"input", input},
                    {"method", conformal_method_name(method)},
                    {"frames", frames.size()},
                    {"flipped_total", flips},
                    {"untangled_vertices_total", untangled},
                    {"fallbacks", fallbacks},
                    {"median",
                     {{"map_seconds", median([](auto& r) { return r.seconds_map; })},
                      {"mean_degrees", median([](auto& r) { return r.distortion.mean_degrees; })},
                      {"p95_degrees", median([](auto& r) { return r.distortion.p95_degrees; })}}},
                    {"worst",
                     {{"map_seconds", worst([](auto& r) { return r.seconds_map; })},
                      {"mean_degrees", worst([](auto& r) { return r.distortion.mean_degrees; })},
                      {"p95_degrees", worst([](auto& r) { return r.distortion.p95_degrees; })},
                      {"max_degrees", worst([](auto& r) { return r.distortion.max_degrees; })}}}};
      json per_frame = json::array();
      for (const FrameResult& r : frames) per_frame.push_back(frame_json(r));
      entry["per_frame"] = std::move(per_frame);
      results.push_back(std::move(entry));
    }
  }
  if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "conformal"}, {"results", results}});
  return 0;
}

}  // namespace facemorph::tools
