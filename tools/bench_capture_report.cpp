// fmbench --capture: one capture's figures as the table, the Markdown report with its curves and
// pictures, and the JSON.
#include "tools/bench_capture_parts.hpp"

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/util/parallel.hpp"
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

namespace {

Image side_by_side(const std::vector<Image>& pictures) {
  int width = 0, height = 0;
  for (const Image& p : pictures) width += p.width, height = std::max(height, p.height);
  Image out(width, height, 3);
  std::fill(out.pixels.begin(), out.pixels.end(), uint8_t{255});
  int x0 = 0;
  for (const Image& p : pictures) {
    for (int y = 0; y < p.height; ++y) {
      for (int x = 0; x < p.width; ++x) std::copy_n(p.at(x, y), 3, out.at(x0 + x, y));
    }
    x0 += p.width;
  }
  return out;
}

Image picture(const TriangleMesh& mesh, const Image& texture) {
  RenderOptions options;
  options.width = options.height = 360;
  return render(mesh, texture.empty() || !mesh.has_uvs() ? constant_shader({200, 200, 200}) : texture_shader(mesh, texture), options);
}

}  // namespace

void add_rows_and_targets(CaptureFigures& f) {
  const MatchedBaselines& b = f.baselines;
  const FacemorphPoints& fm = f.fm;
  f.rows = {
      {"facemorph", "keyframes " + std::to_string(fm.main_keys.size()) + ", N = " + std::to_string(fm.grid),
       double(fm.main.geometry_bytes()), double(fm.main.texture_bytes), f.target_rms, f.summary.held_rms_worst, f.target_psnr,
       f.summary.p99_worst},
      {"raw capture", "OBJ + MTL + images as captured", double(f.c.raw_mesh), double(f.c.raw_texture), -1, -1, -1},
      {"draco",
       "-qp " + std::to_string(b.draco.qp) + " -cl 7" +
           match_note(b.draco_met, b.draco_pick == b.draco_first_pick ? b.draco_pick : 1, "error"),
       double(b.draco.bytes), 0, mean(b.draco.rms), worst(b.draco.rms), -1, worst(b.draco.p99)},
  };
  if (f.c.textured) {
    f.rows.push_back({"draco + jpeg", "-qp " + std::to_string(b.draco.qp) + ", JPEG q" + std::to_string(b.jpeg_quality) + b.jpeg_note,
                      double(b.draco.bytes), double(b.jpeg_bytes), mean(b.draco.rms), worst(b.draco.rms),
                      mean_at(f.texture.jpeg_psnr, b.jpeg_quality), worst(b.draco.p99)});
    f.rows.push_back({"draco + h264", "-qp " + std::to_string(b.draco.qp) + ", x264 crf " + std::to_string(b.h264_crf) + b.h264_note,
                      double(b.draco.bytes), double(b.h264_total), mean(b.draco.rms), worst(b.draco.rms),
                      mean_at(f.texture.h264_psnr, b.h264_crf), worst(b.draco.p99)});
  }
  const Summary xyz = summarise(fm.xyz.evaluation);
  f.rows.push_back({"facemorph xyz", "same keyframes and spline", double(fm.xyz.geometry_bytes()), double(fm.xyz.texture_bytes),
                    xyz.held_rms_mean, xyz.held_rms_worst, -1, xyz.p99_worst});

  f.draco_ratio = double(b.draco.bytes) / f.fm_geometry();
  f.jpeg_ratio = f.c.textured ? (double(b.draco.bytes) + double(b.jpeg_bytes)) / f.fm_total() : 0;
  f.h264_ratio = f.c.textured ? (double(b.draco.bytes) + double(b.h264_total)) / f.fm_total() : 0;
  f.bits = 8 * f.fm_total() / double(f.c.vertex_frames);
  f.targets = {target_line("geometry vs Draco", f.draco_ratio, 20)};
  if (f.c.textured) {
    f.targets.push_back(target_line("total vs Draco + JPEG", f.jpeg_ratio, 20));
    f.targets.push_back(target_line("total vs Draco + H.264", f.h264_ratio, 3));
  }
  f.targets.push_back("bits per captured vertex per frame incl. texture: " + fixed(f.bits, 3) + " (target <= 1 at held-out RMS <= 0.5%: " +
                      (f.bits <= 1 && f.target_rms <= 0.005 ? std::string("met")
                                                            : "missed" + (f.bits > 1 ? " by " + fixed(f.bits, 1) + "x" : std::string())) +
                      ")");
  f.targets.push_back("99th-percentile point error, worst decoded frame: " + fixed(100 * f.summary.p99_worst, 3) +
                      "% of the diagonal (target <= 1%: " +
                      (f.summary.p99_worst <= 0.01 ? std::string("met") : "missed by " + fixed(f.summary.p99_worst / 0.01, 2) + "x") +
                      "); decoded to captured " + fixed(100 * f.summary.p99_decoded_worst, 3) + "%, captured to decoded " +
                      fixed(100 * f.summary.p99_captured_worst, 3) + "%");
}

void print_figures(const CaptureFigures& f) {
  const FacemorphPoints& fm = f.fm;
  const Summary& summary = f.summary;
  std::printf(
      "  facemorph: %llu bytes (%.0f B/s, %.3f bits per captured vertex per frame, %.3f without texture), keyframes %zu, residual frames "
      "%zu, N = %d\n",
      static_cast<unsigned long long>(fm.main.bytes), f.fm_total() / f.c.duration, f.bits, 8 * f.fm_geometry() / double(f.c.vertex_frames),
      fm.main_keys.size(), fm.residual_frames, fm.grid);
  std::printf("  chunks:");
  for (const auto& c : fm.main.info.chunks) std::printf(" %s %llu", c.type.c_str(), static_cast<unsigned long long>(c.stored_bytes));
  std::printf(
      "\n  held-out RMS %.4f%% mean, %.4f%% worst, max %.4f%%; keyframes RMS %.4f%%; 99th percentile %.4f%% worst frame; D1 PSNR held-out "
      "%.2f dB; texture PSNR held-out %.2f dB, keyframes %.2f dB\n",
      100 * f.target_rms, 100 * summary.held_rms_worst, 100 * summary.held_max_worst, 100 * summary.key_rms_mean, 100 * summary.p99_worst,
      d1_psnr(relative_rms(fm.main.evaluation, false)), f.target_psnr, fm.main.key_psnr());
  if (!fm.main.pixel_psnr.empty()) {
    // Per captured pixel: the same on whichever disk the file was sampled (spec/method.md §7.11).
    std::printf("  texture per captured pixel: PSNR held-out %.2f dB; %.1f%% of the pixels on under a texel each, median %.2f texels a pixel\n",
                fm.main.held_pixel_psnr(), 100 * fm.main.density.undersampled, fm.main.density.median_texels_per_pixel);
  }
  std::printf("  %-16s %12s %12s %12s %10s %10s %10s %9s %9s %9s  %s\n", "", "geometry B", "texture B", "total B", "rms mn%", "rms wst%",
              "p99 wst%", "tex dB", "geo x", "total x", "setting");
  for (const FigureRow& r : f.rows) {
    const double total = r.geometry + r.texture;
    std::printf("  %-16s %12.0f %12.0f %12.0f %10s %10s %10s %9s %9.2f %9.2f  %s\n", r.name.c_str(), r.geometry, r.texture, total,
                r.rms >= 0 ? fixed(100 * r.rms, 4).c_str() : "-", r.rms_worst >= 0 ? fixed(100 * r.rms_worst, 4).c_str() : "-",
                r.p99 >= 0 ? fixed(100 * r.p99, 4).c_str() : "-", r.psnr >= 0 ? fixed(r.psnr, 2).c_str() : "-",
                r.geometry / f.fm_geometry(), total / f.fm_total(), r.setting.c_str());
  }
  for (const std::string& t : f.targets) std::printf("  %s\n", t.c_str());
  std::printf("  speed: encode %.2f s per frame (", f.encode_seconds / f.c.count);
  const char* separator = "";
  for (const auto& [stage, seconds] : f.stage_seconds) std::printf("%s%s %.2f s", std::exchange(separator, "; "), stage.c_str(), seconds);
  std::printf("), decode %.1f ms per frame, peak memory %.0f MiB\n", fm.main.evaluation.decode_ms, peak_rss_mib());
}

// ---- report: curves, pictures, Markdown --------------------------------------------------------

// The curves and pictures beside the report; returns the Markdown that shows them.
std::string write_report_pictures(const fs::path& report, const Plan& plan, const CaptureFigures& f) {
  const CapturedFrames& c = f.c;
  const FacemorphPoints& fm = f.fm;
  const double frames = c.count;
  const fs::path dir = fs::absolute(report).parent_path();
  fs::create_directories(dir);
  auto series = [](const char* name, std::array<uint8_t, 3> color) {
    PlotSeries s;
    s.label = name;
    s.color = color;
    s.markers = true;
    return s;
  };
  std::string md;
  PlotSeries fmc = series("facemorph", {200, 40, 40}), fx = series("facemorph xyz", {230, 140, 30}), dr = series("draco", {40, 90, 200});
  for (const Encoded& e : fm.curve)
    fmc.x.push_back(std::log10(e.geometry_bytes() / frames)), fmc.y.push_back(100 * summarise(e.evaluation).held_rms_mean);
  for (const Encoded& e : fm.xyz_curve)
    fx.x.push_back(std::log10(e.geometry_bytes() / frames)), fx.y.push_back(100 * summarise(e.evaluation).held_rms_mean);
  for (const DracoPoint& p : f.baselines.draco_curve)
    dr.x.push_back(std::log10(p.bytes / double(p.frames))), dr.y.push_back(100 * mean(p.rms));
  PlotOptions geometry_plot;
  geometry_plot.x_label = "log10 geometry bytes per frame";
  geometry_plot.y_label = "held-out rms (% of diagonal)";
  write_image(dir / (c.label + "_rd_geometry.png"), line_plot({fmc, fx, dr}, geometry_plot));
  md += "![geometry rate-distortion](" + c.label + "_rd_geometry.png)\n\n";
  if (c.textured) {
    PlotSeries ft = series("facemorph (keyframe budget)", {200, 40, 40}), jp = series("jpeg (quality)", {40, 150, 60}),
               hv = series("h264 (crf)", {120, 60, 180});
    for (const Encoded& e : fm.curve) ft.x.push_back(std::log10(e.texture_bytes / frames)), ft.y.push_back(e.held_psnr());
    for (int q : plan.jpeg_quality) {
      const auto bytes = f.texture.jpeg_sample_bytes.find(q);
      jp.x.push_back(std::log10((bytes == f.texture.jpeg_sample_bytes.end() ? 0 : bytes->second) / double(c.sample.size())));
      jp.y.push_back(mean_at(f.texture.jpeg_psnr, q));
    }
    for (size_t k = 0; k < plan.h264_crf.size(); ++k) {
      hv.x.push_back(std::log10(f.texture.h264_bytes[k] / frames)), hv.y.push_back(mean_at(f.texture.h264_psnr, plan.h264_crf[k]));
    }
    PlotOptions texture_plot;
    texture_plot.x_label = "log10 texture bytes per frame";
    texture_plot.y_label = "texture psnr on the disk (db)";
    texture_plot.y_from_zero = false;
    write_image(dir / (c.label + "_rd_texture.png"), line_plot({ft, jp, hv}, texture_plot));
    md += "![texture rate-distortion](" + c.label + "_rd_texture.png)\n\n";
  }
  write_error_plot(dir / (c.label + "_error.png"), fm.main.evaluation);
  const TriangleMesh& truth = c.meshes[static_cast<size_t>(fm.shown)];
  const Image truth_texture = c.textured ? rgb_of(read_image(c.textures[static_cast<size_t>(fm.shown)])) : Image();
  write_image(dir / (c.label + "_frames.png"),
              side_by_side({picture(truth, truth_texture), picture(fm.shown_decoded.mesh, fm.shown_decoded.texture),
                            picture(f.baselines.draco_shown, truth_texture)}));
  md += "Frame " + std::to_string(fm.shown) + " (t = " + fixed(c.capture.frames[static_cast<size_t>(fm.shown)].time, 3) +
        " s, held out): captured, facemorph, Draco -qp " + std::to_string(f.baselines.draco.qp) + "\n\n![frames](" + c.label +
        "_frames.png)\n\n";
  md += "Error against time (keyframes marked):\n\n![error](" + c.label + "_error.png)\n\n";
  return md;
}

std::string markdown_report(const std::string& input, const fs::path& folder, const Plan& plan, const CaptureFigures& f) {
  const CapturedFrames& c = f.c;
  const FacemorphPoints& fm = f.fm;
  const Summary& summary = f.summary;
  const double frames = c.count;
  std::ostringstream report;
  const bool synthetic = input == "synth" || input.rfind("synth:", 0) == 0;
  const std::string source = synthetic ? "made by fmsynth --frames " + std::to_string(plan.synth.frames) + " --vertices " +
                                             std::to_string(plan.synth.vertices) + " --remesh --expression mixed (noise " +
                                             fixed(plan.synth.noise, 4) + " m, texture " + std::to_string(plan.synth.texture_size) + ")"
                                       : folder.string();
  report << "## " << c.label << "\n\n"
         << source << ": " << c.count << " frames at " << fixed(c.capture.fps, 3) << " fps (" << fixed(c.duration, 2) << " s), "
         << fixed(double(c.vertex_frames) / frames, 0) << " vertices per frame" << (c.textured ? ", textured" : ", no texture") << ".\n\n";
  report << "### Rate\n\n| | |\n| --- | --- |\n| file | " << fm.main.bytes << " bytes (" << fm.main_keys.size() << " keyframes of "
         << c.count << ", N = " << fm.grid << ") |\n| per second | " << fixed(f.fm_total() / c.duration, 0) << " B/s ("
         << fixed(8 * f.fm_total() / c.duration / 1000, 1) << " kbit/s) |\n"
         << "| bits per captured vertex per frame | " << fixed(f.bits, 3) << " with texture, "
         << fixed(8 * f.fm_geometry() / double(c.vertex_frames), 3) << " without |\n";
  for (const auto& chunk : fm.main.info.chunks)
    report << "| chunk " << chunk.type << " | " << chunk.count << " x, " << chunk.stored_bytes << " bytes |\n";
  report << "\n### Distortion (every frame decoded at its own time)\n\n| frames | RMS mean | RMS worst | p99 worst | max worst | D1 PSNR | "
            "texture PSNR |\n"
         << "| --- | --- | --- | --- | --- | --- | --- |\n";
  std::vector<double> key_max, held_max, key_p99, held_p99;
  for (const FrameError& e : fm.main.evaluation.frames) {
    (e.keyframe ? key_max : held_max).push_back(e.max);
    (e.keyframe ? key_p99 : held_p99).push_back(e.p99);
  }
  report << "| keyframes | " << fixed(100 * summary.key_rms_mean, 4) << "% | " << fixed(100 * summary.key_rms_worst, 4) << "% | "
         << fixed(100 * worst(key_p99), 4) << "% | " << fixed(100 * worst(key_max), 4) << "% | "
         << fixed(d1_psnr(relative_rms(fm.main.evaluation, true)), 2) << " dB | " << fixed(fm.main.key_psnr(), 2) << " dB |\n";
  report << "| held out | " << fixed(100 * summary.held_rms_mean, 4) << "% | " << fixed(100 * summary.held_rms_worst, 4) << "% | "
         << fixed(100 * worst(held_p99), 4) << "% | " << fixed(100 * summary.held_max_worst, 4) << "% | "
         << fixed(d1_psnr(relative_rms(fm.main.evaluation, false)), 2) << " dB | " << fixed(f.target_psnr, 2) << " dB |\n\n";
  report << "### Baselines (geometry matched to facemorph's held-out mean RMS, texture to its held-out PSNR)\n\n"
         << "| | setting | geometry | texture | total | RMS mean | RMS worst | p99 worst | texture PSNR | geometry / facemorph | total / "
            "facemorph |\n"
         << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const FigureRow& r : f.rows) {
    report << "| " << r.name << " | " << r.setting << " | " << kilobytes(r.geometry) << " | " << kilobytes(r.texture) << " | "
           << kilobytes(r.geometry + r.texture) << " | " << (r.rms >= 0 ? fixed(100 * r.rms, 4) + "%" : "") << " | "
           << (r.rms_worst >= 0 ? fixed(100 * r.rms_worst, 4) + "%" : "") << " | " << (r.p99 >= 0 ? fixed(100 * r.p99, 4) + "%" : "")
           << " | " << (r.psnr >= 0 ? fixed(r.psnr, 2) + " dB" : "") << " | " << fixed(r.geometry / f.fm_geometry(), 2) << "x | "
           << fixed((r.geometry + r.texture) / f.fm_total(), 2) << "x |\n";
  }
  report << "\nTargets (`../shared/design.md` §7):\n\n";
  for (const std::string& t : f.targets) report << "- " << t << "\n";
  report << "\n### Speed\n\n| stage | seconds | per frame |\n| --- | --- | --- |\n";
  for (const auto& [stage, seconds] : f.stage_seconds)
    report << "| " << stage << " | " << fixed(seconds, 2) << " | " << fixed(seconds / frames, 3) << " |\n";
  report << "\nEncode " << fixed(f.encode_seconds / frames, 2) << " s per frame (mapping to file); decode "
         << fixed(fm.main.evaluation.decode_ms, 1) << " ms per frame; peak memory of the bench " << fixed(peak_rss_mib(), 0) << " MiB.\n\n";
  return report.str();
}

json capture_json(const std::string& input, const fs::path& folder, const Plan& plan, const CaptureFigures& f) {
  const CapturedFrames& c = f.c;
  const FacemorphPoints& fm = f.fm;
  const TextureBaselines& texture = f.texture;
  json baselines = json::array();
  for (const FigureRow& r : f.rows) {
    const double total = r.geometry + r.texture;
    baselines.push_back({{"name", r.name},
                         {"setting", r.setting},
                         {"geometry_bytes", r.geometry},
                         {"texture_bytes", r.texture},
                         {"total_bytes", total},
                         {"rms_mean_relative", r.rms},
                         {"rms_worst_relative", r.rms_worst},
                         {"p99_worst_relative", r.p99},
                         {"texture_psnr_db", r.psnr},
                         {"geometry_ratio", r.geometry / f.fm_geometry()},
                         {"total_ratio", total / f.fm_total()}});
  }
  json budgets = json::array();
  for (size_t k = 0; k < fm.curve.size(); ++k) {
    budgets.push_back({{"budget", fm.curve[k].budget},
                       {"keyframes", fm.curve[k].keyframes.size()},
                       {"bytes", fm.curve[k].bytes},
                       {"geometry_bytes", fm.curve[k].geometry_bytes()},
                       {"held_out_rms_mean", summarise(fm.curve[k].evaluation).held_rms_mean},
                       {"held_out_texture_psnr_sample", fm.curve[k].held_psnr()},
                       {"xyz_geometry_bytes", fm.xyz_curve[k].geometry_bytes()},
                       {"xyz_held_out_rms_mean", summarise(fm.xyz_curve[k].evaluation).held_rms_mean}});
  }
  json draco_json = json::array();
  for (const DracoPoint& p : f.baselines.draco_curve) {
    draco_json.push_back(
        {{"qp", p.qp}, {"bytes_per_frame", p.bytes / double(p.frames)}, {"rms_mean", mean(p.rms)}, {"p99_worst", worst(p.p99)}});
  }
  json jpeg_json = json::array(), h264_json = json::array();
  for (int q : plan.jpeg_quality) {
    const auto bytes = texture.jpeg_sample_bytes.find(q);
    jpeg_json.push_back({{"quality", q},
                         {"bytes_per_frame", (bytes == texture.jpeg_sample_bytes.end() ? 0 : bytes->second) / double(c.sample.size())},
                         {"psnr", mean_at(texture.jpeg_psnr, q)}});
  }
  for (size_t k = 0; k < texture.h264_bytes.size(); ++k) {
    h264_json.push_back(
        {{"crf", plan.h264_crf[k]}, {"bytes", texture.h264_bytes[k]}, {"psnr", mean_at(texture.h264_psnr, plan.h264_crf[k])}});
  }
  json chunks = json::array();
  for (const auto& chunk : fm.main.info.chunks)
    chunks.push_back({{"type", chunk.type}, {"count", chunk.count}, {"bytes", chunk.stored_bytes}});
  return {{"input", input},
          {"capture", folder.string()},
          {"frames", c.count},
          {"fps", c.capture.fps},
          {"vertex_frames", c.vertex_frames},
          {"facemorph",
           {{"bytes", fm.main.bytes},
            {"bytes_per_second", f.fm_total() / c.duration},
            {"bits_per_vertex_frame", f.bits},
            {"bits_per_vertex_frame_geometry", 8 * f.fm_geometry() / double(c.vertex_frames)},
            {"chunks", chunks},
            {"keyframes", fm.main_keys},
            {"grid", fm.grid},
            {"evaluation", evaluation_json(fm.main.evaluation)},
            {"held_out_texture_psnr", f.target_psnr},
            {"keyframe_texture_psnr", fm.main.key_psnr()},
            {"held_out_texture_psnr_per_captured_pixel", fm.main.held_pixel_psnr()},
            {"captured_pixels_under_a_texel", fm.main.density.undersampled},
            {"captured_pixels_shown", fm.main.density.shown_pixels},
            {"captured_pixels_of_the_face", fm.main.density.face_pixels},
            {"held_out_d1_psnr", d1_psnr(relative_rms(fm.main.evaluation, false))},
            {"keyframe_d1_psnr", d1_psnr(relative_rms(fm.main.evaluation, true))}}},
          {"baselines", baselines},
          {"ratios", {{"geometry_vs_draco", f.draco_ratio}, {"total_vs_draco_jpeg", f.jpeg_ratio}, {"total_vs_draco_h264", f.h264_ratio}}},
          {"curves", {{"keyframe_budgets", budgets}, {"draco_sample", draco_json}, {"jpeg_sample", jpeg_json}, {"h264", h264_json}}},
          {"speed",
           {{"stage_seconds", json(std::map<std::string, double>(f.stage_seconds.begin(), f.stage_seconds.end()))},
            {"encode_seconds_per_frame", f.encode_seconds / c.count},
            {"decode_ms_per_frame", fm.main.evaluation.decode_ms},
            {"peak_memory_mib", peak_rss_mib()}}}};
}

}  // namespace facemorph::tools::capture_bench
