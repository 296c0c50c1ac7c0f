// fmbench --capture: what users would ship instead (Draco per frame, JPEG textures, one H.264 texture
// video), and the settings of each that match facemorph's error.
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

DracoPoint draco_point(const Capture& capture, const std::vector<TriangleMesh>& captured, const std::vector<int>& frames, int qp,
                       const fs::path& scratch, TriangleMesh* decoded_of_first) {
  DracoPoint p;
  p.qp = qp;
  p.frames = static_cast<int>(frames.size());
  std::vector<uint64_t> bytes(frames.size());
  p.rms.resize(frames.size());
  p.max.resize(frames.size());
  p.p99.resize(frames.size());
  parallel_for(static_cast<int>(frames.size()), 0, [&](int k) {
    const int i = frames[static_cast<size_t>(k)];
    const fs::path drc = scratch / ("draco_" + std::to_string(i) + ".drc"), obj = scratch / ("draco_" + std::to_string(i) + ".obj");
    run_program("draco_encoder -i " + shell_quote(capture.mesh_path(static_cast<size_t>(i)).string()) + " -o " + shell_quote(drc.string()) +
                    " -qp " + std::to_string(qp) + " -cl 7",
                "draco_encoder");
    run_program("draco_decoder -i " + shell_quote(drc.string()) + " -o " + shell_quote(obj.string()), "draco_decoder");
    bytes[static_cast<size_t>(k)] = file_bytes(drc);
    TriangleMesh decoded = read_mesh(obj, {.allow_missing_texture = true});
    const SurfaceDistance d = surface_distance(captured[static_cast<size_t>(i)], decoded);
    p.rms[static_cast<size_t>(k)] = d.rms / d.diagonal;
    p.max[static_cast<size_t>(k)] = d.max / d.diagonal;
    p.p99[static_cast<size_t>(k)] = d.p99 / d.diagonal;
    if (k == 0 && decoded_of_first) *decoded_of_first = std::move(decoded);
    std::error_code ec;
    fs::remove(drc, ec);
    fs::remove(obj, ec);
  });
  for (uint64_t b : bytes) p.bytes += b;
  return p;
}

Image rgb_of(const Image& image) {
  if (image.channels == 3) return image;
  Image out(image.width, image.height, 3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) std::copy_n(image.at(x, y), 3, out.at(x, y));
  }
  return out;
}

// Writes one libx264 video per CRF of every captured texture (yuv420p, preset medium, the
// capture's frame rate); returns each file's bytes.
std::vector<uint64_t> encode_h264(const std::vector<fs::path>& textures, double fps, const std::vector<int>& crfs, const fs::path& scratch,
                                  int& width, int& height) {
  const Image first = read_image(textures.front());
  width = first.width, height = first.height;
  std::vector<std::unique_ptr<Pipe>> pipes;
  for (int crf : crfs) {
    auto pipe = std::make_unique<Pipe>();
    char rate[32];
    std::snprintf(rate, sizeof rate, "%.6g", fps);
    // Odd sizes padded to even (yuv420p); the decode crops back.
    pipe->command = "ffmpeg -v error -y -f rawvideo -pix_fmt rgb24 -s " + std::to_string(width) + "x" + std::to_string(height) + " -r " +
                    rate + " -i - -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -preset medium -crf " + std::to_string(crf) +
                    " -pix_fmt yuv420p " + shell_quote((scratch / ("texture_crf" + std::to_string(crf) + ".mp4")).string()) +
                    " > /dev/null 2>&1";
    pipe->file = popen(pipe->command.c_str(), "w");
    if (!pipe->file) throw Error(ErrorCode::kIo, "could not start ffmpeg: " + pipe->command);
    pipes.push_back(std::move(pipe));
  }
  for (const fs::path& path : textures) {
    const Image image = rgb_of(read_image(path));
    if (image.width != width || image.height != height) {
      throw Error(ErrorCode::kUnsupported, path.string() + ": textures of several sizes cannot be one H.264 video");
    }
    for (auto& pipe : pipes) {
      if (std::fwrite(image.pixels.data(), 1, image.pixels.size(), pipe->file) != image.pixels.size()) {
        throw Error(ErrorCode::kIo, "ffmpeg stopped reading: " + pipe->command);
      }
    }
  }
  std::vector<uint64_t> bytes;
  for (size_t k = 0; k < pipes.size(); ++k) {
    if (pipes[k]->close() != 0) throw Error(ErrorCode::kIo, "ffmpeg failed: " + pipes[k]->command);
    bytes.push_back(file_bytes(scratch / ("texture_crf" + std::to_string(crfs[k]) + ".mp4")));
  }
  return bytes;
}

// " (... not matched ...)" where a baseline missed facemorph's figure at its finest setting, or "an
// upper bound" where its coarsest setting met it already.
std::string match_note(bool met, size_t pick, const char* missed) {
  return !met        ? std::string(" (") + missed + " not matched at the finest tried)"
         : pick == 0 ? std::string(" (the coarsest tried: an upper bound)")
                     : std::string();
}

MatchedBaselines match_baselines(const Plan& plan, const CapturedFrames& c, int shown, const TextureBaselines& texture, double target_rms,
                                 double target_psnr, StageSeconds& stage_seconds) {
  MatchedBaselines m;
  // Draco on the sample frames at every qp, the coarsest meeting facemorph's held-out RMS then on
  // every frame (one finer while the whole capture misses it).
  const auto draco_start = std::chrono::steady_clock::now();
  for (int qp : plan.draco_qp) m.draco_curve.push_back(draco_point(c.capture, c.meshes, c.sample, qp, c.scratch));
  m.draco_pick = coarsest_meeting(
      m.draco_curve.size(), [&](size_t k) { return mean(m.draco_curve[k].rms) <= target_rms; }, m.draco_met);
  m.draco_first_pick = m.draco_pick;
  for (;;) {
    m.draco = draco_point(c.capture, c.meshes, c.every, plan.draco_qp[m.draco_pick], c.scratch);
    m.draco_met = mean(m.draco.rms) <= target_rms;
    if (m.draco_met || m.draco_pick + 1 == plan.draco_qp.size()) break;
    ++m.draco_pick;
  }
  draco_point(c.capture, c.meshes, {shown}, m.draco.qp, c.scratch, &m.draco_shown);
  stage_seconds["baseline draco"] = seconds_since(draco_start);

  // JPEG and H.264 at the quality that meets facemorph's held-out texture PSNR on the sample frames.
  if (c.textured) {
    const auto jpeg_psnr = [&](int quality) { return mean_at(texture.jpeg_psnr, quality); };
    const auto h264_psnr = [&](int crf) { return mean_at(texture.h264_psnr, crf); };
    const size_t q = coarsest_meeting(
        plan.jpeg_quality.size(), [&](size_t k) { return jpeg_psnr(plan.jpeg_quality[k]) >= target_psnr; }, m.jpeg_met);
    m.jpeg_quality = plan.jpeg_quality[q];
    m.jpeg_note = match_note(m.jpeg_met, q, "PSNR");
    for (const fs::path& path : c.textures) m.jpeg_bytes += encode_image(rgb_of(read_image(path)), ".jpg", m.jpeg_quality).size();
    // CRFs fine to coarse in the plan: the coarsest meeting is the last that does.
    const size_t n = plan.h264_crf.size();
    const size_t crf = coarsest_meeting(
        n, [&](size_t k) { return h264_psnr(plan.h264_crf[n - 1 - k]) >= target_psnr; }, m.h264_met);
    m.h264_crf = plan.h264_crf[n - 1 - crf];
    m.h264_note = match_note(m.h264_met, crf, "PSNR");
    m.h264_total = texture.h264_bytes[n - 1 - crf];
  }
  return m;
}

}  // namespace facemorph::tools::capture_bench
