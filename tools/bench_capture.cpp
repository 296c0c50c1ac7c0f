// fmbench --capture: facemorph's rate on whole captures, side by side in one run with what users
// would ship instead. For each capture: the .fmv file's bytes (per chunk type, per second, bits per
// captured vertex per frame); every captured frame decoded at its own time and measured against it
// (symmetric point-to-surface RMS and max relative to the bbox diagonal, D1 PSNR with the diagonal as
// peak, texture PSNR on the disk through the frame's own map); encode time by stage, decode time,
// peak memory; and the baselines: the raw capture, Draco per frame at the coarsest quantisation
// whose error is at most facemorph's held-out error, + JPEG textures or + one H.264 texture video at
// the quality that matches facemorph's texture PSNR, and facemorph's own xyz representation.
#include "tools/bench_capture.hpp"

#include "codec/meshkit/geometry/distance.hpp"
#include "facemorph/decoder.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/meshkit/render/render.hpp"
#include "codec/decoder/container/sequence_file.hpp"

#include "tools/bench_sequence.hpp"
#include "tools/plot.hpp"
#include "tools/tool_support.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"

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

namespace facemorph::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// What one run tries: the full bench, or the smoke test CI runs in about a minute.
struct Plan {
  SynthOptions synth;
  int frame_limit = 0;      // 0: every frame
  int texture_size = 0;     // fmenc's default: auto (as sharp as the capture's texture, at most 1024)
  int sample_frames = 15;   // frames the baselines' sweeps are measured on (the matched points on all)
  std::vector<double> budgets = {0.05, 0.10, 0.20, 0.30};
  std::vector<int> draco_qp = {3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14};  // coarse to fine
  std::vector<int> jpeg_quality = {2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 95};
  std::vector<int> h264_crf = {14, 18, 22, 26, 30, 34, 38, 42, 46, 51};  // fine to coarse
};

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

// ---- texture PSNR on the disk through each frame's own map --------------------------------------

// The texels of a size x size disk texture inside the disk, where each lies in the captured
// texture (through the frame's registration and map), and the captured texture's colour there.
// Computed once per frame; then any image of the captured texture's layout (a JPEG or H.264
// decode of it) or any disk texture (facemorph's decode) is compared against it.
struct DiskTexels {
  int size = 0;
  std::vector<int> texel;       // y * size + x
  std::vector<Vec2> uv;         // in the captured texture
  std::vector<uint8_t> truth;   // RGB of the captured texture there
};

std::array<uint8_t, 3> rounded(const std::array<double, 3>& rgb) {
  std::array<uint8_t, 3> out{};
  for (size_t c = 0; c < 3; ++c) out[c] = static_cast<uint8_t>(std::clamp(std::lround(rgb[c]), 0L, 255L));
  return out;
}

DiskTexels disk_texels(const SequenceEncoder& encoder, int frame, const Image& captured, int size) {
  DiskTexels t;
  t.size = size;
  const std::shared_ptr<const MappedFrame> mapped = encoder.frame(frame);  // held while `inverse` refers to its map
  const InverseDiskMap inverse(mapped->map);
  const SequenceEncoder::Sampler sample = encoder.sampler(frame);
  std::vector<std::vector<std::pair<int, Vec2>>> rows(static_cast<size_t>(size));
  parallel_for(size, 0, [&](int y) {
    for (int x = 0; x < size; ++x) {
      const Vec2 w(2 * (x + 0.5) / size - 1, 1 - 2 * (y + 0.5) / size);
      if (w.norm() > 1) continue;
      Vec2 v = sample(w);
      if (v.norm() > 1) v.normalize();
      if (const auto hit = inverse.locate(v)) rows[static_cast<size_t>(y)].emplace_back(y * size + x, inverse.texture_uv(*hit));
    }
  });
  for (const auto& row : rows) {
    for (const auto& [texel, uv] : row) {
      t.texel.push_back(texel);
      t.uv.push_back(uv);
      const auto rgb = rounded(sample_bilinear(captured, uv.x(), uv.y()));
      t.truth.insert(t.truth.end(), rgb.begin(), rgb.end());
    }
  }
  return t;
}

template <typename Colour>
double texel_psnr(const DiskTexels& t, Colour&& colour) {
  double sum = 0;
  for (size_t k = 0; k < t.texel.size(); ++k) {
    const std::array<uint8_t, 3> c = colour(k);
    for (size_t j = 0; j < 3; ++j) {
      const double d = double(c[j]) - double(t.truth[3 * k + j]);
      sum += d * d;
    }
  }
  const double mse = sum / std::max<double>(3.0 * static_cast<double>(t.texel.size()), 1);
  return psnr_of_mse(std::max(mse, 1e-12));
}

// A disk texture (facemorph's decode) against the captured texture.
double psnr_of_disk(const DiskTexels& t, const Image& disk) {
  if (disk.width != t.size) throw Error(ErrorCode::kInternal, "decoded texture size differs from the measured one");
  return texel_psnr(t, [&](size_t k) {
    const uint8_t* p = disk.at(t.texel[k] % t.size, t.texel[k] / t.size);
    return std::array<uint8_t, 3>{p[0], p[1], p[2]};
  });
}

// A coded copy of the captured texture (JPEG, an H.264 frame) against it, through the same map.
double psnr_of_copy(const DiskTexels& t, const Image& copy) {
  return texel_psnr(t, [&](size_t k) { return rounded(sample_bilinear(copy, t.uv[k].x(), t.uv[k].y())); });
}

// ---- Draco: every frame through draco_encoder and draco_decoder -------------------------------

struct DracoPoint {
  int qp = 0;
  uint64_t bytes = 0;           // .drc bytes of the frames measured
  std::vector<double> rms, max, p99;  // relative to the captured frame's diagonal
  int frames = 0;
};

DracoPoint draco_point(const Capture& capture, const std::vector<TriangleMesh>& captured, const std::vector<int>& frames, int qp,
                       const fs::path& scratch, TriangleMesh* decoded_of_first = nullptr) {
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
    pipe->command = "ffmpeg -v error -y -f rawvideo -pix_fmt rgb24 -s " + std::to_string(width) + "x" + std::to_string(height) + " -r " + rate +
                    " -i - -vf 'pad=ceil(iw/2)*2:ceil(ih/2)*2' -c:v libx264 -preset medium -crf " + std::to_string(crf) +
                    " -pix_fmt yuv420p " + shell_quote((scratch / ("texture_crf" + std::to_string(crf) + ".mp4")).string()) + " > /dev/null 2>&1";
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

// Frames of the videos encode_h264 wrote, read in order, one reader per CRF.
class H264Readers {
 public:
  H264Readers(const std::vector<int>& crfs, const fs::path& scratch, int width, int height) : width_(width), height_(height) {
    for (int crf : crfs) {
      auto pipe = std::make_unique<Pipe>();
      pipe->command = "ffmpeg -v error -i " + shell_quote((scratch / ("texture_crf" + std::to_string(crf) + ".mp4")).string()) + " -vf crop=" +
                      std::to_string(width) + ":" + std::to_string(height) + ":0:0 -f rawvideo -pix_fmt rgb24 - 2> /dev/null";
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
  std::map<int, double> psnr;  // texture PSNR by frame, where measured
  double held_psnr() const {
    std::vector<double> v;
    for (const auto& [i, db] : psnr) {
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
  return std::string(what) + ": " + fixed(ratio, 2) + "x (target " + fixed(target, 0) + "x: " +
         (ratio >= target ? "met" : "missed by " + fixed(target / ratio, 1) + "x") + ")";
}

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

// The frame of `capture` nearest `time` (the earlier of two as near): where a file's keyframe lies.
int nearest_frame(const Capture& capture, double time) {
  int nearest = 0;
  for (int i = 1; i < static_cast<int>(capture.frames.size()); ++i) {
    if (std::abs(capture.frames[static_cast<size_t>(i)].time - time) < std::abs(capture.frames[static_cast<size_t>(nearest)].time - time)) nearest = i;
  }
  return nearest;
}

// --geometry-only: the given file's geometry error on every frame of its capture, nothing else (no
// mapping, no baselines): comparing encodes of one capture in seconds rather than minutes.
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
  if (count == 0 || std::abs(sequence.first_time - capture.frames.front().time) > slack || std::abs(sequence.last_time - capture.frames.back().time) > slack) {
    throw Error(ErrorCode::kInvalidArgument, options.fmv + " spans " + std::to_string(sequence.first_time) + " to " + std::to_string(sequence.last_time) +
                                                 " s, " + input + " " + (count == 0 ? std::string("has no frames") : std::to_string(capture.frames.front().time) + " to " +
                                                 std::to_string(capture.frames.back().time) + " s") + ": its keyframes are no frames of it (was the file made from another capture?)");
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
  if (other && other->outline().grid_n != sequence.grid_n) throw Error(ErrorCode::kInvalidArgument, options.against + ": another grid than " + options.fmv + "'s");
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
      const SurfaceDistance d = surface_distance(read_mesh(capture.mesh_path(static_cast<size_t>(i)), {.allow_missing_texture = true}), decoded.mesh);
      f.rms = d.rms / d.diagonal;
      f.max = d.max / d.diagonal;
      f.p99 = d.p99 / d.diagonal;
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
  std::printf("%s: %llu bytes, %d keyframes of %d frames, N = %d; ", options.fmv.c_str(), static_cast<unsigned long long>(file_bytes), e.keyframes, count, e.grid);
  if (held_out) {
    std::printf("held-out RMS %.4f%% mean, %.4f%% worst, max %.4f%%; ", 100 * s.held_rms_mean, 100 * s.held_rms_worst, 100 * s.held_max_worst);
  } else {
    std::printf("no held-out frames (every frame a keyframe); ");
  }
  std::printf("keyframes RMS %.4f%% mean, %.4f%% worst; 99th percentile %.4f%% worst frame\n", 100 * s.key_rms_mean, 100 * s.key_rms_worst, 100 * s.p99_worst);
  json evaluation = evaluation_json(e);
  if (other) {
    double mean = 0;
    for (double a : apart) mean += a / static_cast<double>(count);
    const double worst = *std::max_element(apart.begin(), apart.end());
    std::printf("  decoded apart from %s: RMS %.4f%% mean, %.4f%% worst of the diagonal\n", options.against.c_str(), 100 * mean, 100 * worst);
    evaluation["against"] = {{"fmv", options.against}, {"rms_mean", mean}, {"rms_worst", worst}};
  }
  for (const char* key : {"decode_ms_per_frame", "mean_iterations"}) evaluation.erase(key);  // not measured here
  if (!held_out) {
    for (const char* key : {"held_out_rms_mean", "held_out_rms_worst", "held_out_max_worst"}) evaluation[key] = nullptr;
  }
  return {{"input", input}, {"fmv", options.fmv}, {"bytes", file_bytes}, {"evaluation", evaluation}};
}

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
  bool textured = false;  // every frame has its image
  std::vector<int> every, sample;  // every frame; the frames the baselines' sweeps are measured on
};

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

// ---- facemorph's points, and the texture baselines measured as they decode ---------------------

// JPEG at every quality and H.264 at every CRF, on the sample frames.
struct TextureBaselines {
  std::map<int, std::vector<double>> jpeg_psnr, h264_psnr;
  std::map<int, uint64_t> jpeg_sample_bytes;
  std::vector<uint64_t> h264_bytes;
};

// The mean of the values under `key`; 0 where none was measured.
double mean_at(const std::map<int, std::vector<double>>& values, int key) {
  const auto found = values.find(key);
  return found == values.end() ? 0 : mean(found->second);
}

struct FacemorphPoints {
  int grid = 0;
  std::vector<int> main_keys;
  Encoded main, xyz;  // fmenc's default budget (or the file given), and its xyz variant
  size_t residual_frames = 0;
  std::vector<Encoded> curve, xyz_curve;  // by keyframe budget
  int shown = 0;  // the held-out frame nearest the middle, for the pictures
  DecodedFrame shown_decoded;
};

FacemorphPoints measure_facemorph(const Context& context, const CapturedFrames& c, StageSeconds& stage_seconds, TextureBaselines& texture) {
  const CaptureBenchOptions& options = context.options;
  const Plan& plan = context.plan;
  const int count = c.count;
  // facemorph, stage by stage, with fmenc's defaults (the texture smaller with --quick).
  EncodeOptions encode;
  encode.texture = c.textured;
  encode.texture_size = plan.texture_size;
  encode.residual_frames = options.residual_frames;
  Progress progress(c.label, options.quiet);
  encode.progress = [&](const std::string&, int done, int total) { progress.update(done, total); };
  SequenceFileInfo given_info;
  std::optional<Sequence> given;
  if (!options.fmv.empty()) {
    given = read_sequence_file(options.fmv, &given_info);
    const json settings = json::parse(given_info.metadata.settings.empty() ? "{}" : given_info.metadata.settings, nullptr, false);
    if (settings.is_object() && settings.contains("registration")) encode.registration.method = parse_registration_method(settings["registration"]);
    encode.representation = given->representation;
  }
  SequenceEncoder encoder(c.capture, encode);
  auto timed = [&](const char* stage, auto&& body) {
    const auto start = std::chrono::steady_clock::now();
    body();
    stage_seconds[stage] += seconds_since(start);
  };
  timed("mapping", [&] { encoder.map_frames(); });
  timed("registration", [&] { encoder.register_frames(); });
  timed("sampling", [&] { encoder.sample_frames(); });
  // fmenc's order: the keyframes first, then the grid their predicted error allows.
  FacemorphPoints points;
  KeyframeSelection main_chosen;
  if (!given) timed("selection", [&] { main_chosen = encoder.select_keyframes(); });
  int& grid = points.grid;
  timed("grid", [&] { grid = given ? given->grid_n : encoder.choose_grid(&main_chosen); });
  if (!given) timed("representation", [&] { encoder.choose_representation(main_chosen, grid); });
  const Representation main_representation = given ? given->representation : encoder.representation();
  progress.finish();

  // Facemorph's texture PSNR per frame (and the baselines' on the sample frames) as frames decode.
  auto measure = [&](const std::string& name, double budget, const std::vector<int>& keyframes, const Sequence& sequence, uint64_t bytes,
                     const SequenceFileInfo& info, bool all_textures,
                     const std::function<void(int, const DiskTexels&, const DecodedFrame&)>& also = {}) {
    Encoded out;
    out.label = name;
    out.budget = budget;
    out.keyframes = keyframes;
    out.bytes = bytes;
    out.info = info;
    out.texture_bytes = chunk_bytes(info, "TEXR") + chunk_bytes(info, "TGOP");  // stills, or one sequence per group (2.1)
    out.evaluation = evaluate(encoder, sequence, keyframes, c.meshes, c.every, false, [&](int i, const DecodedFrame& decoded) {
      const bool measured = c.textured && !decoded.texture.empty() && (all_textures || std::binary_search(c.sample.begin(), c.sample.end(), i));
      if (!measured && !also) return;
      if (!measured) return also(i, DiskTexels{}, decoded);
      const Image source = read_image(c.textures[static_cast<size_t>(i)]);
      const DiskTexels texels = disk_texels(encoder, i, source, decoded.texture.width);
      out.psnr[i] = psnr_of_disk(texels, decoded.texture);
      if (also) also(i, texels, decoded);
    });
    for (const auto& [i, db] : out.psnr) out.evaluation.frames[static_cast<size_t>(i)].psnr = db;  // frames_to_decode is every frame
    return out;
  };
  std::map<std::vector<int>, std::vector<int>> texture_qualities;  // per keyframe set, as encode_file chose them
  // As fmenc stores it: the keyframes built, their fields rounded to the steps their error allows
  // (fmenc's default), the file written and read back.
  auto encode_file = [&](const KeyframeSelection& chosen, int n, Representation representation, std::vector<uint8_t>& bytes, SequenceFileInfo& info) {
    const bool xyz_variant = representation == Representation::kXYZ && main_representation != Representation::kXYZ;
    encoder.options().representation = representation;
    Sequence sequence;
    timed(xyz_variant ? "keyframes (xyz)" : "keyframes", [&] { sequence = encoder.build(chosen.keyframes, n); });
    sequence.residuals = encoder.residual_frames(chosen);
    FieldCoding coding;
    if (encoder.options().predicted_fields) timed(xyz_variant ? "field precision (xyz)" : "field precision", [&] { coding = encoder.round_fields(sequence, chosen); });
    Sequence back;
    // The textures depend on the keyframes only (not on the representation or N): chosen once for each set.
    std::vector<int>& qualities = texture_qualities[chosen.keyframes];
    if (qualities.empty()) timed("texture quality", [&] { qualities = encoder.choose_texture_qualities(sequence, chosen.keyframes); });
    timed(xyz_variant ? "file (xyz)" : "file", [&] { back = file_round_trip(sequence, qualities, &bytes, &info, coding); });
    return back;
  };

  // The texture baselines are measured while facemorph's main encode decodes (one pass over the
  // captured textures): JPEG at every quality, and H.264 at every CRF.
  std::unique_ptr<H264Readers> h264;
  if (c.textured) {
    Progress h264_progress(c.label + " h264", true);
    int width = 0, height = 0;
    const auto start = std::chrono::steady_clock::now();
    texture.h264_bytes = encode_h264(c.textures, c.capture.fps, plan.h264_crf, c.scratch, width, height);
    stage_seconds["baseline h264 encode"] = seconds_since(start);
    h264 = std::make_unique<H264Readers>(plan.h264_crf, c.scratch, width, height);
  }
  auto baselines_at = [&](int i, const DiskTexels& texels, const DecodedFrame&) {
    if (!h264) return;
    const std::vector<Image> videos = h264->next();  // every frame is read, the sample ones measured
    if (texels.texel.empty() || !std::binary_search(c.sample.begin(), c.sample.end(), i)) return;
    for (size_t k = 0; k < plan.h264_crf.size(); ++k) texture.h264_psnr[plan.h264_crf[k]].push_back(psnr_of_copy(texels, videos[k]));
    const Image source = rgb_of(read_image(c.textures[static_cast<size_t>(i)]));
    for (int q : plan.jpeg_quality) {
      const std::vector<uint8_t> jpeg = encode_image(source, ".jpg", q);
      texture.jpeg_sample_bytes[q] += jpeg.size();
      texture.jpeg_psnr[q].push_back(psnr_of_copy(texels, decode_image(jpeg, "jpeg")));
    }
  };

  // The main point: fmenc's default budget (or the file given), every frame's texture measured.
  std::vector<uint8_t> main_bytes;
  SequenceFileInfo main_info;
  Sequence main_sequence;
  std::vector<int>& main_keys = points.main_keys;
  if (given) {
    for (const Keyframe& key : given->keyframes) main_keys.push_back(nearest_frame(c.capture, key.time));
    main_chosen.keyframes = main_keys;  // without predicted errors the xyz variant gets auto field error's default (1e-4)
    main_sequence = *given;
    main_info = given_info;
    main_bytes.resize(given_info.file_bytes);
  } else {
    main_keys = main_chosen.keyframes;
    main_sequence = encode_file(main_chosen, grid, main_representation, main_bytes, main_info);
  }
  points.residual_frames = main_sequence.residuals.size();
  points.shown = [&] {
    for (int d = 0; d < count; ++d) {
      for (int i : {count / 2 - d, count / 2 + d}) {
        if (i >= 0 && i < count && !std::binary_search(main_keys.begin(), main_keys.end(), i)) return i;
      }
    }
    return count / 2;
  }();
  const auto decode_start = std::chrono::steady_clock::now();
  points.main = measure(given ? "facemorph (" + options.fmv + ")" : "facemorph", encode.keyframe_fraction, main_keys, main_sequence,
                        main_bytes.size(), main_info, true, [&](int i, const DiskTexels& texels, const DecodedFrame& decoded) {
                          baselines_at(i, texels, decoded);
                          if (i == points.shown) points.shown_decoded = decoded;
                        });
  stage_seconds["measuring facemorph and the texture baselines"] = seconds_since(decode_start);
  h264.reset();

  // Facemorph's xyz variant: the same keyframes, grid and spline.
  std::vector<uint8_t> xyz_bytes;
  SequenceFileInfo xyz_info;
  const Sequence xyz_sequence = encode_file(main_chosen, grid, Representation::kXYZ, xyz_bytes, xyz_info);
  points.xyz = measure("facemorph xyz", points.main.budget, main_keys, xyz_sequence, xyz_bytes.size(), xyz_info, false);
  encoder.options().representation = encode.representation;

  // Keyframe budgets: facemorph's rate-distortion curve (and xyz's), texture on the sample frames.
  for (double budget : plan.budgets) {
    if (!given && std::abs(budget - encode.keyframe_fraction) < 1e-9) {
      points.curve.push_back(points.main);
      points.xyz_curve.push_back(points.xyz);
      continue;
    }
    encoder.options().keyframe_fraction = budget;
    const KeyframeSelection chosen = encoder.select_keyframes();
    const int budget_grid = given ? grid : encoder.choose_grid(&chosen);  // as fmenc would for this budget
    std::vector<uint8_t> bytes;
    SequenceFileInfo info;
    const Sequence sequence = encode_file(chosen, budget_grid, main_sequence.representation, bytes, info);
    points.curve.push_back(measure("facemorph", budget, chosen.keyframes, sequence, bytes.size(), info, false));
    const Sequence xyz_at = encode_file(chosen, budget_grid, Representation::kXYZ, bytes, info);
    points.xyz_curve.push_back(measure("facemorph xyz", budget, chosen.keyframes, xyz_at, bytes.size(), info, false));
    encoder.options().representation = encode.representation;
    if (!options.quiet) std::fprintf(stderr, "fmbench --capture: %s: keyframe budget %g%% measured\n", c.label.c_str(), 100 * budget);
  }
  encoder.options().keyframe_fraction = encode.keyframe_fraction;
  return points;
}

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

// " (... not matched ...)" where a baseline missed facemorph's figure at its finest setting, or "an
// upper bound" where its coarsest setting met it already.
std::string match_note(bool met, size_t pick, const char* missed) {
  return !met ? std::string(" (") + missed + " not matched at the finest tried)" : pick == 0 ? std::string(" (the coarsest tried: an upper bound)") : std::string();
}

MatchedBaselines match_baselines(const Plan& plan, const CapturedFrames& c, int shown, const TextureBaselines& texture, double target_rms,
                                 double target_psnr, StageSeconds& stage_seconds) {
  MatchedBaselines m;
  // Draco on the sample frames at every qp, the coarsest meeting facemorph's held-out RMS then on
  // every frame (one finer while the whole capture misses it).
  const auto draco_start = std::chrono::steady_clock::now();
  for (int qp : plan.draco_qp) m.draco_curve.push_back(draco_point(c.capture, c.meshes, c.sample, qp, c.scratch));
  m.draco_pick = coarsest_meeting(m.draco_curve.size(), [&](size_t k) { return mean(m.draco_curve[k].rms) <= target_rms; }, m.draco_met);
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
    const size_t q = coarsest_meeting(plan.jpeg_quality.size(), [&](size_t k) { return jpeg_psnr(plan.jpeg_quality[k]) >= target_psnr; }, m.jpeg_met);
    m.jpeg_quality = plan.jpeg_quality[q];
    m.jpeg_note = match_note(m.jpeg_met, q, "PSNR");
    for (const fs::path& path : c.textures) m.jpeg_bytes += encode_image(rgb_of(read_image(path)), ".jpg", m.jpeg_quality).size();
    // CRFs fine to coarse in the plan: the coarsest meeting is the last that does.
    const size_t n = plan.h264_crf.size();
    const size_t crf = coarsest_meeting(n, [&](size_t k) { return h264_psnr(plan.h264_crf[n - 1 - k]) >= target_psnr; }, m.h264_met);
    m.h264_crf = plan.h264_crf[n - 1 - crf];
    m.h264_note = match_note(m.h264_met, crf, "PSNR");
    m.h264_total = texture.h264_bytes[n - 1 - crf];
  }
  return m;
}

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

void add_rows_and_targets(CaptureFigures& f) {
  const MatchedBaselines& b = f.baselines;
  const FacemorphPoints& fm = f.fm;
  f.rows = {
      {"facemorph", "keyframes " + std::to_string(fm.main_keys.size()) + ", N = " + std::to_string(fm.grid), double(fm.main.geometry_bytes()),
       double(fm.main.texture_bytes), f.target_rms, f.summary.held_rms_worst, f.target_psnr, f.summary.p99_worst},
      {"raw capture", "OBJ + MTL + images as captured", double(f.c.raw_mesh), double(f.c.raw_texture), -1, -1, -1},
      {"draco", "-qp " + std::to_string(b.draco.qp) + " -cl 7" + match_note(b.draco_met, b.draco_pick == b.draco_first_pick ? b.draco_pick : 1, "error"),
       double(b.draco.bytes), 0, mean(b.draco.rms), worst(b.draco.rms), -1, worst(b.draco.p99)},
  };
  if (f.c.textured) {
    f.rows.push_back({"draco + jpeg", "-qp " + std::to_string(b.draco.qp) + ", JPEG q" + std::to_string(b.jpeg_quality) + b.jpeg_note, double(b.draco.bytes),
                      double(b.jpeg_bytes), mean(b.draco.rms), worst(b.draco.rms), mean_at(f.texture.jpeg_psnr, b.jpeg_quality), worst(b.draco.p99)});
    f.rows.push_back({"draco + h264", "-qp " + std::to_string(b.draco.qp) + ", x264 crf " + std::to_string(b.h264_crf) + b.h264_note, double(b.draco.bytes),
                      double(b.h264_total), mean(b.draco.rms), worst(b.draco.rms), mean_at(f.texture.h264_psnr, b.h264_crf), worst(b.draco.p99)});
  }
  const Summary xyz = summarise(fm.xyz.evaluation);
  f.rows.push_back({"facemorph xyz", "same keyframes and spline", double(fm.xyz.geometry_bytes()), double(fm.xyz.texture_bytes), xyz.held_rms_mean,
                    xyz.held_rms_worst, -1, xyz.p99_worst});

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
                      (f.bits <= 1 && f.target_rms <= 0.005 ? std::string("met") : "missed" + (f.bits > 1 ? " by " + fixed(f.bits, 1) + "x" : std::string())) + ")");
  f.targets.push_back("99th-percentile point error, worst decoded frame: " + fixed(100 * f.summary.p99_worst, 3) + "% of the diagonal (target <= 1%: " +
                      (f.summary.p99_worst <= 0.01 ? std::string("met") : "missed by " + fixed(f.summary.p99_worst / 0.01, 2) + "x") + ")");
}

void print_figures(const CaptureFigures& f) {
  const FacemorphPoints& fm = f.fm;
  const Summary& summary = f.summary;
  std::printf("  facemorph: %llu bytes (%.0f B/s, %.3f bits per captured vertex per frame, %.3f without texture), keyframes %zu, residual frames %zu, N = %d\n",
              static_cast<unsigned long long>(fm.main.bytes), f.fm_total() / f.c.duration, f.bits, 8 * f.fm_geometry() / double(f.c.vertex_frames),
              fm.main_keys.size(), fm.residual_frames, fm.grid);
  std::printf("  chunks:");
  for (const auto& c : fm.main.info.chunks) std::printf(" %s %llu", c.type.c_str(), static_cast<unsigned long long>(c.stored_bytes));
  std::printf("\n  held-out RMS %.4f%% mean, %.4f%% worst, max %.4f%%; keyframes RMS %.4f%%; 99th percentile %.4f%% worst frame; D1 PSNR held-out %.2f dB; texture PSNR held-out %.2f dB, keyframes %.2f dB\n",
              100 * f.target_rms, 100 * summary.held_rms_worst, 100 * summary.held_max_worst, 100 * summary.key_rms_mean, 100 * summary.p99_worst,
              d1_psnr(relative_rms(fm.main.evaluation, false)), f.target_psnr, fm.main.key_psnr());
  std::printf("  %-16s %12s %12s %12s %10s %10s %10s %9s %9s %9s  %s\n", "", "geometry B", "texture B", "total B", "rms mn%", "rms wst%", "p99 wst%", "tex dB",
              "geo x", "total x", "setting");
  for (const FigureRow& r : f.rows) {
    const double total = r.geometry + r.texture;
    std::printf("  %-16s %12.0f %12.0f %12.0f %10s %10s %10s %9s %9.2f %9.2f  %s\n", r.name.c_str(), r.geometry, r.texture, total,
                r.rms >= 0 ? fixed(100 * r.rms, 4).c_str() : "-", r.rms_worst >= 0 ? fixed(100 * r.rms_worst, 4).c_str() : "-",
                r.p99 >= 0 ? fixed(100 * r.p99, 4).c_str() : "-", r.psnr >= 0 ? fixed(r.psnr, 2).c_str() : "-", r.geometry / f.fm_geometry(),
                total / f.fm_total(), r.setting.c_str());
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
  for (const Encoded& e : fm.curve) fmc.x.push_back(std::log10(e.geometry_bytes() / frames)), fmc.y.push_back(100 * summarise(e.evaluation).held_rms_mean);
  for (const Encoded& e : fm.xyz_curve) fx.x.push_back(std::log10(e.geometry_bytes() / frames)), fx.y.push_back(100 * summarise(e.evaluation).held_rms_mean);
  for (const DracoPoint& p : f.baselines.draco_curve) dr.x.push_back(std::log10(p.bytes / double(p.frames))), dr.y.push_back(100 * mean(p.rms));
  PlotOptions geometry_plot;
  geometry_plot.x_label = "log10 geometry bytes per frame";
  geometry_plot.y_label = "held-out rms (% of diagonal)";
  write_image(dir / (c.label + "_rd_geometry.png"), line_plot({fmc, fx, dr}, geometry_plot));
  md += "![geometry rate-distortion](" + c.label + "_rd_geometry.png)\n\n";
  if (c.textured) {
    PlotSeries ft = series("facemorph (keyframe budget)", {200, 40, 40}), jp = series("jpeg (quality)", {40, 150, 60}), hv = series("h264 (crf)", {120, 60, 180});
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
  write_image(dir / (c.label + "_frames.png"), side_by_side({picture(truth, truth_texture), picture(fm.shown_decoded.mesh, fm.shown_decoded.texture),
                                                             picture(f.baselines.draco_shown, truth_texture)}));
  md += "Frame " + std::to_string(fm.shown) + " (t = " + fixed(c.capture.frames[static_cast<size_t>(fm.shown)].time, 3) + " s, held out): captured, facemorph, Draco -qp " +
        std::to_string(f.baselines.draco.qp) + "\n\n![frames](" + c.label + "_frames.png)\n\n";
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
  const std::string source = synthetic ? "made by fmsynth --frames " + std::to_string(plan.synth.frames) + " --vertices " + std::to_string(plan.synth.vertices) +
                                             " --remesh --expression mixed (noise " + fixed(plan.synth.noise, 4) + " m, texture " +
                                             std::to_string(plan.synth.texture_size) + ")"
                                       : folder.string();
  report << "## " << c.label << "\n\n" << source << ": " << c.count << " frames at " << fixed(c.capture.fps, 3) << " fps (" << fixed(c.duration, 2)
         << " s), " << fixed(double(c.vertex_frames) / frames, 0) << " vertices per frame" << (c.textured ? ", textured" : ", no texture") << ".\n\n";
  report << "### Rate\n\n| | |\n| --- | --- |\n| file | " << fm.main.bytes << " bytes (" << fm.main_keys.size() << " keyframes of " << c.count << ", N = " << fm.grid
         << ") |\n| per second | " << fixed(f.fm_total() / c.duration, 0) << " B/s (" << fixed(8 * f.fm_total() / c.duration / 1000, 1) << " kbit/s) |\n"
         << "| bits per captured vertex per frame | " << fixed(f.bits, 3) << " with texture, " << fixed(8 * f.fm_geometry() / double(c.vertex_frames), 3)
         << " without |\n";
  for (const auto& chunk : fm.main.info.chunks) report << "| chunk " << chunk.type << " | " << chunk.count << " x, " << chunk.stored_bytes << " bytes |\n";
  report << "\n### Distortion (every frame decoded at its own time)\n\n| frames | RMS mean | RMS worst | p99 worst | max worst | D1 PSNR | texture PSNR |\n"
         << "| --- | --- | --- | --- | --- | --- | --- |\n";
  std::vector<double> key_max, held_max, key_p99, held_p99;
  for (const FrameError& e : fm.main.evaluation.frames) {
    (e.keyframe ? key_max : held_max).push_back(e.max);
    (e.keyframe ? key_p99 : held_p99).push_back(e.p99);
  }
  report << "| keyframes | " << fixed(100 * summary.key_rms_mean, 4) << "% | " << fixed(100 * summary.key_rms_worst, 4) << "% | " << fixed(100 * worst(key_p99), 4) << "% | "
         << fixed(100 * worst(key_max), 4) << "% | " << fixed(d1_psnr(relative_rms(fm.main.evaluation, true)), 2) << " dB | " << fixed(fm.main.key_psnr(), 2) << " dB |\n";
  report << "| held out | " << fixed(100 * summary.held_rms_mean, 4) << "% | " << fixed(100 * summary.held_rms_worst, 4) << "% | " << fixed(100 * worst(held_p99), 4) << "% | "
         << fixed(100 * summary.held_max_worst, 4) << "% | " << fixed(d1_psnr(relative_rms(fm.main.evaluation, false)), 2) << " dB | " << fixed(f.target_psnr, 2)
         << " dB |\n\n";
  report << "### Baselines (geometry matched to facemorph's held-out mean RMS, texture to its held-out PSNR)\n\n"
         << "| | setting | geometry | texture | total | RMS mean | RMS worst | p99 worst | texture PSNR | geometry / facemorph | total / facemorph |\n"
         << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const FigureRow& r : f.rows) {
    report << "| " << r.name << " | " << r.setting << " | " << kilobytes(r.geometry) << " | " << kilobytes(r.texture) << " | " << kilobytes(r.geometry + r.texture)
           << " | " << (r.rms >= 0 ? fixed(100 * r.rms, 4) + "%" : "") << " | " << (r.rms_worst >= 0 ? fixed(100 * r.rms_worst, 4) + "%" : "") << " | "
           << (r.p99 >= 0 ? fixed(100 * r.p99, 4) + "%" : "") << " | " << (r.psnr >= 0 ? fixed(r.psnr, 2) + " dB" : "") << " | " << fixed(r.geometry / f.fm_geometry(), 2)
           << "x | " << fixed((r.geometry + r.texture) / f.fm_total(), 2) << "x |\n";
  }
  report << "\nTargets (`../shared/design.md` §7):\n\n";
  for (const std::string& t : f.targets) report << "- " << t << "\n";
  report << "\n### Speed\n\n| stage | seconds | per frame |\n| --- | --- | --- |\n";
  for (const auto& [stage, seconds] : f.stage_seconds) report << "| " << stage << " | " << fixed(seconds, 2) << " | " << fixed(seconds / frames, 3) << " |\n";
  report << "\nEncode " << fixed(f.encode_seconds / frames, 2) << " s per frame (mapping to file); decode " << fixed(fm.main.evaluation.decode_ms, 1)
         << " ms per frame; peak memory of the bench " << fixed(peak_rss_mib(), 0) << " MiB.\n\n";
  return report.str();
}

json capture_json(const std::string& input, const fs::path& folder, const Plan& plan, const CaptureFigures& f) {
  const CapturedFrames& c = f.c;
  const FacemorphPoints& fm = f.fm;
  const TextureBaselines& texture = f.texture;
  json baselines = json::array();
  for (const FigureRow& r : f.rows) {
    const double total = r.geometry + r.texture;
    baselines.push_back({{"name", r.name}, {"setting", r.setting}, {"geometry_bytes", r.geometry}, {"texture_bytes", r.texture}, {"total_bytes", total},
                         {"rms_mean_relative", r.rms}, {"rms_worst_relative", r.rms_worst}, {"p99_worst_relative", r.p99}, {"texture_psnr_db", r.psnr},
                         {"geometry_ratio", r.geometry / f.fm_geometry()}, {"total_ratio", total / f.fm_total()}});
  }
  json budgets = json::array();
  for (size_t k = 0; k < fm.curve.size(); ++k) {
    budgets.push_back({{"budget", fm.curve[k].budget}, {"keyframes", fm.curve[k].keyframes.size()}, {"bytes", fm.curve[k].bytes},
                       {"geometry_bytes", fm.curve[k].geometry_bytes()}, {"held_out_rms_mean", summarise(fm.curve[k].evaluation).held_rms_mean},
                       {"held_out_texture_psnr_sample", fm.curve[k].held_psnr()}, {"xyz_geometry_bytes", fm.xyz_curve[k].geometry_bytes()},
                       {"xyz_held_out_rms_mean", summarise(fm.xyz_curve[k].evaluation).held_rms_mean}});
  }
  json draco_json = json::array();
  for (const DracoPoint& p : f.baselines.draco_curve) {
    draco_json.push_back({{"qp", p.qp}, {"bytes_per_frame", p.bytes / double(p.frames)}, {"rms_mean", mean(p.rms)}, {"p99_worst", worst(p.p99)}});
  }
  json jpeg_json = json::array(), h264_json = json::array();
  for (int q : plan.jpeg_quality) {
    const auto bytes = texture.jpeg_sample_bytes.find(q);
    jpeg_json.push_back({{"quality", q}, {"bytes_per_frame", (bytes == texture.jpeg_sample_bytes.end() ? 0 : bytes->second) / double(c.sample.size())},
                         {"psnr", mean_at(texture.jpeg_psnr, q)}});
  }
  for (size_t k = 0; k < texture.h264_bytes.size(); ++k) {
    h264_json.push_back({{"crf", plan.h264_crf[k]}, {"bytes", texture.h264_bytes[k]}, {"psnr", mean_at(texture.h264_psnr, plan.h264_crf[k])}});
  }
  json chunks = json::array();
  for (const auto& chunk : fm.main.info.chunks) chunks.push_back({{"type", chunk.type}, {"count", chunk.count}, {"bytes", chunk.stored_bytes}});
  return {{"input", input},
          {"capture", folder.string()},
          {"frames", c.count},
          {"fps", c.capture.fps},
          {"vertex_frames", c.vertex_frames},
          {"facemorph",
           {{"bytes", fm.main.bytes}, {"bytes_per_second", f.fm_total() / c.duration}, {"bits_per_vertex_frame", f.bits},
            {"bits_per_vertex_frame_geometry", 8 * f.fm_geometry() / double(c.vertex_frames)}, {"chunks", chunks}, {"keyframes", fm.main_keys},
            {"grid", fm.grid}, {"evaluation", evaluation_json(fm.main.evaluation)}, {"held_out_texture_psnr", f.target_psnr},
            {"keyframe_texture_psnr", fm.main.key_psnr()}, {"held_out_d1_psnr", d1_psnr(relative_rms(fm.main.evaluation, false))},
            {"keyframe_d1_psnr", d1_psnr(relative_rms(fm.main.evaluation, true))}}},
          {"baselines", baselines},
          {"ratios", {{"geometry_vs_draco", f.draco_ratio}, {"total_vs_draco_jpeg", f.jpeg_ratio}, {"total_vs_draco_h264", f.h264_ratio}}},
          {"curves", {{"keyframe_budgets", budgets}, {"draco_sample", draco_json}, {"jpeg_sample", jpeg_json}, {"h264", h264_json}}},
          {"speed", {{"stage_seconds", json(std::map<std::string, double>(f.stage_seconds.begin(), f.stage_seconds.end()))},
                     {"encode_seconds_per_frame", f.encode_seconds / c.count}, {"decode_ms_per_frame", fm.main.evaluation.decode_ms},
                     {"peak_memory_mib", peak_rss_mib()}}}};
}

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
  const double target_rms = summary.held_rms_mean, target_psnr = fm.main.held_psnr();
  const MatchedBaselines baselines = match_baselines(context.plan, captured, fm.shown, texture, target_rms, target_psnr, stage_seconds);
  CaptureFigures figures{captured, fm, texture, baselines, stage_seconds, summary, target_rms, target_psnr, {}, {}};
  // Mapping to file; a stage that did not run is listed with 0 s.
  for (const char* stage : {"mapping", "registration", "sampling", "grid", "selection", "keyframes", "field precision", "file"}) {
    figures.encode_seconds += stage_seconds[stage];
  }
  add_rows_and_targets(figures);
  print_figures(figures);
  const std::string pictures = options.report.empty() ? std::string() : write_report_pictures(options.report, context.plan, figures);
  context.markdown += markdown_report(input, *folder, context.plan, figures) + pictures;
  return capture_json(input, *folder, context.plan, figures);
}

}  // namespace

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
  app.add_flag("--residual-frames", options.residual_frames, "With --capture: encode with residual frames (fmenc --residual-frames, format 2.3)");
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
  if (!options.fmv.empty() && captures.size() != 1) throw Error(ErrorCode::kInvalidArgument, "--fmv needs exactly one --capture, the one it was made from");
  for (const std::string& c : captures) {
    std::error_code ec;
    if (c != "synth" && c != "medusa" && c != "ict" && !fs::exists(c, ec)) throw Error(ErrorCode::kIo, "capture '" + c + "' does not exist");
  }
  if (!options.against.empty() && !options.geometry_only) throw Error(ErrorCode::kInvalidArgument, "--against is for --geometry-only");
  if (options.geometry_only) {
    if (options.fmv.empty()) throw Error(ErrorCode::kInvalidArgument, "--geometry-only measures a given file: it needs --fmv");
    const json result = measure_geometry_only(options, captures.front());
    if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "capture-geometry"}, {"results", json::array({result})}});
    return 0;
  }
  require_program("draco_encoder", "draco");
  require_program("draco_decoder", "draco");
  require_program("ffmpeg", "ffmpeg");
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each capture's lines as they come, also into a log file
  std::signal(SIGPIPE, SIG_IGN);  // an ffmpeg that dies is reported by its pipe, not by killing the bench
  const Plan plan = make_plan(options.quick);
  const ScratchFolder scratch("fmbench-capture");
  Context context{options, plan, scratch.path, {}};
  context.markdown = "# facemorph rate against Draco, JPEG and H.264\n\nMade by `fmbench --capture" + std::string(options.quick ? " --quick" : "") +
                     "`. Geometry error: symmetric point-to-surface distance between each captured frame and its decode at the "
                     "frame's own time, relative to the frame's bounding-box diagonal; D1 PSNR takes the diagonal as peak. Texture PSNR: "
                     "RGB on the registered disk, each frame's texture carried there through its own conformal map. Ratios are baseline "
                     "bytes over facemorph's (above 1: facemorph is smaller).\n\n";
  json results = json::array();
  const auto start = std::chrono::steady_clock::now();
  for (const std::string& c : captures) results.push_back(measure_capture(context, c));
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
