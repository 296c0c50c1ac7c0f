// What fmbench's whole-capture benches share (see bench_sequence.hpp).
#include "tools/bench_sequence.hpp"

#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tools/plot.hpp"
#include "tools/tool_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include <unistd.h>

namespace facemorph::tools {
namespace fs = std::filesystem;
using nlohmann::json;

ScratchFolder::ScratchFolder(const std::string& name) : path(fs::temp_directory_path() / (name + "-" + std::to_string(::getpid()))) {
  fs::create_directories(path);
}

ScratchFolder::~ScratchFolder() {
  std::error_code ec;
  fs::remove_all(path, ec);
}

std::optional<fs::path> make_bench_capture(const std::string& input, const std::string& data, const fs::path& scratch,
                                           const SynthOptions& synth, const char* bench, bool quiet) {
  if (input == "synth" || input.rfind("synth:head", 0) == 0) {
    SynthOptions options = synth;
    if (input != "synth") options.head_motion_degrees = std::stod(input.substr(10));
    const fs::path out = scratch / (input == "synth" ? "synth" : "synth_head" + input.substr(10));
    if (!quiet) {
      std::fprintf(stderr,
                   "%s: writing %s (fmsynth --frames %d --vertices %d --expression mixed --remesh --noise %g --texture-size %d%s)\n", bench,
                   out.c_str(), options.frames, options.vertices, options.noise, options.texture_size,
                   input == "synth" ? "" : (" --head-motion " + input.substr(10)).c_str());
    }
    write_synthetic_capture(out, options);
    return out;
  }
  if (input == "ict") {
    const fs::path script = fs::path(data) / "ict-facekit/tools/make_capture.py";
    std::error_code ec;
    if (!fs::exists(script, ec) || std::system("python3 --version > /dev/null 2>&1") != 0) return std::nullopt;
    const fs::path out = scratch / "ict";
    if (!quiet) std::fprintf(stderr, "%s: making the ICT capture (make_capture.py --start-seconds 56 --seconds 4)\n", bench);
    const std::string command = "python3 '" + script.string() + "' '" + out.string() + "' --start-seconds 56 --seconds 4 > /dev/null 2>&1";
    if (std::system(command.c_str()) != 0) throw Error(ErrorCode::kIo, "make_capture.py failed");
    return out;
  }
  if (input == "medusa") {
    const fs::path path = fs::path(data) / "medusa-mediapipe-4d/capture";
    std::error_code ec;
    if (!fs::is_directory(path, ec)) return std::nullopt;
    return path;
  }
  return fs::path(input);
}

Sequence file_round_trip(const Sequence& sequence, const std::vector<int>& texture_qualities, std::vector<uint8_t>* bytes,
                         SequenceFileInfo* info, const FieldCoding& coding) {
  SequenceFileMetadata metadata;
  metadata.keyframe_texture_qualities = texture_qualities;
  metadata.field_coding = coding;
  std::vector<uint8_t> file = encode_sequence_file(sequence, metadata);
  Sequence back = decode_sequence_file(file, "fmbench: the file round trip", info);
  if (bytes) *bytes = std::move(file);
  return back;
}

void record_distance(const SurfaceDistance& d, FrameError& f) {
  f.rms = d.rms / d.diagonal;
  f.max = d.max / d.diagonal;
  f.p99 = d.p99 / d.diagonal;
  // The union of both directions lets one side's points decide the percentile: a 450-vertex torso
  // sheet the repair drops was more than 1% of the points where G had fewer than ~25,000 nodes, and
  // the union's p99 then measured the torso, not the codec (spec/method.md §7.6).
  f.p99_decoded = d.p99_test_to_reference / d.diagonal;
  f.p99_captured = d.p99_reference_to_test / d.diagonal;
}

Summary summarise(const Evaluation& e) {
  Summary s;
  int keys = 0, held = 0, textured = 0;
  double psnr_sum = 0;
  s.psnr_worst = 1e300;
  for (const FrameError& f : e.frames) {
    s.p99_worst = std::max(s.p99_worst, f.p99);
    s.p99_decoded_worst = std::max(s.p99_decoded_worst, f.p99_decoded);
    s.p99_captured_worst = std::max(s.p99_captured_worst, f.p99_captured);
    if (f.keyframe) {
      s.key_rms_mean += f.rms, s.key_rms_worst = std::max(s.key_rms_worst, f.rms), ++keys;
    } else {
      s.held_rms_mean += f.rms, s.held_rms_worst = std::max(s.held_rms_worst, f.rms), s.held_max_worst = std::max(s.held_max_worst, f.max),
                                ++held;
      if (f.psnr >= 0) psnr_sum += f.psnr, s.psnr_worst = std::min(s.psnr_worst, f.psnr), ++textured;
    }
  }
  s.key_rms_mean /= std::max(keys, 1);
  s.held_rms_mean /= std::max(held, 1);
  s.psnr_mean = textured ? psnr_sum / textured : -1;
  if (!textured) s.psnr_worst = -1;
  return s;
}

double disk_psnr(const Image& a, const Image& b) { return psnr_of_mse(std::max(disk_texture_mse(a, b), 1e-12)); }

Evaluation evaluate(const SequenceEncoder& encoder, const Sequence& sequence, const std::vector<int>& keyframes,
                    const std::vector<TriangleMesh>& captured, const std::vector<int>& frames_to_decode, bool textures,
                    const std::function<void(int, const DecodedFrame&)>& on_decoded) {
  Evaluation e;
  e.registration = registration_method_name(encoder.registration(0)->method);
  e.spline = spline_kind_name(sequence.spline);
  e.keyframes = static_cast<int>(keyframes.size());
  e.grid = sequence.grid_n;
  SequenceDecoder decoder(std::make_shared<const Sequence>(sequence));
  DecodeOptions options;
  options.ignore_sane_range = true;
  options.reconstruct.throw_on_failure = false;  // a frame that does not converge is measured and counted, not fatal
  double seconds = 0;
  int steps = 0;
  for (int i : frames_to_decode) {
    FrameError f;
    f.time = encoder.capture().frames[static_cast<size_t>(i)].time;
    f.keyframe = std::binary_search(keyframes.begin(), keyframes.end(), i);
    const auto start = std::chrono::steady_clock::now();
    const DecodedFrame decoded = decoder.decode(f.time, options);
    seconds += seconds_since(start);
    steps += decoded.iterations;
    f.converged = decoded.converged;
    const SurfaceDistance d = surface_distance(captured[static_cast<size_t>(i)], decoded.mesh);
    record_distance(d, f);
    if (textures && !f.keyframe && !decoded.texture.empty()) {
      const Image truth = encoder.frame_sampler().frame_texture(i, decoded.texture.width);
      f.psnr = disk_psnr(truth, decoded.texture);
    }
    if (on_decoded) on_decoded(i, decoded);
    e.frames.push_back(f);
  }
  e.decode_ms = 1e3 * seconds / std::max<size_t>(frames_to_decode.size(), 1);
  e.iterations = steps / std::max(static_cast<int>(frames_to_decode.size()), 1);
  return e;
}

json evaluation_json(const Evaluation& e) {
  const Summary s = summarise(e);
  json frames = json::array();
  for (const FrameError& f : e.frames)
    frames.push_back({{"time", f.time},
                      {"keyframe", f.keyframe},
                      {"rms_relative", f.rms},
                      {"max_relative", f.max},
                      {"p99_relative", f.p99},
                      {"p99_decoded_relative", f.p99_decoded},
                      {"p99_captured_relative", f.p99_captured},
                      {"texture_psnr_db", f.psnr},
                      {"converged", f.converged}});
  return {{"registration", e.registration},
          {"spline", e.spline},
          {"keyframes", e.keyframes},
          {"grid", e.grid},
          {"keyframe_rms_mean", s.key_rms_mean},
          {"keyframe_rms_worst", s.key_rms_worst},
          {"held_out_rms_mean", s.held_rms_mean},
          {"held_out_rms_worst", s.held_rms_worst},
          {"held_out_max_worst", s.held_max_worst},
          {"p99_worst", s.p99_worst},
          {"p99_decoded_worst", s.p99_decoded_worst},
          {"p99_captured_worst", s.p99_captured_worst},
          {"held_out_texture_psnr_mean", s.psnr_mean},
          {"held_out_texture_psnr_worst", s.psnr_worst},
          {"decode_ms_per_frame", e.decode_ms},
          {"mean_iterations", e.iterations},
          {"frames", frames}};
}

void write_error_plot(const fs::path& path, const Evaluation& e) {
  PlotSeries held, keys;
  held.color = {40, 90, 200};
  keys.color = {220, 80, 40};
  keys.line = false;
  keys.markers = true;
  std::vector<double> marks;
  for (const FrameError& f : e.frames) {
    (f.keyframe ? keys : held).x.push_back(f.time);
    (f.keyframe ? keys : held).y.push_back(100 * f.rms);
    if (f.keyframe) marks.push_back(f.time);
  }
  PlotOptions options;
  options.x_label = "time (s)";
  options.y_label = "rms error (% of diagonal)";
  options.vertical_marks = marks;
  fs::create_directories(path.parent_path());
  write_png(path, line_plot({held, keys}, options));
}

}  // namespace facemorph::tools
