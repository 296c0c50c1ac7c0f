// fmplay: the example player. Decodes a .fmv file through the C API (facemorph.h) exactly as a
// player embedding the library would — open, ask the sizes, decode every frame of a range into
// buffers it owns — and reports the decode rate (mean and worst frame), the reconstruction's
// iterations and the peak memory. With --video it also renders the frames with the decoder's
// software renderer and writes them as an mp4 (tools/video_file.hpp).
#include "facemorph.h"

#include "codec/meshkit/render/render.hpp"
#include "tools/player_options.hpp"
#include "tools/tool_support.hpp"
#include "tools/video_file.hpp"

#include <CLI/CLI.hpp>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;

// A failed C call: the status and the library's message, printed at the tool's boundary. The
// message names the file and the reason, as fmdec's (tools::player_error_message).
struct Failure {
  fm_status status;
  std::string message;
};

void check(fm_status status) {
  if (status != FM_OK) throw Failure{status, facemorph::tools::player_error_message()};
}

double peak_memory_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

// The buffers a player keeps for the file's largest frame, allocated once.
struct Buffers {
  std::vector<float> positions, normals, uvs;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> texture;

  explicit Buffers(const fm_info& info)
      : positions(3 * size_t{info.max_vertex_count}),
        normals(3 * size_t{info.max_vertex_count}),
        uvs(2 * size_t{info.max_vertex_count}),
        indices(3 * size_t{info.max_triangle_count}),
        texture(4 * size_t{info.texture_size} * info.texture_size) {}

  fm_frame frame() {
    fm_frame f;
    fm_frame_init(&f);
    f.positions = positions.data();
    f.positions_bytes = positions.size() * sizeof(float);
    f.normals = normals.data();
    f.normals_bytes = normals.size() * sizeof(float);
    f.uvs = uvs.data();
    f.uvs_bytes = uvs.size() * sizeof(float);
    f.indices = indices.data();
    f.indices_bytes = indices.size() * sizeof(uint32_t);
    f.texture = texture.empty() ? nullptr : texture.data();
    f.texture_bytes = texture.size();
    return f;
  }
};

// The frame as the renderer takes it (the one use of the C++ headers: the software renderer).
facemorph::Image render_frame(const Buffers& b, const fm_frame& frame, int size) {
  facemorph::TriangleMesh mesh;
  for (uint32_t v = 0; v < frame.vertex_count; ++v) {
    mesh.positions.emplace_back(b.positions[3 * v], b.positions[3 * v + 1], b.positions[3 * v + 2]);
    mesh.uvs.emplace_back(b.uvs[2 * v], b.uvs[2 * v + 1]);
  }
  for (uint32_t f = 0; f < frame.triangle_count; ++f) {
    mesh.faces.push_back(
        {static_cast<int32_t>(b.indices[3 * f]), static_cast<int32_t>(b.indices[3 * f + 1]), static_cast<int32_t>(b.indices[3 * f + 2])});
  }
  mesh.uv_faces = mesh.faces;
  // Shaded smoothly by the normals the C API decoded with the frame, as fmdec --preview and the web
  // page shade it (the video was flat-shaded until the previews turned smooth).
  std::vector<facemorph::Vec3> normals;
  normals.reserve(frame.vertex_count);
  for (uint32_t v = 0; v < frame.vertex_count; ++v) normals.emplace_back(b.normals[3 * v], b.normals[3 * v + 1], b.normals[3 * v + 2]);
  facemorph::RenderOptions options;
  options.width = options.height = size;
  options.yaw_degrees = facemorph::kPreviewYawDegrees;
  if (frame.texture_size > 0) {
    facemorph::Image texture(static_cast<int>(frame.texture_size), static_cast<int>(frame.texture_size), 3);
    for (size_t p = 0; p < texture.pixels.size() / 3; ++p) std::copy_n(&b.texture[4 * p], 3, &texture.pixels[3 * p]);
    return facemorph::render(mesh, facemorph::texture_shader(mesh, texture), options, normals);
  }
  return facemorph::render(mesh, facemorph::constant_shader({200, 200, 200}), options, normals);
}

// --threads N: N players in one process, each its own decoder on the shared file and its own
// thread, each playing the range once; wall-clock frames per second over all of them, against one.
void play_in_parallel(fm_file* file, const fm_info& info, double begin, int count, double fps, uint32_t flags, int threads) {
  std::vector<std::thread> players;
  std::vector<fm_status> statuses(static_cast<size_t>(threads), FM_OK);
  std::vector<std::string> messages(static_cast<size_t>(threads));
  const auto start = std::chrono::steady_clock::now();
  for (int p = 0; p < threads; ++p) {
    players.emplace_back([&, p] {
      fm_decoder* decoder = nullptr;
      fm_status status = fm_decoder_create(file, &decoder);
      Buffers buffers(info);
      for (int i = 0; i < count && status == FM_OK; ++i) {
        fm_frame frame = buffers.frame();
        status = fm_decoder_decode(decoder, begin + i / fps, flags, &frame);
      }
      if (status != FM_OK) messages[static_cast<size_t>(p)] = facemorph::tools::player_error_message();
      statuses[static_cast<size_t>(p)] = status;
      fm_decoder_destroy(decoder);
    });
  }
  for (std::thread& t : players) t.join();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (int p = 0; p < threads; ++p) {
    if (statuses[static_cast<size_t>(p)] != FM_OK) throw Failure{statuses[static_cast<size_t>(p)], messages[static_cast<size_t>(p)]};
  }
  const double frames = static_cast<double>(count) * threads;
  std::printf(
      "fmplay: %d players on %d threads, one file: %.0f frames in %.2f s wall (decoders created included): %.1f fps in all, "
      "%.1f fps a player; peak memory %.1f MiB\n",
      threads, threads, frames, seconds, frames / seconds, count / seconds, peak_memory_mib());
}

// fmplay's command line as given.
struct Arguments {
  std::string input, video;
  std::optional<double> from, to;
  double fps = 60;
  int loops = 1, video_size = 480, threads = 1;
  bool clamp = false, quiet = false;
  facemorph::DecoderLimits limits;
  std::string max_memory;
};

void declare_options(CLI::App& app, Arguments& a) {
  app.add_option("input", a.input, "The .fmv file")->required();
  app.add_option("--from", a.from, "First time, seconds (default: the capture's first frame)");
  app.add_option("--to", a.to, "Last time, seconds (default: the capture's last frame)");
  app.add_option("--fps", a.fps, "Frames per second of playback: the time step, and the rate to keep up with")->capture_default_str();
  app.add_option("--loop", a.loops, "Play the range this many times (the decoder's state carries over)")->capture_default_str();
  app.add_option("--video", a.video, "Also render the first pass to this .mp4 (not timed)");
  app.add_option("--video-size", a.video_size, "Video pixels per side")->capture_default_str();
  app.add_option("--threads", a.threads,
                 "Afterwards, play the range once more with this many players in parallel (own decoder and thread each, one shared file) "
                 "and report the wall-clock rate: how decoding scales")
      ->capture_default_str();
  app.add_flag("--clamp", a.clamp, "Clamp times outside the file's range instead of failing");
  app.add_flag("--quiet", a.quiet, "Print only the summary line");
  facemorph::tools::add_limit_options(app, a.limits, a.max_memory);
}

void check_arguments(const Arguments& a) {
  if (!(a.fps > 0) || !std::isfinite(a.fps)) throw Failure{FM_ERROR_INVALID_ARGUMENT, "--fps must be positive"};
  if (a.loops < 1) throw Failure{FM_ERROR_INVALID_ARGUMENT, "--loop must be at least 1"};
  if (a.threads < 1 || a.threads > 256) throw Failure{FM_ERROR_INVALID_ARGUMENT, "--threads must be 1 .. 256"};
  if (a.video_size < 16 || a.video_size > 8192) throw Failure{FM_ERROR_INVALID_ARGUMENT, "--video-size must be 16 .. 8192"};
  if (!a.video.empty() && fs::path(a.video).extension() != ".mp4")
    throw Failure{FM_ERROR_INVALID_ARGUMENT, a.video + ": the video must be .mp4"};
}

// The file opened and a decoder on it, as a player starts, each step timed; closed with the Player.
struct Player {
  std::unique_ptr<fm_file, decltype(&fm_file_close)> file{nullptr, fm_file_close};
  std::unique_ptr<fm_decoder, decltype(&fm_decoder_destroy)> decoder{nullptr, fm_decoder_destroy};
  fm_info info{};
  double open_ms = 0, create_ms = 0;

  explicit Player(const Arguments& a) {
    const auto open_start = std::chrono::steady_clock::now();
    fm_decoder_options options;
    try {
      options = facemorph::tools::player_options(facemorph::tools::parsed_limits(a.limits, a.max_memory));
    } catch (const facemorph::Error& e) {
      throw Failure{FM_ERROR_INVALID_ARGUMENT, e.what()};
    }
    fm_file* opened = nullptr;
    check(fm_file_open_with_options(a.input.c_str(), &options, &opened));
    file.reset(opened);
    fm_info_init(&info);
    check(fm_file_get_info(file.get(), &info));
    const auto create_start = std::chrono::steady_clock::now();
    fm_decoder* created_decoder = nullptr;
    check(fm_decoder_create(file.get(), &created_decoder));  // builds G and factors its Laplacian
    decoder.reset(created_decoder);
    const auto created = std::chrono::steady_clock::now();
    open_ms = std::chrono::duration<double, std::milli>(create_start - open_start).count();
    create_ms = std::chrono::duration<double, std::milli>(created - create_start).count();
  }
};

// The times played: --from .. --to at --fps, checked against what the file serves.
struct Range {
  double begin = 0;
  int count = 0;
};

Range playback_range(const Arguments& a, const fm_info& info) {
  Range range;
  range.begin = a.from.value_or(info.first_time);
  const double end = a.to.value_or(info.last_time);
  if (!(end >= range.begin)) throw Failure{FM_ERROR_INVALID_ARGUMENT, "--to is before --from"};
  if (!a.clamp && (range.begin < info.range_begin || end > info.range_end)) {
    char text[200];
    std::snprintf(text, sizeof text, "%s: t = %.4g .. %.4g s is outside the range the file serves, [%.4g, %.4g] s (--clamp clamps)",
                  a.input.c_str(), range.begin, end, info.range_begin, info.range_end);
    throw Failure{FM_ERROR_OUT_OF_RANGE, text};
  }
  try {
    range.count = facemorph::tools::frame_count(range.begin, end, a.fps, 1e-9);
  } catch (const facemorph::Error& e) {
    throw Failure{FM_ERROR_INVALID_ARGUMENT, e.what()};
  }
  return range;
}

// What --loop passes over the range measured.
struct Playback {
  double total_ms = 0, worst_ms = 0, worst_t = 0, first_ms = 0;
  long iterations = 0;
  int fell_back = 0, slow = 0;
};

// Plays the range --loop times, every frame into the same buffers; the first pass also to `writer`.
Playback play(const Arguments& a, const Player& player, const Range& range, uint32_t flags, facemorph::tools::VideoFile* writer) {
  Buffers buffers(player.info);
  Playback p;
  p.worst_t = range.begin;
  const double budget_ms = 1000 / a.fps;
  for (int loop = 0; loop < a.loops; ++loop) {
    for (int i = 0; i < range.count; ++i) {
      const double t = range.begin + i / a.fps;
      fm_frame frame = buffers.frame();
      const auto start = std::chrono::steady_clock::now();
      check(fm_decoder_decode(player.decoder.get(), t, flags, &frame));
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      p.total_ms += ms;
      if (loop == 0 && i == 0) p.first_ms = ms;  // cold: the keyframes' own surfaces are decoded on first use
      if (ms > p.worst_ms) p.worst_ms = ms, p.worst_t = t;
      p.slow += ms > budget_ms;
      p.iterations += frame.iterations;
      p.fell_back += static_cast<int>(frame.fell_back);
      if (writer && loop == 0) writer->write(render_frame(buffers, frame, a.video_size));
    }
  }
  return p;
}

void print_playback(const Arguments& a, const Player& player, const Range& range, const Playback& p) {
  const int frames = range.count * a.loops;
  const double mean_ms = p.total_ms / frames;
  std::printf(
      "fmplay: %d frames (%d x %d, t = %.3f .. %.3f s): %.1f fps mean (%.2f ms), worst frame %.2f ms (%.1f fps) at t = %.3f s, "
      "%.1f iterations a frame, peak memory %.1f MiB, file opened in %.0f ms, decoder created in %.0f ms\n",
      frames, a.loops, range.count, range.begin, range.begin + (range.count - 1) / a.fps, 1000 / mean_ms, mean_ms, p.worst_ms,
      1000 / p.worst_ms, p.worst_t, static_cast<double>(p.iterations) / frames, peak_memory_mib(), player.open_ms, player.create_ms);
  if (!a.quiet) {
    std::printf("  first frame (cold) %.2f ms; real time at %.3f fps (%.2f ms a frame): %s (%d of %d frames slower)\n", p.first_ms, a.fps,
                1000 / a.fps, p.slow == 0 ? "yes" : "no", p.slow, frames);
    if (p.fell_back > 0) std::printf("  %d frames did not converge and show the keyframes' blended surfaces\n", p.fell_back);
  }
}

// The whole run; `partial` names the video while it is written (removed by main if the run fails).
void run(const Arguments& a, fs::path& partial) {
  check_arguments(a);
  const Player player(a);
  const fm_info& info = player.info;
  const Range range = playback_range(a, info);
  if (!a.quiet) {
    std::printf("fmplay: %s: N = %u, %u keyframes, %.3f s at %.3f fps, up to %u vertices and %u triangles%s, texture %ux%u\n",
                a.input.c_str(), info.grid_n, info.keyframe_count, info.duration, info.fps, info.max_vertex_count, info.max_triangle_count,
                info.has_holes ? " (holes: counts change per frame)" : "", info.texture_size, info.texture_size);
  }
  std::optional<facemorph::tools::VideoFile> writer;
  if (!a.video.empty()) {
    partial = fs::path(a.video).replace_extension(".partial.mp4");
    writer.emplace(partial, a.video_size, a.fps);
  }
  const uint32_t flags = a.clamp ? FM_DECODE_CLAMP : 0;
  print_playback(a, player, range, play(a, player, range, flags, writer ? &*writer : nullptr));
  if (writer) {
    writer->close();
    std::error_code ec;
    fs::rename(partial, a.video, ec);
    if (ec) throw Failure{FM_ERROR_IO, a.video + ": cannot write the video: " + ec.message()};
    partial.clear();
    if (!a.quiet) std::printf("  video %s (%d frames, %dx%d)\n", a.video.c_str(), range.count, a.video_size, a.video_size);
  }
  if (a.threads > 1) play_in_parallel(player.file.get(), info, range.begin, range.count, a.fps, flags, a.threads);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Play a facemorph file (.fmv) through the C API as a player would, and report the decode rate and memory.", "fmplay");
  Arguments a;
  declare_options(app, a);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  fs::path partial;  // the video being written, under a temporary name until complete
  int status = 0;
  try {
    run(a, partial);
  } catch (const Failure& f) {
    std::fprintf(stderr, "fmplay: error (%s): %s\n", fm_status_name(f.status), f.message.c_str());
    status = 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fmplay: error: %s\n", e.what());
    status = 1;
  }
  if (!partial.empty()) {
    std::error_code ec;
    fs::remove(partial, ec);  // a failed run leaves no half video (and any earlier one untouched)
  }
  return status;
}
