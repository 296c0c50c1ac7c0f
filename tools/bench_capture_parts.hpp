// fmbench --capture's parts (bench_capture.cpp runs them): what they share, each file one job.
//   bench_capture_common.cpp      the plan, small helpers, the capture as it lies on disk
//   bench_capture_texels.cpp      texture PSNR on the disk through each frame's own map
//   bench_capture_baselines.cpp   Draco, JPEG and H.264, and the settings that match facemorph's error
//   bench_capture_facemorph.cpp   facemorph's own encodes, as fmenc writes them, measured
//   bench_capture_geometry.cpp    --geometry-only: a given file's geometry error
//   bench_capture_report.cpp      the figures: table, Markdown report, pictures, JSON
#pragma once

#include "tools/bench_capture.hpp"
#include "tools/bench_sequence.hpp"

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace facemorph::tools::capture_bench {

namespace fs = std::filesystem;
using nlohmann::json;

// What one run tries: the full bench, or the smoke test CI runs in about a minute.
struct Plan {
  SynthOptions synth;
  int frame_limit = 0;     // 0: every frame
  int texture_size = 0;    // fmenc's default: auto (as sharp as the capture's texture, at most 1024)
  int sample_frames = 15;  // frames the baselines' sweeps are measured on (the matched points on all)
  std::vector<double> budgets = {0.05, 0.10, 0.20, 0.30};
  std::vector<int> draco_qp = {3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14};  // coarse to fine
  std::vector<int> jpeg_quality = {2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 95};
  std::vector<int> h264_crf = {14, 18, 22, 26, 30, 34, 38, 42, 46, 51};  // fine to coarse
};

Plan make_plan(bool quick);

// ---- small helpers (bench_capture_common.cpp) ---------------------------------------------------

std::string shell_quote(const std::string& text);
// Throws naming the program and the package that has it when it is not on PATH.
void require_program(const char* program, const char* package);
void run_program(const std::string& command, const std::string& what);
uint64_t file_bytes(const fs::path& path);
double mean(const std::vector<double>& values);
double worst(const std::vector<double>& values);
// D1 PSNR with the bbox diagonal as peak (MPEG's convention for the peak), from the symmetric
// point-to-surface RMS relative to the diagonal, averaged over frames as MPEG averages it.
double d1_psnr(const std::vector<double>& relative_rms);
double peak_rss_mib();
uint64_t chunk_bytes(const SequenceFileInfo& info, const std::string& type);
std::vector<double> relative_rms(const Evaluation& e, bool keyframes);
std::string fixed(double value, int digits);
std::string kilobytes(double bytes);
std::string target_line(const char* what, double ratio, double target);
// The frame of `capture` nearest `time` (the earlier of two as near): where a file's keyframe lies.
int nearest_frame(const Capture& capture, double time);
// The mean of the values under `key`; 0 where none was measured.
double mean_at(const std::map<int, std::vector<double>>& values, int key);

// ---- texture PSNR on the disk through each frame's own map --------------------------------------

// The texels of a size x size disk texture inside the disk, where each lies in the captured
// texture (through the frame's registration and map), and the captured texture's colour there.
// Computed once per frame; then any image of the captured texture's layout (a JPEG or H.264
// decode of it) or any disk texture (facemorph's decode) is compared against it.
struct DiskTexels {
  int size = 0;
  std::vector<int> texel;      // y * size + x
  std::vector<Vec2> uv;        // in the captured texture
  std::vector<uint8_t> truth;  // RGB of the captured texture there
  // Captured pixels each texel shows (the captured texture's area over the texel): weighting the
  // error by it gives a PSNR over the captured image, the same whatever disk the file was sampled
  // on (the conformal disk and the density-equalised one spread the face's texels differently).
  std::vector<double> pixels;
};

DiskTexels disk_texels(const SequenceEncoder& encoder, int frame, const Image& captured, int size);
// A disk texture (facemorph's decode) against the captured texture.
double psnr_of_disk(const DiskTexels& t, const Image& disk);
// The same, each texel's error weighted by the captured pixels it shows (DiskTexels::pixels).
double pixel_psnr_of_disk(const DiskTexels& t, const Image& disk);
// Of the captured pixels the disk shows, the share shown by fewer than one texel each (detail the
// disk texture cannot hold), and the median texels per captured pixel; the captured pixels the
// texels show in all, and those the face's UV triangles cover (`surface`, the frame's mapped
// surface, in an image of width x height): the disk shows the face once, so the two agree.
struct TexelDensity {
  double undersampled = 0, median_texels_per_pixel = 0;
  double shown_pixels = 0, face_pixels = 0;
};
TexelDensity texel_density(const DiskTexels& t, const TriangleMesh& surface, int width, int height);
// A coded copy of the captured texture (JPEG, an H.264 frame) against it, through the same map.
double psnr_of_copy(const DiskTexels& t, const Image& copy);

// ---- Draco: every frame through draco_encoder and draco_decoder -------------------------------

struct DracoPoint {
  int qp = 0;
  uint64_t bytes = 0;                 // .drc bytes of the frames measured
  std::vector<double> rms, max, p99;  // relative to the captured frame's diagonal
  int frames = 0;
};

DracoPoint draco_point(const Capture& capture, const std::vector<TriangleMesh>& captured, const std::vector<int>& frames, int qp,
                       const fs::path& scratch, TriangleMesh* decoded_of_first = nullptr);

// ---- H.264: the captured textures as one video per CRF, streamed through ffmpeg ---------------

struct Pipe {
  FILE* file = nullptr;
  std::string command;
  ~Pipe() {
    if (file) pclose(file);
  }
  int close() {
    const int status = file ? pclose(file) : -1;
    file = nullptr;
    return status;
  }
};

Image rgb_of(const Image& image);

// Writes one libx264 video per CRF of every captured texture (yuv420p, preset medium, the
// capture's frame rate); returns each file's bytes.
std::vector<uint64_t> encode_h264(const std::vector<fs::path>& textures, double fps, const std::vector<int>& crfs, const fs::path& scratch,
                                  int& width, int& height);

// Frames of the videos encode_h264 wrote, read in order, one reader per CRF.
class H264Readers {
 public:
  H264Readers(const std::vector<int>& crfs, const fs::path& scratch, int width, int height) : width_(width), height_(height) {
    for (int crf : crfs) {
      auto pipe = std::make_unique<Pipe>();
      pipe->command = "ffmpeg -v error -i " + shell_quote((scratch / ("texture_crf" + std::to_string(crf) + ".mp4")).string()) +
                      " -vf crop=" + std::to_string(width) + ":" + std::to_string(height) +
                      ":0:0 -f rawvideo -pix_fmt rgb24 - 2> /dev/null";
      pipe->file = popen(pipe->command.c_str(), "r");
      if (!pipe->file) throw Error(ErrorCode::kIo, "could not start ffmpeg: " + pipe->command);
      pipes_.push_back(std::move(pipe));
    }
  }
  // The next frame of every video.
  std::vector<Image> next() {
    std::vector<Image> frames;
    for (auto& pipe : pipes_) {
      Image image(width_, height_, 3);
      if (std::fread(image.pixels.data(), 1, image.pixels.size(), pipe->file) != image.pixels.size()) {
        throw Error(ErrorCode::kIo, "ffmpeg gave fewer frames than were encoded: " + pipe->command);
      }
      frames.push_back(std::move(image));
    }
    return frames;
  }

 private:
  int width_, height_;
  std::vector<std::unique_ptr<Pipe>> pipes_;
};

// The coarsest candidate whose error meets the target; candidates ordered coarse to fine, `meets`
// tells. The finest when none does (`met` false). When the coarsest meets, the baseline could go
// coarser still: its bytes are an upper bound, and the report says so.
template <typename Meets>
size_t coarsest_meeting(size_t count, Meets&& meets, bool& met) {
  for (size_t k = 0; k < count; ++k) {
    if (meets(k)) return met = true, k;
  }
  met = false;
  return count - 1;
}

// ---- one facemorph encode, measured -----------------------------------------------------------

struct Encoded {
  std::string label;
  double budget = 0;
  std::vector<int> keyframes;
  uint64_t bytes = 0, texture_bytes = 0;
  SequenceFileInfo info;
  Evaluation evaluation;
  std::map<int, double> psnr;        // texture PSNR by frame, where measured
  std::map<int, double> pixel_psnr;  // the same per captured pixel (pixel_psnr_of_disk)
  TexelDensity density;              // the first measured frame's
  double held_psnr() const { return held_mean(psnr); }
  double held_pixel_psnr() const { return held_mean(pixel_psnr); }
  double held_mean(const std::map<int, double>& by_frame) const {
    std::vector<double> v;
    for (const auto& [i, db] : by_frame) {
      if (!std::binary_search(keyframes.begin(), keyframes.end(), i)) v.push_back(db);
    }
    return v.empty() ? -1 : mean(v);
  }
  double key_psnr() const {
    std::vector<double> v;
    for (const auto& [i, db] : psnr) {
      if (std::binary_search(keyframes.begin(), keyframes.end(), i)) v.push_back(db);
    }
    return v.empty() ? -1 : mean(v);
  }
  uint64_t geometry_bytes() const { return bytes - texture_bytes; }
};

// Seconds by stage, in the order the stages first ran.
class StageSeconds {
 public:
  double& operator[](const std::string& stage) {
    for (auto& [name, seconds] : stages_) {
      if (name == stage) return seconds;
    }
    return stages_.emplace_back(stage, 0.0).second;
  }
  auto begin() const { return stages_.begin(); }
  auto end() const { return stages_.end(); }

 private:
  std::vector<std::pair<std::string, double>> stages_;
};

struct Context {
  const CaptureBenchOptions& options;
  const Plan& plan;
  fs::path scratch;
  std::string markdown;
};

// ---- the capture as it lies on disk ------------------------------------------------------------

struct CapturedFrames {
  Capture capture;
  std::string label;
  fs::path scratch;  // the baselines' files
  int count = 0;
  double duration = 0;  // seconds, the last frame's included
  std::vector<TriangleMesh> meshes;
  uint64_t raw_mesh = 0, raw_texture = 0;  // bytes of the OBJ + MTL files, and of their images
  int64_t vertex_frames = 0;
  std::vector<fs::path> textures;
  bool textured = false;           // every frame has its image
  std::vector<int> every, sample;  // every frame; the frames the baselines' sweeps are measured on
};

CapturedFrames read_captured_frames(const Context& context, const fs::path& folder, const std::string& input);

// ---- facemorph's points, and the texture baselines measured as they decode ---------------------

// JPEG at every quality and H.264 at every CRF, on the sample frames.
struct TextureBaselines {
  std::map<int, std::vector<double>> jpeg_psnr, h264_psnr;
  std::map<int, uint64_t> jpeg_sample_bytes;
  std::vector<uint64_t> h264_bytes;
};

struct FacemorphPoints {
  int grid = 0;
  std::vector<int> main_keys;
  Encoded main, xyz;  // fmenc's default budget (or the file given), and its xyz variant
  size_t residual_frames = 0;
  std::vector<Encoded> curve, xyz_curve;  // by keyframe budget
  int shown = 0;                          // the held-out frame nearest the middle, for the pictures
  DecodedFrame shown_decoded;
};

FacemorphPoints measure_facemorph(const Context& context, const CapturedFrames& c, StageSeconds& stage_seconds, TextureBaselines& texture);

// ---- the baselines at facemorph's error --------------------------------------------------------

struct MatchedBaselines {
  std::vector<DracoPoint> draco_curve;  // on the sample frames, at every qp
  DracoPoint draco;                     // on every frame, at the qp chosen
  bool draco_met = false;
  size_t draco_pick = 0, draco_first_pick = 0;
  TriangleMesh draco_shown;
  bool jpeg_met = false, h264_met = false;
  int jpeg_quality = 0, h264_crf = 0;
  std::string jpeg_note, h264_note;
  uint64_t jpeg_bytes = 0, h264_total = 0;
};

MatchedBaselines match_baselines(const Plan& plan, const CapturedFrames& c, int shown, const TextureBaselines& texture, double target_rms,
                                 double target_psnr, StageSeconds& stage_seconds);

// ---- figures -----------------------------------------------------------------------------------

struct FigureRow {
  std::string name, setting;
  double geometry = 0, texture = 0;  // bytes
  double rms = -1, rms_worst = -1, psnr = -1;
  double p99 = -1;  // the worst frame's 99th-percentile point error
};

// What one capture measured, for the table, the report and the JSON.
struct CaptureFigures {
  const CapturedFrames& c;
  const FacemorphPoints& fm;
  const TextureBaselines& texture;
  const MatchedBaselines& baselines;
  const StageSeconds& stage_seconds;
  Summary summary;
  double target_rms = 0, target_psnr = 0;  // facemorph's held-out RMS and texture PSNR, the baselines' targets
  std::vector<FigureRow> rows;
  std::vector<std::string> targets;
  double draco_ratio = 0, jpeg_ratio = 0, h264_ratio = 0, bits = 0, encode_seconds = 0;
  double fm_total() const { return static_cast<double>(fm.main.bytes); }
  double fm_geometry() const { return static_cast<double>(fm.main.geometry_bytes()); }
};

void add_rows_and_targets(CaptureFigures& f);
void print_figures(const CaptureFigures& f);
// The curves and pictures beside the report; returns the Markdown that shows them.
std::string write_report_pictures(const fs::path& report, const Plan& plan, const CaptureFigures& f);
std::string markdown_report(const std::string& input, const fs::path& folder, const Plan& plan, const CaptureFigures& f);
json capture_json(const std::string& input, const fs::path& folder, const Plan& plan, const CaptureFigures& f);

// ---- --geometry-only (bench_capture_geometry.cpp) ------------------------------------------------

// --geometry-only: the given file's geometry error on every frame of its capture, nothing else (no
// mapping, no baselines): comparing encodes of one capture in seconds rather than minutes.
json measure_geometry_only(const CaptureBenchOptions& options, const std::string& input);

}  // namespace facemorph::tools::capture_bench
