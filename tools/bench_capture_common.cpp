// fmbench --capture: the plan of a run, small helpers, and the capture as it lies on disk.
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

Plan make_plan(bool quick) {
  Plan plan;
  plan.synth.remesh = true;  // fmsynth --remesh --expression mixed, its other defaults (60 frames, 20k vertices, noise)
  if (!quick) return plan;
  plan.synth.frames = 20;
  plan.synth.vertices = 5000;
  plan.synth.texture_size = 256;
  plan.frame_limit = 20;
  plan.texture_size = 256;
  plan.sample_frames = 5;
  plan.budgets = {0.10};
  plan.draco_qp = {6, 8, 10, 12};
  plan.jpeg_quality = {10, 30, 60, 90};
  plan.h264_crf = {20, 30, 40};
  return plan;
}

std::string shell_quote(const std::string& text) {
  std::string out = "'";
  for (char c : text) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Throws naming the program and the package that has it when it is not on PATH.
void require_program(const char* program, const char* package) {
  if (std::system(("command -v " + std::string(program) + " > /dev/null 2>&1").c_str()) != 0) {
    throw Error(ErrorCode::kIo, std::string(program) + " not found on PATH: the baselines need it (Debian package '" + package +
                                    "'; tools/install-deps.sh installs it)");
  }
}

void run_program(const std::string& command, const std::string& what) {
  if (std::system((command + " > /dev/null 2>&1").c_str()) != 0) throw Error(ErrorCode::kIo, what + " failed: " + command);
}

uint64_t file_bytes(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : static_cast<uint64_t>(size);
}

double mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return values.empty() ? 0 : sum / static_cast<double>(values.size());
}

double worst(const std::vector<double>& values) { return values.empty() ? 0 : *std::max_element(values.begin(), values.end()); }

// D1 PSNR with the bbox diagonal as peak (MPEG's convention for the peak), from the symmetric
// point-to-surface RMS relative to the diagonal, averaged over frames as MPEG averages it.
double d1_psnr(const std::vector<double>& relative_rms) {
  std::vector<double> db;
  for (double r : relative_rms) db.push_back(-20 * std::log10(std::max(r, 1e-12)));
  return mean(db);
}

double peak_rss_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024;  // kilobytes on Linux
}

uint64_t chunk_bytes(const SequenceFileInfo& info, const std::string& type) {
  for (const auto& c : info.chunks) {
    if (c.type == type) return c.stored_bytes;
  }
  return 0;
}

std::vector<double> relative_rms(const Evaluation& e, bool keyframes) {
  std::vector<double> v;
  for (const FrameError& f : e.frames) {
    if (f.keyframe == keyframes) v.push_back(f.rms);
  }
  return v;
}

std::string fixed(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, value);
  return text;
}

std::string kilobytes(double bytes) { return fixed(bytes / 1000, bytes < 10000 ? 2 : 1) + " kB"; }

std::string target_line(const char* what, double ratio, double target) {
  return std::string(what) + ": " + fixed(ratio, 2) + "x (target " + fixed(target, 0) +
         "x: " + (ratio >= target ? "met" : "missed by " + fixed(target / ratio, 1) + "x") + ")";
}

// The frame of `capture` nearest `time` (the earlier of two as near): where a file's keyframe lies.
int nearest_frame(const Capture& capture, double time) {
  int nearest = 0;
  for (int i = 1; i < static_cast<int>(capture.frames.size()); ++i) {
    if (std::abs(capture.frames[static_cast<size_t>(i)].time - time) < std::abs(capture.frames[static_cast<size_t>(nearest)].time - time))
      nearest = i;
  }
  return nearest;
}

// The mean of the values under `key`; 0 where none was measured.
double mean_at(const std::map<int, std::vector<double>>& values, int key) {
  const auto found = values.find(key);
  return found == values.end() ? 0 : mean(found->second);
}

CapturedFrames read_captured_frames(const Context& context, const fs::path& folder, const std::string& input) {
  const Plan& plan = context.plan;
  CapturedFrames c;
  c.capture = read_capture(folder);
  Capture& capture = c.capture;
  if (plan.frame_limit > 0 && capture.frames.size() > static_cast<size_t>(plan.frame_limit)) {
    capture.frames.resize(static_cast<size_t>(plan.frame_limit));
    capture.landmarks.resize(static_cast<size_t>(plan.frame_limit));
  }
  c.count = static_cast<int>(capture.frames.size());
  c.duration = capture.duration() + 1.0 / capture.fps;
  c.label = fs::path(input).filename().string().empty() ? "capture" : fs::path(input).filename().string();
  c.scratch = context.scratch / (c.label + "_work");
  fs::create_directories(c.scratch);
  for (int i = 0; i < c.count; ++i) {
    const fs::path path = capture.mesh_path(static_cast<size_t>(i));
    c.meshes.push_back(read_mesh(path, {.allow_missing_texture = true}));
    c.raw_mesh += file_bytes(path) + file_bytes(fs::path(path).replace_extension(".mtl"));
    c.vertex_frames += c.meshes.back().vertex_count();
    if (!c.meshes.back().texture.empty()) {
      c.textures.push_back(c.meshes.back().texture);
      c.raw_texture += file_bytes(c.meshes.back().texture);
    }
  }
  c.textured = static_cast<int>(c.textures.size()) == c.count;
  c.every.resize(static_cast<size_t>(c.count));
  for (int i = 0; i < c.count; ++i) c.every[static_cast<size_t>(i)] = i;
  const int stride = std::max(1, (c.count + plan.sample_frames - 1) / plan.sample_frames);
  for (int i = 0; i < c.count; i += stride) c.sample.push_back(i);
  std::printf("\n%s: %d frames at %.3g fps (%.2f s), %.0f vertices per frame, %s\n", c.label.c_str(), c.count, capture.fps, c.duration,
              static_cast<double>(c.vertex_frames) / c.count, c.textured ? "textured" : "no texture");
  return c;
}

}  // namespace facemorph::tools::capture_bench
