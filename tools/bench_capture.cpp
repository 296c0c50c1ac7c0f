// fmbench --capture: facemorph's rate on whole captures, side by side in one run with what users
// would ship instead. For each capture: the .fmv file's bytes (per chunk type, per second, bits per
// captured vertex per frame); every captured frame decoded at its own time and measured against it
// (symmetric point-to-surface RMS and max relative to the bbox diagonal, D1 PSNR with the diagonal as
// peak, texture PSNR on the disk through the frame's own map); encode time by stage, decode time,
// peak memory; and the baselines: the raw capture, Draco per frame at the coarsest quantisation
// whose error is at most facemorph's held-out error, + JPEG textures or + one H.264 texture video at
// the quality that matches facemorph's texture PSNR, and facemorph's own xyz representation.
#include "tools/bench_capture.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tools/bench_capture_parts.hpp"
#include "tools/tool_support.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>

namespace facemorph::tools::capture_bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// ---- one capture -------------------------------------------------------------------------------

json measure_capture(Context& context, const std::string& input) {
  const CaptureBenchOptions& options = context.options;
  const auto folder = make_bench_capture(input, options.data, context.scratch, context.plan.synth, "fmbench --capture", options.quiet);
  if (!folder) {
    std::printf("\n%s: skipped (the shared data or python3 is absent)\n", input.c_str());
    context.markdown += "## " + input + "\n\nSkipped: the shared data (or python3) is absent.\n\n";
    return {{"input", input}, {"skipped", true}};
  }
  std::error_code ec;
  if (!fs::exists(*folder, ec)) throw Error(ErrorCode::kIo, "capture '" + folder->string() + "' does not exist");
  const CapturedFrames captured = read_captured_frames(context, *folder, input);
  StageSeconds stage_seconds;
  TextureBaselines texture;
  const FacemorphPoints fm = measure_facemorph(context, captured, stage_seconds, texture);
  const Summary summary = summarise(fm.main.evaluation);
  // Where every frame is a keyframe (a single scan), no frame is held out: the baselines are matched
  // to the keyframes' error, not to the held-out mean of none (0, which no Draco setting reaches).
  const bool held_out =
      std::any_of(fm.main.evaluation.frames.begin(), fm.main.evaluation.frames.end(), [](const FrameError& f) { return !f.keyframe; });
  const double target_rms = held_out ? summary.held_rms_mean : summary.key_rms_mean;
  const double target_psnr = held_out ? fm.main.held_psnr() : fm.main.key_psnr();
  const MatchedBaselines baselines = match_baselines(context.plan, captured, fm.shown, texture, target_rms, target_psnr, stage_seconds);
  CaptureFigures figures{captured, fm, texture, baselines, stage_seconds, summary, target_rms, target_psnr, {}, {}};
  // The main encode, mapping to file; a stage that did not run is listed with 0 s.
  for (const char* stage : {"mapping", "registration", "sampling", "selection", "grid", "representation", "keyframes", "field precision",
                            "residual frames", "texture quality", "file"}) {
    figures.encode_seconds += stage_seconds[stage];
  }
  add_rows_and_targets(figures);
  print_figures(figures);
  const std::string pictures = options.report.empty() ? std::string() : write_report_pictures(options.report, context.plan, figures);
  context.markdown += markdown_report(input, *folder, context.plan, figures) + pictures;
  return capture_json(input, *folder, context.plan, figures);
}

}  // namespace

}  // namespace facemorph::tools::capture_bench

namespace facemorph::tools {

void add_capture_options(CLI::App& app, CaptureBenchOptions& options) {
  app.add_option("--capture", options.captures,
                 "The rate bench: capture folders, or synth (fmsynth --remesh --expression mixed), medusa, ict (from --data), all (those "
                 "three); repeatable. Compares facemorph with the raw capture, Draco, Draco + JPEG, Draco + H.264 and its xyz variant");
  app.add_option("--fmv", options.fmv, "With --capture: measure this file (made from that capture) instead of the bench's own encode");
  app.add_option("--json", options.json_out, "With --capture: also write the results as JSON ('-': standard output)");
  app.add_option("--report", options.report, "With --capture: write a Markdown report here, its curves and pictures beside it");
  app.add_option("--data", options.data, "With --capture: folder of the shared real data")->capture_default_str();
  app.add_option("--against", options.against,
                 "With --geometry-only: also how far the file decodes from this one, made from the same capture (a joined file against the "
                 "one-process encode), RMS over G's nodes at every frame");
  app.add_flag("--quick", options.quick, "With --capture: the smoke test (20 frames, small texture, few candidates; about a minute)");
  app.add_flag("--geometry-only", options.geometry_only,
               "With --capture and --fmv: only the file's geometry error on every frame (no mapping, no baselines; seconds, not minutes)");
  app.add_flag("--quiet", options.quiet, "With --capture: no progress display");
  app.add_flag("--residual-frames,!--no-residual-frames", options.residual_frames,
               "With --capture: encode with residual frames where they pay (on by default, as fmenc; format 2.3)");
}

int run_capture_bench(const CaptureBenchOptions& options) {
  std::vector<std::string> captures;
  for (const std::string& c : options.captures) {
    if (c == "all") {
      captures.insert(captures.end(), {"synth", "medusa", "ict"});
    } else {
      captures.push_back(c);
    }
  }
  if (!options.fmv.empty() && captures.size() != 1)
    throw Error(ErrorCode::kInvalidArgument, "--fmv needs exactly one --capture, the one it was made from");
  for (const std::string& c : captures) {
    std::error_code ec;
    if (c != "synth" && c != "medusa" && c != "ict" && !fs::exists(c, ec))
      throw Error(ErrorCode::kIo, "capture '" + c + "' does not exist");
  }
  if (!options.against.empty() && !options.geometry_only) throw Error(ErrorCode::kInvalidArgument, "--against is for --geometry-only");
  if (options.geometry_only) {
    if (options.fmv.empty()) throw Error(ErrorCode::kInvalidArgument, "--geometry-only measures a given file: it needs --fmv");
    const json result = capture_bench::measure_geometry_only(options, captures.front());
    if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "capture-geometry"}, {"results", json::array({result})}});
    return 0;
  }
  capture_bench::require_program("draco_encoder", "draco");
  capture_bench::require_program("draco_decoder", "draco");
  capture_bench::require_program("ffmpeg", "ffmpeg");
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each capture's lines as they come, also into a log file
  std::signal(SIGPIPE, SIG_IGN);             // an ffmpeg that dies is reported by its pipe, not by killing the bench
  const capture_bench::Plan plan = capture_bench::make_plan(options.quick);
  const ScratchFolder scratch("fmbench-capture");
  capture_bench::Context context{options, plan, scratch.path, {}};
  context.markdown = "# facemorph rate against Draco, JPEG and H.264\n\nMade by `fmbench --capture" +
                     std::string(options.quick ? " --quick" : "") +
                     "`. Geometry error: symmetric point-to-surface distance between each captured frame and its decode at the "
                     "frame's own time, relative to the frame's bounding-box diagonal; D1 PSNR takes the diagonal as peak. Texture PSNR: "
                     "RGB on the registered disk, each frame's texture carried there through its own conformal map. Ratios are baseline "
                     "bytes over facemorph's (above 1: facemorph is smaller).\n\n";
  json results = json::array();
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& c : captures) results.push_back(capture_bench::measure_capture(context, c));
  std::printf("\nfmbench --capture: %.1f s\n", seconds_since(start));
  if (!options.report.empty()) {
    std::ofstream out(options.report);
    out << context.markdown;
    if (!out) throw Error(ErrorCode::kIo, "could not write the report '" + options.report + "'");
  }
  if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "capture"}, {"quick", options.quick}, {"results", results}});
  return 0;
}

}  // namespace facemorph::tools
