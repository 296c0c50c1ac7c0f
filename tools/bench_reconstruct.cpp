// fmbench reconstruct: the keyframe round trip (frame -> conformal map -> grid -> fields -> 16 bits
// -> Laplace-Beltrami reconstruction) for each representation, and the decoder's speed.
#include "tools/bench_reconstruct.hpp"

#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tools/bench_inputs.hpp"
#include "tools/tool_support.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace facemorph::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct RoundTrip {
  Representation representation;
  bool quantized;
  size_t bytes = 0;  // compressed 16-bit fields (compressed_bytes)
  int iterations = 0;
  bool converged = false;
  double change = 0, seconds = 0;
  double rms = 0, max = 0;                          // symmetric point-to-surface, relative to the frame's bbox diagonal
  double disk_l2 = 0, disk_linf = 0, disk_rms = 0;  // against the resampled surface on G (capture units)
};

// Bytes of a file holding the fields as its one keyframe, at 16-bit precision (the writer's steps
// where none are given: a 65535th of each array's range).
size_t compressed_bytes(const GridFields& fields) {
  Sequence one;
  one.grid_n = fields.grid_n;
  one.representation = fields.representation;
  one.fps = 30;
  one.keyframes.push_back(Keyframe{0, fields, RigidPose{}, {}, {}});
  return encode_sequence_file(one, {}).size();
}

std::vector<Representation> representations(const std::string& which) {
  if (which == "all") return {Representation::kHLT, Representation::kHL, Representation::kXYZ};
  return {parse_representation(which)};
}

// The paper's measures over the disk: L∞ = max |e|, L2 = (∫_D |e|²)^½ with the lumped mass as the
// quadrature, RMS = L2 / √π (spec/method.md §5.5).
void disk_errors(const GridGeometry& geometry, const std::vector<Vec3>& truth, const std::vector<Vec3>& test, RoundTrip& r) {
  double integral = 0;
  for (size_t v = 0; v < truth.size(); ++v) {
    const double e = (truth[v] - test[v]).norm();
    r.disk_linf = std::max(r.disk_linf, e);
    if (v < static_cast<size_t>(geometry.interior_count())) integral += geometry.mass()[static_cast<Eigen::Index>(v)] * e * e;
  }
  r.disk_l2 = std::sqrt(integral);
  r.disk_rms = r.disk_l2 / std::sqrt(std::numbers::pi);
}

}  // namespace

void add_reconstruct_command(CLI::App& app, ReconstructBenchOptions& options) {
  CLI::App* cmd = app.add_subcommand("reconstruct", "Keyframe round trip through (H, λ) and the Laplace-Beltrami decoder; decode speed");
  cmd->add_option("inputs", options.inputs,
                  "Meshes, capture folders (every frame) or synth:N. None: synth:20000, the Medusa capture and the ICT face from --data");
  cmd->add_option("--grid", options.grid, "Grid size N")->capture_default_str()->check(CLI::Range(9, 2049));
  cmd->add_option("--representation", options.representation, "hl | hl+t | xyz | all")->capture_default_str();
  cmd->add_option("--data", options.data, "Folder of the shared real data")->capture_default_str();
  cmd->add_option("--out", options.out, "Write the first frame's reconstruction (default representation, 16 bits)");
  cmd->add_option("--json", options.json_out, "Also write the results as JSON to this file ('-': standard output)");
  cmd->add_option("--limit", options.limit, "At most this many frames per capture (0: all)")->capture_default_str();
  cmd->add_flag("--speed", options.speed, "Measure decode speed at N = 64, 128, 256, 512 (cold and warm) on a synthetic sequence");
  cmd->add_option("--rotation", options.rotation,
                  "Head rotation test: two keyframes of a synthetic face turning by this many degrees, the midpoint decoded "
                  "from their blended fields, per representation (repeatable)");
  cmd->add_flag("-q,--quiet", options.quiet, "No progress display");
  cmd->footer(
      "Round trip: the frame's surface against the reconstruction from its own fields, as symmetric point-to-surface "
      "distance (RMS, max) relative to the frame's bounding-box diagonal, in float (f64) and at the stored 16 bits (q16); "
      "'floor'/'flrmax' are the grid resampling alone (RMS/max). L2/Linf: the paper's measures over the disk against the resampled "
      "surface.");
}

int run_reconstruct_bench(const ReconstructBenchOptions& options) {
  std::vector<std::string> inputs = options.inputs;
  if (inputs.empty() && !options.speed && options.rotation.empty()) inputs = default_bench_inputs(options.data, /*large_synthetic=*/false);
  const std::vector<Representation> reps = representations(options.representation);
  json results = json::array();
  if (!inputs.empty()) {
    Reconstructor reconstructor(options.grid);
    const GridGeometry& geometry = reconstructor.geometry();
    std::printf("grid N = %d: %d interior nodes (%d in the rim band), %d rim samples\n", options.grid, geometry.interior_count(),
                geometry.band_count(), geometry.grid().rim_count);
    std::printf("%-34s %6s %-5s %-4s %6s %5s %9s %9s %9s %9s %9s %11s %11s %8s\n", "input", "frames", "repr", "bits", "iters", "conv",
                "floor %", "rms %", "flrmax %", "max %", "worst %", "L2", "Linf", "kB/key");
    bool wrote = false;
    for (const std::string& input : inputs) {
      const BenchSource source = open_bench_source(input);
      const size_t frames = options.limit > 0 ? std::min<size_t>(source.frames, static_cast<size_t>(options.limit)) : source.frames;
      std::vector<std::vector<RoundTrip>> per_frame(frames);
      std::vector<double> floors(frames), floor_max(frames);
      Progress progress("reconstruct " + fs::path(input).filename().string(), options.quiet || frames < 8);
      for (size_t i = 0; i < frames; ++i) {
        const BenchFrame input_frame = source.frame(i);
        const MappedFrame mapped = map_frame(input_frame.mesh, source.frame_name(i), input_frame.landmarks);
        const DiskMap& map = mapped.map;
        const std::vector<Vec3> sampled = sample_on_grid(mapped, geometry.grid());
        const SurfaceDistance floor = surface_distance(map.surface, grid_mesh(geometry.grid(), sampled));
        floors[i] = floor.rms / floor.diagonal;
        floor_max[i] = floor.max / floor.diagonal;
        const std::vector<int32_t> folds = folded_nodes(geometry, sampled);
        for (Representation rep : reps) {
          for (bool quantized : {false, true}) {
            const GridFields fields = keyframe_fields(geometry, sampled, rep, folds, quantized);
            RoundTrip r{rep, quantized};
            if (quantized) r.bytes = compressed_bytes(fields);
            reconstructor.forget_warm_start();
            ReconstructOptions ro;
            ro.throw_on_failure = false;
            ro.tolerance = 1e-6;  // a keyframe's round trip is measured to the notes' tolerance
            const auto start = std::chrono::steady_clock::now();
            const ReconstructResult result = reconstructor.reconstruct(fields, ro);
            r.seconds = seconds_since(start);
            r.iterations = result.iterations;
            r.converged = result.converged;
            r.change = result.change;
            const TriangleMesh decoded = grid_mesh(geometry.grid(), result.positions);
            const SurfaceDistance d = surface_distance(map.surface, decoded);
            r.rms = d.rms / d.diagonal;
            r.max = d.max / d.diagonal;
            disk_errors(geometry, sampled, result.positions, r);
            if (!wrote && !options.out.empty() && quantized && rep == reps.front()) {
              write_mesh(options.out, decoded);
              wrote = true;
            }
            per_frame[i].push_back(r);
          }
        }
        progress.update(static_cast<int>(i + 1), static_cast<int>(frames));
      }
      progress.finish();
      const std::string label = input.size() > 34 ? "..." + input.substr(input.size() - 31) : input;
      for (size_t k = 0; k < per_frame[0].size(); ++k) {
        std::vector<double> rms, max, iterations, l2, linf, bytes;
        int converged = 0;
        for (const auto& frame : per_frame) {
          rms.push_back(frame[k].rms);
          max.push_back(frame[k].max);
          iterations.push_back(frame[k].iterations);
          l2.push_back(frame[k].disk_l2);
          linf.push_back(frame[k].disk_linf);
          bytes.push_back(static_cast<double>(frame[k].bytes));
          converged += frame[k].converged;
        }
        const RoundTrip& first = per_frame[0][k];
        std::printf("%-34s %6zu %-5s %-4s %6.0f %5d %9.5f %9.5f %9.5f %9.5f %9.5f %11.3e %11.3e %8s\n", label.c_str(), frames,
                    representation_name(first.representation), first.quantized ? "q16" : "f64", percentile(iterations, 0.5), converged,
                    100 * percentile(floors, 0.5), 100 * percentile(rms, 0.5), 100 * percentile(floor_max, 0.5), 100 * percentile(max, 0.5),
                    100 * percentile(rms, 1.0), percentile(l2, 0.5), percentile(linf, 0.5),
                    first.quantized ? std::to_string(static_cast<int>(std::lround(percentile(bytes, 0.5) / 1000))).c_str() : "");
        json entry = {{"input", input},
                      {"frames", frames},
                      {"representation", representation_name(first.representation)},
                      {"bits", first.quantized ? 16 : 64},
                      {"converged_frames", converged},
                      {"median_compressed_bytes_per_keyframe", first.quantized ? percentile(bytes, 0.5) : 0.0},
                      {"median",
                       {{"iterations", percentile(iterations, 0.5)},
                        {"rms_relative", percentile(rms, 0.5)},
                        {"max_relative", percentile(max, 0.5)},
                        {"resampling_floor_rms_relative", percentile(floors, 0.5)},
                        {"resampling_floor_max_relative", percentile(floor_max, 0.5)},
                        {"disk_l2", percentile(l2, 0.5)},
                        {"disk_linf", percentile(linf, 0.5)}}},
                      {"worst",
                       {{"rms_relative", percentile(rms, 1.0)},
                        {"max_relative", percentile(max, 1.0)},
                        {"iterations", percentile(iterations, 1.0)}}}};
        json frames_json = json::array();
        for (size_t i = 0; i < per_frame.size(); ++i) {
          const RoundTrip& r = per_frame[i][k];
          frames_json.push_back({{"frame", source.frame_name(i)},
                                 {"iterations", r.iterations},
                                 {"converged", r.converged},
                                 {"last_change", r.change},
                                 {"seconds", r.seconds},
                                 {"rms_relative", r.rms},
                                 {"max_relative", r.max},
                                 {"disk_l2", r.disk_l2},
                                 {"disk_linf", r.disk_linf},
                                 {"disk_rms", r.disk_rms},
                                 {"resampling_floor_rms_relative", floors[i]},
                                 {"resampling_floor_max_relative", floor_max[i]}});
        }
        entry["per_frame"] = std::move(frames_json);
        results.push_back(std::move(entry));
      }
    }
  }
  json speed = json::array();
  if (options.speed) speed = run_decode_speed(options.quiet);
  json rotation = json::array();
  for (double degrees : options.rotation) rotation.push_back(run_rotation_experiment(options.grid, degrees));
  if (!options.json_out.empty())
    write_json(options.json_out,
               {{"benchmark", "reconstruct"}, {"grid", options.grid}, {"round_trip", results}, {"speed", speed}, {"rotation", rotation}});
  return 0;
}

json run_rotation_experiment(int grid_n, double degrees) {
  // Keyframes: one synthetic face turned rigidly about the neck (yaw) by 0 and by `degrees`; the
  // truth at the midpoint is the face turned by half. Every difference between the representations
  // is then how they interpolate a rotation: (H, λ, a, b) do not change under it, positions do.
  const SyntheticFace face(Expression::kMixed, 1);
  const double t = 0.5;
  const Vec3 pivot(0, -0.12, -0.05);
  auto turned = [&](double angle_degrees) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle_degrees * std::numbers::pi / 180, Vec3::UnitY()).toRotationMatrix();
    return [R, pivot](const Vec3& p) { return Vec3(R * (p - pivot) + pivot); };
  };
  Reconstructor reconstructor(grid_n);
  std::vector<Vec3> sampled[2];
  const TriangleMesh base = face.truth_mesh(t, 8000);
  for (int k = 0; k < 2; ++k) {
    const auto rotate = turned(k * degrees);
    TriangleMesh mesh = base;
    for (Vec3& p : mesh.positions) p = rotate(p);
    FrameLandmarks landmarks = synthetic_landmarks(face, t);
    landmarks.centre = rotate(*landmarks.centre);
    landmarks.up = rotate(*landmarks.up);
    for (Vec3& p : landmarks.rim_markers) p = rotate(p);
    sampled[k] = sample_on_grid(map_frame(mesh, "turned face", landmarks), reconstructor.geometry().grid());
  }
  TriangleMesh truth = face.truth_mesh(t, 20000);
  const auto half = turned(degrees / 2);
  for (Vec3& p : truth.positions) p = half(p);
  std::printf("\nhead rotation %.0f°: one face turned by 0 and %.0f° about the neck, the midpoint decoded from the fields blended 50/50\n",
              degrees, degrees);
  json out = {{"degrees", degrees}, {"grid", grid_n}};
  for (Representation rep : {Representation::kHLT, Representation::kHL, Representation::kXYZ}) {
    const GridFields a = keyframe_fields(reconstructor.geometry(), sampled[0], rep);
    const GridFields b = keyframe_fields(reconstructor.geometry(), sampled[1], rep);
    reconstructor.forget_warm_start();
    ReconstructOptions ro;
    ro.throw_on_failure = false;
    const ReconstructResult r = reconstructor.reconstruct(combine_fields({&a, &b}, {0.5, 0.5}), ro);
    const SurfaceDistance d = surface_distance(truth, grid_mesh(reconstructor.geometry().grid(), r.positions));
    std::printf("  %-5s midpoint error: rms %.4f%%, max %.4f%% of the diagonal (%d iterations%s)\n", representation_name(rep),
                100 * d.rms / d.diagonal, 100 * d.max / d.diagonal, r.iterations, r.converged ? "" : ", not converged");
    out[representation_name(rep)] = {{"rms_relative", d.rms / d.diagonal},
                                     {"max_relative", d.max / d.diagonal},
                                     {"iterations", r.iterations},
                                     {"converged", r.converged}};
  }
  return out;
}

json run_decode_speed(bool quiet) {
  // A 1-second synthetic sequence: 30 frames, each mapped once and resampled at every N.
  const SyntheticFace face(Expression::kMixed, 1);
  const int frames = 30;
  std::vector<MappedFrame> maps;
  Progress progress("mapping the sequence", quiet);
  for (int i = 0; i < frames; ++i) {
    const double t = i / 30.0;
    maps.push_back(map_frame(face.truth_mesh(t, 8000), "synthetic frame", synthetic_landmarks(face, t)));
    progress.update(i + 1, frames);
  }
  progress.finish();
  std::printf("\ndecode speed, one thread, hl+t at 16 bits, a %d-frame synthetic sequence\n", frames);
  std::printf("%6s %9s %10s %10s %10s %11s %11s %10s %10s\n", "N", "nodes", "setup s", "solver MB", "cold ms", "cold iters", "warm ms",
              "warm iters", "warm fps");
  json out = json::array();
  const ReconstructOptions ro;  // the decoder's defaults
  for (int n : {64, 128, 256, 512}) {
    auto start = std::chrono::steady_clock::now();
    Reconstructor reconstructor(n);
    const double setup_seconds = seconds_since(start);  // G, its operators and the multigrid hierarchy
    std::vector<GridFields> fields;
    for (const MappedFrame& map : maps) {
      fields.push_back(
          keyframe_fields(reconstructor.geometry(), sample_on_grid(map, reconstructor.geometry().grid()), Representation::kHLT));
    }
    start = std::chrono::steady_clock::now();
    const ReconstructResult cold = reconstructor.reconstruct(fields[0], ro);
    const double cold_ms = 1e3 * seconds_since(start);
    double warm_seconds = 0;
    int warm_iterations = 0;
    for (int i = 1; i < frames; ++i) {
      start = std::chrono::steady_clock::now();
      warm_iterations += reconstructor.reconstruct(fields[static_cast<size_t>(i)], ro).iterations;
      warm_seconds += seconds_since(start);
    }
    const double warm_ms = 1e3 * warm_seconds / (frames - 1);
    const double warm_mean_iterations = static_cast<double>(warm_iterations) / (frames - 1);
    std::printf("%6d %9d %10.3f %10.1f %10.2f %11d %11.2f %10.1f %10.1f\n", n, reconstructor.geometry().grid().node_count(), setup_seconds,
                reconstructor.solver_bytes() / 1e6, cold_ms, cold.iterations, warm_ms, warm_mean_iterations, 1e3 / warm_ms);
    out.push_back({{"grid", n},
                   {"nodes", reconstructor.geometry().grid().node_count()},
                   {"setup_seconds", setup_seconds},
                   {"solver_bytes", reconstructor.solver_bytes()},
                   {"cold_ms", cold_ms},
                   {"cold_iterations", cold.iterations},
                   {"warm_ms", warm_ms},
                   {"warm_iterations", warm_mean_iterations},
                   {"warm_fps", 1e3 / warm_ms}});
  }
  return out;
}

}  // namespace facemorph::tools
