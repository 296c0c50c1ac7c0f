// fmdec: plays a .fmv file back. One time (--t) to a mesh with its texture and, on request, a
// shaded picture; a range of times (--fps, --from, --to) to a folder of meshes, to nothing (--null,
// for timing), or to a video of previews; or each keyframe's stored fields as EXR (--extract-fields).
//
// Every frame is decoded through the player API (facemorph.h), the path every player takes: the
// reference decoder exercises it. The API's double-precision arrays and hole levels (1.3) give
// the surface at the decoder's own precision, so the meshes and clips are written from the numbers
// the decoder computed (spec/api.md §9). --extract-fields has no player's path (a player never sees
// the stored fields): it reads the file whole through the container's reader.
#include "facemorph.h"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/meshkit/gltf/gltf.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "tools/field_export.hpp"
#include "tools/player_options.hpp"
#include "tools/tool_support.hpp"
#include "tools/video_file.hpp"

#include "format/file_io.hpp"

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <optional>

namespace {

using namespace facemorph;
namespace fs = std::filesystem;

// fmdec's command line as given.
struct Arguments {
  std::string input, extract;
  std::optional<double> t, from, to;
  double fps = 0;
  std::string mesh_out, preview, out_dir;
  std::string format = "obj";  // --out-dir's meshes: obj or ply
  bool null = false;
  double yaw = kPreviewYawDegrees;
  bool keep_holes = false, clamp = false, quiet = false, no_texture = false, glb_float = false, glb_flat = false;
  int preview_size = 800;
  double tolerance = FM_DEFAULT_TOLERANCE;
  DecoderLimits limits;
  std::string max_memory;
};

void declare_options(CLI::App& app, Arguments& a) {
  app.add_option("input", a.input, "The .fmv file")->required();
  app.add_option("--t", a.t, "The time to decode, in seconds from the first frame (past the ends: extrapolated within the sane range)");
  app.add_option("-o,--output", a.mesh_out,
                 "Mesh of the frame: FRAME.obj (+ FRAME.mtl, FRAME.png) or FRAME.ply; for a range, CLIP.glb (glTF 2.0)");
  app.add_option("--preview", a.preview, "A shaded, textured picture (.png) of the frame, or a video (.mp4) of a range");
  app.add_option("--preview-size", a.preview_size, "Preview pixels per side")->capture_default_str();
  app.add_option("--yaw", a.yaw, "Preview: degrees the face is turned")->capture_default_str();
  app.add_option("--fps", a.fps, "A range of frames at this rate (with --from, --to)");
  app.add_option("--from", a.from, "First time of the range (default: the first frame)");
  app.add_option("--to", a.to, "Last time of the range (default: the last frame)");
  app.add_option("--out-dir", a.out_dir, "A range: one mesh per frame in this folder (frame_00000.obj, ...)");
  app.add_option("--format", a.format, "Mesh format in --out-dir: obj or ply")->capture_default_str();
  app.add_flag("--null", a.null, "Decode and write nothing (timing)");
  app.add_option("--extract-fields", a.extract, "Write each keyframe's fields (EXR), boundary (CSV) and texture (PNG) into this folder");
  app.add_flag("--keep-holes-filled", a.keep_holes, "Show eyes and mouth as the encoder's fill instead of cutting them out");
  app.add_flag("--clamp", a.clamp, "Clamp times past the sane extrapolation range to it instead of failing");
  app.add_flag("--no-texture", a.no_texture, "Do not blend or write the texture");
  app.add_flag("--glb-float", a.glb_float,
               "A glTF clip in plain floats, without KHR_mesh_quantization and EXT_meshopt_compression (for viewers that lack them)");
  app.add_flag("--glb-flat", a.glb_flat,
               "A glTF clip without normals: viewers shade each triangle flat; the sample's compact clip is 37% smaller");
  app.add_option("--tolerance", a.tolerance,
                 "Stop the reconstruction when a step moves no node more than this fraction of the rim's diameter")
      ->capture_default_str();
  app.add_flag("-q,--quiet", a.quiet, "No progress display or summary");
  tools::add_limit_options(app, a.limits, a.max_memory);
}

using tools::check_player;

// A frame as fmdec writes it: the mesh at the decoder's precision (one UV per vertex), its texture
// (empty when not asked for or when the file has none) and G's hole levels (when asked for).
struct PlayedFrame {
  double time = 0;
  TriangleMesh mesh;
  Image texture;
  std::vector<double> hole_level;
  int iterations = 0;
  bool fell_back = false;
};

// An opened file and a decoder on it, through the C API, with buffers for the file's largest frame.
class Player {
 public:
  Player(const std::string& path, const DecoderLimits& limits) : file_(path, limits), info_(file_.info()) {
    fm_decoder* decoder = nullptr;
    check_player(fm_decoder_create(file_.get(), &decoder));
    decoder_.reset(decoder);
  }

  const fm_info& info() const { return info_; }
  std::vector<double> keyframe_times() const { return file_.keyframe_times(); }
  void set_tolerance(double tolerance) { check_player(fm_decoder_set_tolerance(decoder_.get(), tolerance)); }

  // The frame at t (flags: FM_DECODE_*), with its texture when `texture`, and G's hole levels when
  // `levels` and the file has holes. Without `keep` only its time and the solver's figures come
  // back: the player API decodes into this object's buffers as before, and the copy into a mesh and
  // an RGB image, which is fmdec's own (a fifth of a textured frame's time at N = 129), is not made:
  // --null times what a player pays.
  PlayedFrame decode(double t, uint32_t flags, bool texture, bool levels, bool keep = true) {
    const size_t vertices = info_.max_vertex_count, triangles = info_.max_triangle_count,
                 texels = size_t{info_.texture_size} * info_.texture_size;
    positions_.resize(3 * vertices);
    uvs_.resize(2 * vertices);
    indices_.resize(3 * triangles);
    fm_frame frame;
    fm_frame_init(&frame);
    frame.positions_f64 = positions_.data();
    frame.positions_f64_bytes = positions_.size() * sizeof(double);
    frame.uvs_f64 = uvs_.data();
    frame.uvs_f64_bytes = uvs_.size() * sizeof(double);
    frame.indices = indices_.data();
    frame.indices_bytes = indices_.size() * sizeof(uint32_t);
    if (texture && texels > 0) {
      rgba_.resize(4 * texels);
      frame.texture = rgba_.data();
      frame.texture_bytes = rgba_.size();
    }
    if (levels && info_.has_holes) {
      levels_.resize(info_.grid_vertex_count);
      frame.hole_levels = levels_.data();
      frame.hole_levels_bytes = levels_.size() * sizeof(double);
    }
    check_player(fm_decoder_decode(decoder_.get(), t, flags, &frame));
    if (!keep) return {frame.time, {}, {}, {}, static_cast<int>(frame.iterations), frame.fell_back != 0};
    return played(frame);
  }

 private:
  PlayedFrame played(const fm_frame& frame) const {
    PlayedFrame out;
    out.time = frame.time;
    out.iterations = static_cast<int>(frame.iterations);
    out.fell_back = frame.fell_back != 0;
    TriangleMesh& mesh = out.mesh;
    mesh.positions.resize(frame.vertex_count);
    mesh.uvs.resize(frame.vertex_count);
    for (size_t v = 0; v < frame.vertex_count; ++v) {
      mesh.positions[v] = Vec3(positions_[3 * v], positions_[3 * v + 1], positions_[3 * v + 2]);
      mesh.uvs[v] = Vec2(uvs_[2 * v], uvs_[2 * v + 1]);
    }
    mesh.faces.resize(frame.triangle_count);
    for (size_t f = 0; f < frame.triangle_count; ++f) {
      for (size_t k = 0; k < 3; ++k) mesh.faces[f][k] = static_cast<int32_t>(indices_[3 * f + k]);
    }
    mesh.uv_faces = mesh.faces;  // one UV per vertex
    if (frame.texture != nullptr) {
      const int m = static_cast<int>(frame.texture_size);
      out.texture = Image(m, m, 3);
      for (size_t p = 0; p < size_t{frame.texture_size} * frame.texture_size; ++p) {
        for (size_t c = 0; c < 3; ++c) out.texture.pixels[3 * p + c] = rgba_[4 * p + c];
      }
    }
    if (frame.hole_levels != nullptr) out.hole_level.assign(levels_.begin(), levels_.begin() + frame.hole_level_count);
    return out;
  }

  tools::PlayerFile file_;
  std::unique_ptr<fm_decoder, decltype(&fm_decoder_destroy)> decoder_{nullptr, fm_decoder_destroy};
  fm_info info_{};
  std::vector<double> positions_, uvs_, levels_;
  std::vector<uint32_t> indices_;
  std::vector<uint8_t> rgba_;
};

// The picture a person looks at: the textured face (or a grey one), turned a little, shaded smoothly
// by the decoder's vertex normals (the player API's fm_frame.normals), as the web page draws it.
Image preview_picture(const PlayedFrame& frame, double yaw, int size) {
  RenderOptions options;
  options.width = options.height = size;
  options.yaw_degrees = yaw;
  const SurfaceShader shader = frame.texture.empty() ? constant_shader({200, 200, 200}) : texture_shader(frame.mesh, frame.texture);
  return render(frame.mesh, shader, options, shading_normals(frame.mesh));
}

// Writes the frame's mesh; for OBJ also FRAME.mtl and the texture FRAME.png beside it.
void write_frame(const PlayedFrame& frame, const fs::path& path) {
  TriangleMesh mesh = frame.mesh;
  if (!frame.texture.empty()) {
    fs::path texture = path;
    texture.replace_extension(".png");
    write_png(texture, frame.texture);
    mesh.texture = texture;
  }
  write_mesh(path, mesh);
}

void check_mesh_path(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".glb") throw Error(ErrorCode::kInvalidArgument, path.string() + ": a glTF clip is a range: give --fps (and --from, --to)");
  if (ext != ".obj" && ext != ".ply") throw Error(ErrorCode::kInvalidArgument, path.string() + ": the mesh must be .obj or .ply");
}

// Collects a range of frames as a glTF clip: G's mesh in every frame (glTF cannot change triangles
// over time: the frames are decoded with the holes filled, so each is G's nodes and triangles) less
// the triangles inside a hole in every frame (faces_outside_holes). glTF has no animated textures:
// the clip switches between the textures of the frames nearest each keyframe the range spans (a
// blink's closed eyes show while that keyframe is nearest), each from midway to the one before; a
// range within one keyframe's reach carries the middle frame's texture alone.
class ClipCollector {
 public:
  ClipCollector(bool compact, bool normals, std::vector<double> keyframe_times) : keyframe_times_(std::move(keyframe_times)) {
    clip_.compact = compact;
    clip_.normals = normals;
  }
  void add(const PlayedFrame& frame, bool middle) {
    if (clip_.times.empty()) {
      // G's triangles and UV = (w + 1) / 2 of its nodes, the same in every frame of fixed topology.
      clip_.faces = frame.mesh.faces;
      clip_.uvs = frame.mesh.uvs;
    }
    clip_.times.push_back(frame.time);
    clip_.positions.push_back(frame.mesh.positions);
    if (!frame.hole_level.empty()) levels_.push_back(frame.hole_level);
    if (middle) clip_.texture = frame.texture;
    if (frame.texture.empty() || keyframe_times_.empty()) return;
    // The keyframe nearest this frame; the frame nearest that keyframe keeps its texture.
    const auto after = std::lower_bound(keyframe_times_.begin(), keyframe_times_.end(), frame.time);
    size_t k = static_cast<size_t>(after - keyframe_times_.begin());
    if (k == keyframe_times_.size() || (k > 0 && frame.time - keyframe_times_[k - 1] < keyframe_times_[k] - frame.time)) --k;
    const double distance = std::abs(frame.time - keyframe_times_[k]);
    auto [it, fresh] = nearest_.try_emplace(k, Nearest{frame.time, distance, frame.texture});
    if (!fresh && distance < it->second.distance) it->second = Nearest{frame.time, distance, frame.texture};
  }
  void write(const fs::path& path) {
    if (!levels_.empty()) clip_.faces = faces_outside_holes(clip_.faces, levels_);
    if (nearest_.size() > 1) {
      double previous = clip_.times.front();
      for (auto& [k, n] : nearest_) {
        const double start = clip_.switched_textures.empty() ? clip_.times.front() : 0.5 * (previous + n.time);
        clip_.switched_textures.push_back({start, std::move(n.texture)});
        previous = n.time;
      }
      clip_.texture = {};
    }
    format::write_file_atomically(path, encode_glb(clip_));
  }
  size_t textures() const { return clip_.switched_textures.empty() ? !clip_.texture.empty() : clip_.switched_textures.size(); }

 private:
  struct Nearest {
    double time = 0, distance = 0;
    Image texture;
  };
  GltfClip clip_;
  std::vector<std::vector<double>> levels_;
  std::vector<double> keyframe_times_;
  std::map<size_t, Nearest> nearest_;  // by keyframe, in time order
};

void print_frame(const PlayedFrame& frame, const fs::path& where) {
  std::printf("fmdec: t = %.4f s -> %s: %d vertices, %d faces, %d iterations%s\n", frame.time, where.string().c_str(),
              frame.mesh.vertex_count(), frame.mesh.face_count(), frame.iterations,
              frame.fell_back ? " (did not converge: shows the keyframes' blended surfaces)" : "");
}

// --t: one frame to a mesh and/or a picture.
int decode_one(const Arguments& a, Player& player, uint32_t flags) {
  if (a.fps > 0 || a.from || a.to || !a.out_dir.empty() || a.null) {
    throw Error(ErrorCode::kInvalidArgument, "--t decodes one frame; --fps/--from/--to/--out-dir/--null decode a range");
  }
  if (a.mesh_out.empty() && a.preview.empty())
    throw Error(ErrorCode::kInvalidArgument, "--t needs -o FRAME.obj and/or --preview FRAME.png");
  if (!a.mesh_out.empty()) check_mesh_path(a.mesh_out);
  if (!a.mesh_out.empty() && !a.preview.empty() && fs::path(a.mesh_out).extension() == ".obj" &&
      fs::weakly_canonical(fs::path(a.mesh_out).replace_extension(".png")) == fs::weakly_canonical(a.preview)) {
    throw Error(ErrorCode::kInvalidArgument,
                a.preview + " is where the mesh's texture goes; give the preview another name (e.g. FRAME_view.png)");
  }
  if (!a.preview.empty() && fs::path(a.preview).extension() != ".png")
    throw Error(ErrorCode::kInvalidArgument, a.preview + ": a frame's preview is a .png");
  const PlayedFrame frame = player.decode(*a.t, flags, !a.no_texture, false);
  if (!a.mesh_out.empty()) write_frame(frame, a.mesh_out);
  if (!a.preview.empty()) write_png(a.preview, preview_picture(frame, a.yaw, a.preview_size));
  if (!a.quiet) {
    print_frame(frame, a.mesh_out.empty() ? fs::path(a.preview) : fs::path(a.mesh_out));
    if (!a.mesh_out.empty() && !frame.texture.empty())
      std::printf("  texture %s\n", fs::path(a.mesh_out).replace_extension(".png").string().c_str());
    if (!a.preview.empty()) std::printf("  preview %s\n", a.preview.c_str());
  }
  return 0;
}

// What a range of frames went to: a clip, a video, a folder of meshes (or nothing, --null).
struct RangeOutputs {
  std::optional<ClipCollector> clip;
  std::optional<tools::VideoFile> video;
};

// The range's outputs checked, and the clip opened into `out`, with the flag its frames need (holes filled).
void open_range_outputs(const Arguments& a, const Player& player, uint32_t& flags, RangeOutputs& out) {
  if (a.fps <= 0)
    throw Error(ErrorCode::kInvalidArgument,
                "give --t T for one frame, or --fps F (with --out-dir, --null or --preview SEQ.mp4) for a range");
  const bool glb = fs::path(a.mesh_out).extension() == ".glb";
  if (!a.mesh_out.empty() && !glb)
    throw Error(ErrorCode::kInvalidArgument, "a range goes to -o CLIP.glb, --out-dir DIR, --null or --preview SEQ.mp4, not to one mesh");
  if (a.out_dir.empty() && !a.null && a.preview.empty() && !glb) {
    throw Error(ErrorCode::kInvalidArgument, "a range needs -o CLIP.glb, --out-dir DIR, --null or --preview SEQ.mp4");
  }
  if (glb) {
    out.clip.emplace(!a.glb_float, !a.glb_flat, player.keyframe_times());
    flags |= FM_DECODE_KEEP_HOLES_FILLED;  // the clip drops the triangles inside a hole throughout instead
  }
  if (a.format != "obj" && a.format != "ply") throw Error(ErrorCode::kInvalidArgument, "--format must be obj or ply");
}

// --fps: a range of frames.
int decode_range(const Arguments& a, Player& player, uint32_t flags, double seconds_read) {
  RangeOutputs out;
  open_range_outputs(a, player, flags, out);
  const double begin = a.from.value_or(player.info().first_time), end = a.to.value_or(player.info().last_time);
  if (!(end >= begin)) throw Error(ErrorCode::kInvalidArgument, "--to is before --from");
  // A thousandth of a frame of slack: a rounded rate (23.976 for 24000/1001) must still reach the
  // last frame.
  const int count = tools::frame_count(begin, end, a.fps, 1e-3);
  if (!a.preview.empty()) {
    if (fs::path(a.preview).extension() != ".mp4")
      throw Error(ErrorCode::kInvalidArgument, a.preview + ": a range's preview is an .mp4 video");
    out.video.emplace(fs::path(a.preview).replace_extension(".partial.mp4"), a.preview_size, a.fps);
  }
  if (!a.out_dir.empty()) {
    std::error_code ec;
    fs::create_directories(a.out_dir, ec);
    if (ec) throw Error(ErrorCode::kIo, a.out_dir + ": " + ec.message());
  }
  const bool keep = out.clip || out.video || !a.out_dir.empty();  // else --null: nothing is written
  tools::Progress progress("fmdec", a.quiet);
  const auto decode_start = std::chrono::steady_clock::now();
  double worst_ms = 0;
  int fell_back = 0;
  long iterations = 0;
  for (int i = 0; i < count; ++i) {
    const double time = begin + i / a.fps;
    const auto frame_start = std::chrono::steady_clock::now();
    const PlayedFrame frame = player.decode(time, flags, !a.no_texture, out.clip.has_value(), keep);
    worst_ms = std::max(worst_ms, 1000 * tools::seconds_since(frame_start));
    fell_back += frame.fell_back;
    iterations += frame.iterations;
    if (out.clip) out.clip->add(frame, i == count / 2);
    if (!a.out_dir.empty()) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%05d.%s", i, a.format.c_str());
      write_frame(frame, fs::path(a.out_dir) / name);
    }
    if (out.video) out.video->write(preview_picture(frame, a.yaw, a.preview_size));
    progress.update(i + 1, count);
  }
  progress.finish();
  const double seconds = tools::seconds_since(decode_start);
  if (out.clip) out.clip->write(a.mesh_out);
  if (out.video) {
    out.video->close();
    format::commit_temporary(fs::path(a.preview).replace_extension(".partial.mp4"), a.preview);
  }
  if (a.quiet) return 0;
  std::printf(
      "fmdec: %d frames, t = %.3f .. %.3f s at %.3f fps: %.2f ms per frame (worst %.2f ms, %.1f iterations), file read in %.0f ms%s\n",
      count, begin, begin + (count - 1) / a.fps, a.fps, 1000 * seconds / count, worst_ms, static_cast<double>(iterations) / count,
      1000 * seconds_read, fell_back ? (", " + std::to_string(fell_back) + " frames did not converge").c_str() : "");
  if (!a.out_dir.empty()) std::printf("  meshes in %s\n", a.out_dir.c_str());
  if (out.video) std::printf("  video %s\n", a.preview.c_str());
  if (out.clip) {
    std::printf("  glTF clip %s (%llu bytes, %zu texture%s)\n", a.mesh_out.c_str(),
                static_cast<unsigned long long>(fs::file_size(a.mesh_out)), out.clip->textures(),
                out.clip->textures() == 1 ? "" : "s, switched at the keyframes");
  }
  return 0;
}

int run(const Arguments& a) {
  const DecoderLimits limits = tools::parsed_limits(a.limits, a.max_memory);
  if (!std::isfinite(a.fps) || a.fps < 0) throw Error(ErrorCode::kInvalidArgument, "--fps must be a finite positive number");
  const auto start = std::chrono::steady_clock::now();
  if (!a.extract.empty()) {
    // Every keyframe's fields at once: the file decoded whole, within the same limits.
    const Sequence whole = read_sequence_file(a.input, nullptr, limits);
    const auto files = tools::export_keyframe_fields(whole, a.extract);
    if (!a.quiet) std::printf("fmdec: %zu files for %zu keyframes in %s\n", files.size(), whole.keyframes.size(), a.extract.c_str());
    if (!a.t && a.fps <= 0) return 0;
  }
  // Keyframes decoded as the frames need them, within the memory budget.
  Player player(a.input, limits);
  const double seconds_read = tools::seconds_since(start);
  if (!(a.tolerance > 0) || a.tolerance > 0.01) throw Error(ErrorCode::kInvalidArgument, "--tolerance must be in (0, 0.01]");
  player.set_tolerance(a.tolerance);
  const uint32_t flags = (a.keep_holes ? FM_DECODE_KEEP_HOLES_FILLED : 0u) | (a.clamp ? FM_DECODE_CLAMP : 0u);
  if (a.t) return decode_one(a, player, flags);
  return decode_range(a, player, flags, seconds_read);
}

}  // namespace

int main(int argc, char** argv) {
  tools::reuse_freed_memory();
  CLI::App app("Decode a facemorph file (.fmv): a frame at a time t, a range of frames, or the stored fields.", "fmdec");
  Arguments a;
  declare_options(app, a);
  return tools::guarded_main(app, argc, argv, [&] { return run(a); });
}
