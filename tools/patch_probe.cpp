// patch_probe: what frame patches (spec/method.md §7.19) would cost on a capture and its file, in the
// encoder alone. Decodes every captured frame as fmbench --geometry-only does, and for each frame
// whose 99th-percentile point error passes the bound fits a patch at each lattice size asked for:
// its p99 after rounding, its moving nodes, its bytes (varints; zstd over all of a size's patches).
//   patch_probe CAPTURE FILE.fmv [--lattice 17 --lattice 33 ...] [--bound 0.01] [--step 0.0005]
#include "codec/core/util/parallel.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/zstd_frame.hpp"
#include "tools/tool_support.hpp"

#include <algorithm>
#include <cstdio>

using namespace facemorph;

int main(int argc, char** argv) {
  CLI::App app("The bytes frame patches would take", "patch_probe");
  std::string capture_path, fmv;
  std::vector<int> lattices;
  double bound = 0.01, step = 0.0005, smoothing = 0.1;
  int threads = 2;
  bool measure = false;
  app.add_option("capture", capture_path)->required();
  app.add_option("fmv", fmv)->required();
  app.add_option("--lattice", lattices);
  app.add_option("--bound", bound);
  app.add_option("--step", step);
  app.add_option("--smoothing", smoothing);
  app.add_option("--threads", threads);
  app.add_flag(
      "--measure", measure,
      "Only measure the file as fmbench --geometry-only does: held-out RMS mean and worst, the worst frame's p99, of the diagonal");
  return tools::guarded_main(app, argc, argv, [&] {
    if (lattices.empty()) lattices = {17, 33, 65};
    const Capture capture = read_capture(capture_path);
    const auto source = open_sequence_source(fmv);
    SequenceDecoder decoder(source);
    DecodeOptions decode;
    decode.ignore_sane_range = true;
    decode.reconstruct.throw_on_failure = false;
    const int count = static_cast<int>(capture.frames.size());
    std::vector<ShownFrame> shown(static_cast<size_t>(count));
    for (int i = 0; i < count; ++i) {
      DecodedFrame f = decoder.decode(capture.frames[static_cast<size_t>(i)].time, decode);
      shown[static_cast<size_t>(i)] = {std::move(f.grid_positions), std::move(f.hole_level), f.pose};
    }
    const DiskGrid& grid = decoder.geometry().grid();
    if (measure) {
      std::vector<double> rms(static_cast<size_t>(count)), p99(static_cast<size_t>(count));
      parallel_for(count, threads, [&](int i) {
        const auto& f = shown[static_cast<size_t>(i)];
        const SurfaceDistance d = surface_distance(read_mesh(capture.mesh_path(static_cast<size_t>(i)), {.allow_missing_texture = true}),
                                                   shown_mesh(grid, f.positions, f.hole_level));
        rms[static_cast<size_t>(i)] = d.rms / d.diagonal;
        p99[static_cast<size_t>(i)] = d.p99 / d.diagonal;
      });
      double mean = 0, worst = 0, worst_p99 = 0;
      int held = 0;
      for (int i = 0; i < count; ++i) {
        worst_p99 = std::max(worst_p99, p99[static_cast<size_t>(i)]);
        const double t = capture.frames[static_cast<size_t>(i)].time;
        const auto& times = source->outline().times;
        if (std::any_of(times.begin(), times.end(), [&](double k) { return std::abs(k - t) < 0.25 / capture.fps; })) continue;
        ++held;
        mean += rms[static_cast<size_t>(i)];
        worst = std::max(worst, rms[static_cast<size_t>(i)]);
      }
      std::printf(
          "%s: %llu bytes, %zu keyframes of %d frames, %zu patches; held-out RMS %.4f%% mean, %.4f%% worst; 99th percentile %.4f%% worst "
          "frame\n",
          fmv.c_str(), static_cast<unsigned long long>(std::filesystem::file_size(fmv)), source->outline().keyframe_count(), count,
          source->outline().patches.size(), held ? 100 * mean / held : 0.0, 100 * worst, 100 * worst_p99);
      return 0;
    }
    std::vector<std::vector<PatchFit>> fits(static_cast<size_t>(count));
    std::vector<double> diagonals(static_cast<size_t>(count));
    parallel_for(count, threads, [&](int i) {
      const TriangleMesh captured = read_mesh(capture.mesh_path(static_cast<size_t>(i)), {.allow_missing_texture = true});
      diagonals[static_cast<size_t>(i)] = bounding_box_diagonal(captured.positions);
      for (int c : lattices) {
        fits[static_cast<size_t>(i)].push_back(fit_frame_patch(
            grid, shown[static_cast<size_t>(i)], captured, capture.frames[static_cast<size_t>(i)].time,
            {.lattice = c, .bound = bound, .step_units = step * diagonals[static_cast<size_t>(i)], .smoothing = smoothing}));
      }
    });
    std::printf("%s: %d frames, %zu keyframes, %llu bytes\n", fmv.c_str(), count, source->outline().keyframe_count(),
                static_cast<unsigned long long>(std::filesystem::file_size(fmv)));
    for (size_t l = 0; l < lattices.size(); ++l) {
      int over = 0, patched = 0, nodes = 0;
      double worst_before = 0, worst_after = 0;
      std::vector<uint8_t> all;
      for (int i = 0; i < count; ++i) {
        const PatchFit& f = fits[static_cast<size_t>(i)][l];
        worst_before = std::max(worst_before, f.p99_before);
        worst_after = std::max(worst_after, f.p99_after);
        if (f.p99_before > bound) ++over;
        if (f.patch.nodes.empty()) continue;
        ++patched;
        nodes += static_cast<int>(f.patch.nodes.size());
        const auto bytes = patch_payload(f.patch, step * diagonals[static_cast<size_t>(i)]);
        all.insert(all.end(), bytes.begin(), bytes.end());
        if (l == 0 || lattices.size() == 1) std::printf("  frame %d t=%.3f: p99 %.3f%%", i, f.patch.time, 100 * f.p99_before);
        if (l == 0 || lattices.size() == 1)
          std::printf(" -> %.3f%% (C=%d, %zu nodes, %zu B)\n", 100 * f.p99_after, lattices[l], f.patch.nodes.size(), bytes.size());
      }
      const auto packed = all.empty() ? std::vector<uint8_t>{} : format::compress_frame(all, 19);
      std::printf(
          "C = %d: %d frames over %.2f%%, %d patched, %d nodes; %zu B raw, %zu B zstd (%.1f B a patched frame); worst p99 %.3f%% -> "
          "%.3f%%\n",
          lattices[l], over, 100 * bound, patched, nodes, all.size(), packed.size(),
          patched ? static_cast<double>(packed.size()) / patched : 0.0, 100 * worst_before, 100 * worst_after);
    }
    return 0;
  });
}
