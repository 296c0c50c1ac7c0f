// fmdec: plays a .fmv file back. One time (--t) to a mesh with its texture and, on request, a
// shaded picture; a range of times (--fps, --from, --to) to a folder of meshes, to nothing (--null,
// for timing), or to a video of previews; or each keyframe's stored fields as EXR (--extract-fields).
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/meshkit/gltf/gltf.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "tools/field_export.hpp"
#include "tools/tool_support.hpp"
#include "tools/video_file.hpp"

#include "format/file_io.hpp"

#include <chrono>
#include <cmath>
#include <map>
#include <optional>

namespace {

using namespace facemorph;
namespace fs = std::filesystem;

struct Outputs {
  fs::path mesh;     // -o: .obj (+ .mtl + .png) or .ply
  fs::path preview;  // a .png picture, or an .mp4 video for a range
  fs::path out_dir;  // a range: one mesh per frame
  std::string format = "obj";
  bool null = false;
  double yaw = kPreviewYawDegrees;
};

// The picture a person looks at: the textured face (or a grey one), turned a little, shaded smoothly
// by the decoder's vertex normals (the player API's fm_frame.normals), as the web page draws it.
Image preview_picture(const DecodedFrame& frame, double yaw, int size) {
  RenderOptions options;
  options.width = options.height = size;
  options.yaw_degrees = yaw;
  const SurfaceShader shader = frame.texture.empty() ? constant_shader({200, 200, 200}) : texture_shader(frame.mesh, frame.texture);
  return render(frame.mesh, shader, options, shading_normals(frame.mesh));
}

// Writes the frame's mesh; for OBJ also FRAME.mtl and the texture FRAME.png beside it.
void write_frame(const DecodedFrame& frame, const fs::path& path) {
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
// over time) less the triangles inside a hole in every frame (faces_outside_holes). glTF has no
// animated textures: the clip switches between the textures of the frames nearest each keyframe
// the range spans (a blink's closed eyes show while that keyframe is nearest), each from midway to
// the one before; a range within one keyframe's reach carries the middle frame's texture alone.
class ClipCollector {
 public:
  ClipCollector(const DiskGrid& grid, bool compact, bool normals, std::vector<double> keyframe_times)
      : keyframe_times_(std::move(keyframe_times)) {
    clip_.compact = compact;
    clip_.normals = normals;
    clip_.faces = grid.faces;
    for (const Vec2& w : grid.nodes) clip_.uvs.push_back(0.5 * (w + Vec2(1, 1)));
  }
  void add(const DecodedFrame& frame, bool middle) {
    clip_.times.push_back(frame.time);
    clip_.positions.push_back(frame.grid_positions);
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

void print_frame(const DecodedFrame& frame, const fs::path& where) {
  std::printf("fmdec: t = %.4f s -> %s: %d vertices, %d faces, %d iterations%s\n", frame.time, where.string().c_str(),
              frame.mesh.vertex_count(), frame.mesh.face_count(), frame.iterations,
              frame.fell_back ? " (did not converge: shows the keyframes' blended surfaces)" : "");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Decode a facemorph file (.fmv): a frame at a time t, a range of frames, or the stored fields.", "fmdec");
  std::string input, extract;
  std::optional<double> t, from, to;
  double fps = 0;
  Outputs out;
  std::string mesh_out, preview, out_dir;
  bool keep_holes = false, clamp = false, quiet = false, no_texture = false, glb_float = false, glb_flat = false;
  int preview_size = 800;
  double tolerance = ReconstructOptions{}.tolerance;
  app.add_option("input", input, "The .fmv file")->required();
  app.add_option("--t", t, "The time to decode, in seconds from the first frame (past the ends: extrapolated within the sane range)");
  app.add_option("-o,--output", mesh_out,
                 "Mesh of the frame: FRAME.obj (+ FRAME.mtl, FRAME.png) or FRAME.ply; for a range, CLIP.glb (glTF 2.0)");
  app.add_option("--preview", preview, "A shaded, textured picture (.png) of the frame, or a video (.mp4) of a range");
  app.add_option("--preview-size", preview_size, "Preview pixels per side")->capture_default_str();
  app.add_option("--yaw", out.yaw, "Preview: degrees the face is turned")->capture_default_str();
  app.add_option("--fps", fps, "A range of frames at this rate (with --from, --to)");
  app.add_option("--from", from, "First time of the range (default: the first frame)");
  app.add_option("--to", to, "Last time of the range (default: the last frame)");
  app.add_option("--out-dir", out_dir, "A range: one mesh per frame in this folder (frame_00000.obj, ...)");
  app.add_option("--format", out.format, "Mesh format in --out-dir: obj or ply")->capture_default_str();
  app.add_flag("--null", out.null, "Decode and write nothing (timing)");
  app.add_option("--extract-fields", extract, "Write each keyframe's fields (EXR), boundary (CSV) and texture (PNG) into this folder");
  app.add_flag("--keep-holes-filled", keep_holes, "Show eyes and mouth as the encoder's fill instead of cutting them out");
  app.add_flag("--clamp", clamp, "Clamp times past the sane extrapolation range to it instead of failing");
  app.add_flag("--no-texture", no_texture, "Do not blend or write the texture");
  app.add_flag("--glb-float", glb_float,
               "A glTF clip in plain floats, without KHR_mesh_quantization and EXT_meshopt_compression (for viewers that lack them)");
  app.add_flag("--glb-flat", glb_flat,
               "A glTF clip without normals: viewers shade each triangle flat; the sample's compact clip is 37% smaller");
  app.add_option("--tolerance", tolerance,
                 "Stop the reconstruction when a step moves no node more than this fraction of the rim's diameter")
      ->capture_default_str();
  app.add_flag("-q,--quiet", quiet, "No progress display or summary");
  DecoderLimits limits;
  std::string max_memory;
  tools::add_limit_options(app, limits, max_memory);
  return tools::guarded_main(app, argc, argv, [&] {
    const DecoderLimits checked_limits = tools::parsed_limits(limits, max_memory);
    if (!std::isfinite(fps) || fps < 0) throw Error(ErrorCode::kInvalidArgument, "--fps must be a finite positive number");
    const auto start = std::chrono::steady_clock::now();
    if (!extract.empty()) {
      // Every keyframe's fields at once: the file decoded whole, within the same limits.
      const Sequence whole = read_sequence_file(input, nullptr, checked_limits);
      const auto files = tools::export_keyframe_fields(whole, extract);
      if (!quiet) std::printf("fmdec: %zu files for %zu keyframes in %s\n", files.size(), whole.keyframes.size(), extract.c_str());
      if (!t && fps <= 0) return 0;
    }
    // Keyframes decoded as the frames need them, within the memory budget.
    const std::shared_ptr<const KeyframeSource> sequence = open_sequence_source(input, checked_limits);
    const double seconds_read = tools::seconds_since(start);
    SequenceDecoder decoder(sequence);
    DecodeOptions options;
    options.cut_holes = !keep_holes;
    options.clamp_to_sane_range = clamp;
    options.texture = !no_texture;
    if (!(tolerance > 0) || tolerance > 0.01) throw Error(ErrorCode::kInvalidArgument, "--tolerance must be in (0, 0.01]");
    options.reconstruct.tolerance = tolerance;
    if (t) {
      if (fps > 0 || from || to || !out_dir.empty() || out.null) {
        throw Error(ErrorCode::kInvalidArgument, "--t decodes one frame; --fps/--from/--to/--out-dir/--null decode a range");
      }
      if (mesh_out.empty() && preview.empty())
        throw Error(ErrorCode::kInvalidArgument, "--t needs -o FRAME.obj and/or --preview FRAME.png");
      if (!mesh_out.empty()) check_mesh_path(mesh_out);
      if (!mesh_out.empty() && !preview.empty() && fs::path(mesh_out).extension() == ".obj" &&
          fs::weakly_canonical(fs::path(mesh_out).replace_extension(".png")) == fs::weakly_canonical(preview)) {
        throw Error(ErrorCode::kInvalidArgument,
                    preview + " is where the mesh's texture goes; give the preview another name (e.g. FRAME_view.png)");
      }
      if (!preview.empty() && fs::path(preview).extension() != ".png")
        throw Error(ErrorCode::kInvalidArgument, preview + ": a frame's preview is a .png");
      const DecodedFrame frame = decoder.decode(*t, options);
      if (!mesh_out.empty()) write_frame(frame, mesh_out);
      if (!preview.empty()) write_png(preview, preview_picture(frame, out.yaw, preview_size));
      if (!quiet) {
        print_frame(frame, mesh_out.empty() ? fs::path(preview) : fs::path(mesh_out));
        if (!mesh_out.empty() && !frame.texture.empty())
          std::printf("  texture %s\n", fs::path(mesh_out).replace_extension(".png").string().c_str());
        if (!preview.empty()) std::printf("  preview %s\n", preview.c_str());
      }
      return 0;
    }
    if (fps <= 0)
      throw Error(ErrorCode::kInvalidArgument,
                  "give --t T for one frame, or --fps F (with --out-dir, --null or --preview SEQ.mp4) for a range");
    const bool glb = fs::path(mesh_out).extension() == ".glb";
    if (!mesh_out.empty() && !glb)
      throw Error(ErrorCode::kInvalidArgument, "a range goes to -o CLIP.glb, --out-dir DIR, --null or --preview SEQ.mp4, not to one mesh");
    if (out_dir.empty() && !out.null && preview.empty() && !glb) {
      throw Error(ErrorCode::kInvalidArgument, "a range needs -o CLIP.glb, --out-dir DIR, --null or --preview SEQ.mp4");
    }
    std::optional<ClipCollector> clip;
    if (glb) {
      clip.emplace(decoder.geometry().grid(), !glb_float, !glb_flat, sequence->outline().times);
      options.cut_holes = false;  // the clip drops the triangles inside a hole throughout instead
    }
    if (out.format != "obj" && out.format != "ply") throw Error(ErrorCode::kInvalidArgument, "--format must be obj or ply");
    const double begin = from.value_or(sequence->outline().first_time), end = to.value_or(sequence->outline().last_time);
    if (!(end >= begin)) throw Error(ErrorCode::kInvalidArgument, "--to is before --from");
    // A thousandth of a frame of slack: a rounded rate (23.976 for 24000/1001) must still reach the
    // last frame.
    const int count = tools::frame_count(begin, end, fps, 1e-3);
    std::optional<tools::VideoFile> video;
    if (!preview.empty()) {
      if (fs::path(preview).extension() != ".mp4")
        throw Error(ErrorCode::kInvalidArgument, preview + ": a range's preview is an .mp4 video");
      video.emplace(fs::path(preview).replace_extension(".partial.mp4"), preview_size, fps);
    }
    if (!out_dir.empty()) {
      std::error_code ec;
      fs::create_directories(out_dir, ec);
      if (ec) throw Error(ErrorCode::kIo, out_dir + ": " + ec.message());
    }
    tools::Progress progress("fmdec", quiet);
    const auto decode_start = std::chrono::steady_clock::now();
    double worst_ms = 0;
    int fell_back = 0;
    long iterations = 0;
    for (int i = 0; i < count; ++i) {
      const double time = begin + i / fps;
      const auto frame_start = std::chrono::steady_clock::now();
      const DecodedFrame frame = decoder.decode(time, options);
      worst_ms = std::max(worst_ms, 1000 * tools::seconds_since(frame_start));
      fell_back += frame.fell_back;
      iterations += frame.iterations;
      if (clip) clip->add(frame, i == count / 2);
      if (!out_dir.empty()) {
        char name[32];
        std::snprintf(name, sizeof name, "frame_%05d.%s", i, out.format.c_str());
        write_frame(frame, fs::path(out_dir) / name);
      }
      if (video) video->write(preview_picture(frame, out.yaw, preview_size));
      progress.update(i + 1, count);
    }
    progress.finish();
    const double seconds = tools::seconds_since(decode_start);
    if (clip) clip->write(mesh_out);
    if (video) {
      video->close();
      format::commit_temporary(fs::path(preview).replace_extension(".partial.mp4"), preview);
    }
    if (!quiet) {
      std::printf(
          "fmdec: %d frames, t = %.3f .. %.3f s at %.3f fps: %.2f ms per frame (worst %.2f ms, %.1f iterations), file read in %.0f ms%s\n",
          count, begin, begin + (count - 1) / fps, fps, 1000 * seconds / count, worst_ms, static_cast<double>(iterations) / count,
          1000 * seconds_read, fell_back ? (", " + std::to_string(fell_back) + " frames did not converge").c_str() : "");
      if (!out_dir.empty()) std::printf("  meshes in %s\n", out_dir.c_str());
      if (video) std::printf("  video %s\n", preview.c_str());
      if (clip) {
        std::printf("  glTF clip %s (%llu bytes, %zu texture%s)\n", mesh_out.c_str(),
                    static_cast<unsigned long long>(fs::file_size(mesh_out)), clip->textures(),
                    clip->textures() == 1 ? "" : "s, switched at the keyframes");
      }
    }
    return 0;
  });
}
