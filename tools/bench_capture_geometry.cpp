// fmbench --capture --geometry-only: a given file's geometry error on every frame of its capture.
#include "tools/bench_capture_parts.hpp"

#include "codec/core/util/parallel.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"
#include "facemorph/decoder.hpp"

#include "tools/bench_sequence.hpp"
#include "tools/plot.hpp"
#include "tools/tool_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <utility>

#include <sys/resource.h>
#include <unistd.h>

namespace facemorph::tools::capture_bench {

namespace fs = std::filesystem;
using nlohmann::json;

json measure_geometry_only(const CaptureBenchOptions& options, const std::string& input) {
  const Capture capture = read_capture(input);
  // Opened as a player opens it: keyframes decoded on demand, memory bounded whatever the length.
  const std::shared_ptr<const KeyframeSource> source = open_sequence_source(options.fmv);
  const SequenceOutline& sequence = source->outline();
  const uint64_t file_bytes = std::filesystem::file_size(options.fmv);
  const int count = static_cast<int>(capture.frames.size());
  // The file's span that of the capture, and each keyframe on the frame at its time: a file made
  // from another capture (or other frames of this one) is refused rather than measured against
  // frames it never held.
  const double slack = 0.25 / capture.fps;
  if (count == 0 || std::abs(sequence.first_time - capture.frames.front().time) > slack ||
      std::abs(sequence.last_time - capture.frames.back().time) > slack) {
    throw Error(
        ErrorCode::kInvalidArgument,
        options.fmv + " spans " + std::to_string(sequence.first_time) + " to " + std::to_string(sequence.last_time) + " s, " + input + " " +
            (count == 0 ? std::string("has no frames")
                        : std::to_string(capture.frames.front().time) + " to " + std::to_string(capture.frames.back().time) + " s") +
            ": its keyframes are no frames of it (was the file made from another capture?)");
  }
  std::vector<int> keyframes;
  for (double time : sequence.times) {
    const int nearest = nearest_frame(capture, time);
    if (std::abs(capture.frames[static_cast<size_t>(nearest)].time - time) > slack || (!keyframes.empty() && keyframes.back() == nearest)) {
      throw Error(ErrorCode::kInvalidArgument, options.fmv + ": its keyframe at " + std::to_string(time) + " s is no frame of " + input +
                                                   " (was the file made from another capture?)");
    }
    keyframes.push_back(nearest);
  }
  Evaluation e;
  e.keyframes = static_cast<int>(sequence.keyframe_count());
  e.grid = sequence.grid_n;
  e.registration = "as encoded";
  e.spline = spline_kind_name(sequence.spline);
  e.frames.resize(static_cast<size_t>(count));
  // --against: the other file's surface at every frame, RMS distance of G's nodes / the diagonal.
  const std::shared_ptr<const KeyframeSource> other = options.against.empty() ? nullptr : open_sequence_source(options.against);
  if (other && other->outline().grid_n != sequence.grid_n)
    throw Error(ErrorCode::kInvalidArgument, options.against + ": another grid than " + options.fmv + "'s");
  std::vector<double> apart(static_cast<size_t>(count), 0.0);
  Progress progress(input, options.quiet);
  int done = 0;
  std::mutex progress_lock;  // guards done and the progress display
  // Runs of frames, each decoded in order by a decoder of its own: a decoder starts a frame from the
  // ones it decoded before, so fixed runs give the same figures on every run and machine.
  constexpr int kRun = 16;
  const int runs = (count + kRun - 1) / kRun;
  parallel_for(runs, 0, [&](int r) {
    SequenceDecoder decoder(source);
    std::optional<SequenceDecoder> other_decoder;
    if (other) other_decoder.emplace(other);
    DecodeOptions decode;
    decode.ignore_sane_range = true;
    decode.reconstruct.throw_on_failure = false;
    for (int i = r * kRun; i < std::min(count, (r + 1) * kRun); ++i) {
      FrameError& f = e.frames[static_cast<size_t>(i)];
      f.time = capture.frames[static_cast<size_t>(i)].time;
      f.keyframe = std::binary_search(keyframes.begin(), keyframes.end(), i);
      const DecodedFrame decoded = decoder.decode(f.time, decode);
      f.converged = decoded.converged;
      const TriangleMesh captured = read_mesh(capture.mesh_path(static_cast<size_t>(i)), {.allow_missing_texture = true});
      const SurfaceDistance d = surface_distance(captured, decoded.mesh);
      record_distance(d, f);
      if (other_decoder) {
        const std::vector<Vec3>& p = decoded.grid_positions;
        const std::vector<Vec3> q = other_decoder->decode(f.time, decode).grid_positions;
        double sum = 0;
        for (size_t n = 0; n < p.size(); ++n) sum += (p[n] - q[n]).squaredNorm();
        apart[static_cast<size_t>(i)] = std::sqrt(sum / static_cast<double>(p.size())) / d.diagonal;
      }
      const std::lock_guard<std::mutex> lock(progress_lock);
      progress.update(++done, count);
    }
  });
  progress.finish();
  const Summary s = summarise(e);
  const bool held_out = static_cast<int>(keyframes.size()) < count;
  std::printf("%s: %llu bytes, %d keyframes of %d frames, N = %d; ", options.fmv.c_str(), static_cast<unsigned long long>(file_bytes),
              e.keyframes, count, e.grid);
  if (held_out) {
    std::printf("held-out RMS %.4f%% mean, %.4f%% worst, max %.4f%%; ", 100 * s.held_rms_mean, 100 * s.held_rms_worst,
                100 * s.held_max_worst);
  } else {
    std::printf("no held-out frames (every frame a keyframe); ");
  }
  std::printf("keyframes RMS %.4f%% mean, %.4f%% worst; 99th percentile %.4f%% worst frame (decoded to captured %.4f%%, captured to "
              "decoded %.4f%%)\n",
              100 * s.key_rms_mean, 100 * s.key_rms_worst, 100 * s.p99_worst, 100 * s.p99_decoded_worst, 100 * s.p99_captured_worst);
  json evaluation = evaluation_json(e);
  if (other) {
    double mean = 0;
    for (double a : apart) mean += a / static_cast<double>(count);
    const double worst = *std::max_element(apart.begin(), apart.end());
    std::printf("  decoded apart from %s: RMS %.4f%% mean, %.4f%% worst of the diagonal\n", options.against.c_str(), 100 * mean,
                100 * worst);
    evaluation["against"] = {{"fmv", options.against}, {"rms_mean", mean}, {"rms_worst", worst}};
  }
  for (const char* key : {"decode_ms_per_frame", "mean_iterations"}) evaluation.erase(key);  // not measured here
  if (!held_out) {
    for (const char* key : {"held_out_rms_mean", "held_out_rms_worst", "held_out_max_worst"}) evaluation[key] = nullptr;
  }
  return {{"input", input}, {"fmv", options.fmv}, {"bytes", file_bytes}, {"evaluation", evaluation}};
}

}  // namespace facemorph::tools::capture_bench
