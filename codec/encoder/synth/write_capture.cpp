// fmsynth's capture writer: meshes, per-frame textures, landmarks and the manifest.
#include "facemorph/encoder/capture.hpp"
#include "facemorph/error.hpp"
#include "facemorph/meshkit/mesh_io.hpp"
#include "facemorph/parallel.hpp"
#include "facemorph/encoder/synth.hpp"

#include "format/file_io.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <optional>
#include <random>

namespace facemorph {
namespace fs = std::filesystem;

namespace {

// Texture of frame `time`. The static skin is rendered once; only the eyes and mouth change with
// the expression, so each frame re-renders just those boxes.
class TexturePainter {
 public:
  TexturePainter(const SyntheticFace& face, int size) : face_(face), size_(size), base_(size, size, CV_8UC3) {
    paint(base_, 0, size, 0, size, 0.0);
    // Boxes (material metres) that contain every time-dependent colour: eyes, lips and mouth.
    boxes_ = {box(-0.045, 0.019, -0.019, 0.031), box(0.019, 0.019, 0.045, 0.031), box(-0.026, -0.060, 0.026, -0.034)};
  }

  cv::Mat render(double time) const {
    cv::Mat image = base_.clone();
    for (const auto& b : boxes_) paint(image, b[0], b[1], b[2], b[3], time);
    return image;
  }

 private:
  // Pixel box {x0, x1, y0, y1} (half-open) covering a material-space rectangle.
  std::array<int, 4> box(double s0, double t0, double s1, double t1) const {
    const Vec2 lo = SyntheticFace::texture_coordinate({s0, t0}), hi = SyntheticFace::texture_coordinate({s1, t1});
    auto pixel = [&](double f, bool up) {
      return std::clamp(static_cast<int>(up ? std::ceil(f * size_) : std::floor(f * size_)), 0, size_);
    };
    return {pixel(lo.x(), false), pixel(hi.x(), true), pixel(1 - hi.y(), false), pixel(1 - lo.y(), true)};
  }

  void paint(cv::Mat& image, int x0, int x1, int y0, int y1, double time) const {
    for (int y = y0; y < y1; ++y) {
      auto* row = image.ptr<cv::Vec3b>(y);
      const double v = 1.0 - (y + 0.5) / size_;  // image rows run top-down, v bottom-up
      for (int x = x0; x < x1; ++x) {
        const double u = (x + 0.5) / size_;
        const Vec2 m((2 * u - 1) * SyntheticFace::kHalfWidth, (2 * v - 1) * SyntheticFace::kHalfHeight);
        const auto rgb = face_.color(m, time);
        row[x] = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
      }
    }
  }

  const SyntheticFace& face_;
  int size_;
  cv::Mat base_;
  std::vector<std::array<int, 4>> boxes_;
};

constexpr const char* kSharedTextureName = "texture.jpg";

void write_texture(const fs::path& path, const TexturePainter& painter, double time) {
  std::vector<uint8_t> jpeg;
  if (!cv::imencode(".jpg", painter.render(time), jpeg, {cv::IMWRITE_JPEG_QUALITY, 95})) throw Error(ErrorCode::kIo, path.string() + ": JPEG encoding failed");
  format::write_file_atomically(path, jpeg);
}

std::string frame_stem(int index, int frames) {
  const int width = std::max(4, static_cast<int>(std::to_string(std::max(frames - 1, 0)).size()));
  std::string digits = std::to_string(index);
  return "frame_" + std::string(static_cast<size_t>(std::max(0, width - static_cast<int>(digits.size()))), '0') + digits;
}

void write_frame(const fs::path& directory, const SynthOptions& options, const SyntheticFace& face,
                 const TexturePainter& painter, const MaterialSampling* fixed, int index) {
  const double time = index / options.fps;
  const std::string stem = frame_stem(index, options.frames);
  const MaterialSampling own = fixed ? MaterialSampling{} : sample_material_ellipse(options.vertices, true, options.seed * 1000003 + static_cast<uint64_t>(index));
  const MaterialSampling& sampling = fixed ? *fixed : own;

  TriangleMesh mesh;
  mesh.faces = sampling.faces;
  mesh.positions.reserve(sampling.points.size());
  mesh.uvs.reserve(sampling.points.size());
  std::mt19937_64 rng(options.seed * 7919 + static_cast<uint64_t>(index) * 104729 + 1);
  std::normal_distribution<double> gaussian(0.0, 1.0);
  for (const Vec2& m : sampling.points) {
    Vec3 p = face.position(m, time);
    if (options.noise > 0) p += options.noise * gaussian(rng) * face.normal(m, time);
    mesh.positions.push_back(p);
    if (options.vertex_colour) {
      const auto rgb = face.color(m, time);
      mesh.colours.emplace_back(rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0);
    } else {
      mesh.uvs.push_back(SyntheticFace::texture_coordinate(m));
    }
  }
  if (!options.vertex_colour) mesh.uv_faces = mesh.faces;
  if (options.defects != 0) add_defects(mesh, sampling.points, sampling.boundary_count, options.defects);
  if (options.vertex_colour) {
    // A depth camera's frame: colour per vertex, no image.
    write_mesh(directory / (stem + ".ply"), mesh);
    return;
  }

  const fs::path texture = directory / (options.shared_texture ? std::string(kSharedTextureName) : stem + ".jpg");
  if (!options.shared_texture) write_texture(texture, painter, time);
  mesh.texture = texture;
  write_mesh(directory / (stem + ".obj"), mesh, {.significant_digits = 7});
}

}  // namespace

void write_synthetic_capture(const fs::path& directory, const SynthOptions& options, const ProgressCallback& progress) {
  if (options.frames < 1) throw Error(ErrorCode::kInvalidArgument, "--frames must be at least 1");
  if (!(options.fps > 0) || !std::isfinite(options.fps)) throw Error(ErrorCode::kInvalidArgument, "--fps must be positive");
  if (options.vertices < 100 || options.vertices > 5'000'000) {
    throw Error(ErrorCode::kInvalidArgument, "--vertices must be between 100 and 5000000");
  }
  if (!(options.noise >= 0) || options.noise > 0.01) throw Error(ErrorCode::kInvalidArgument, "--noise must be in [0, 0.01] metres");
  if (options.texture_size < 16 || options.texture_size > 8192) {
    throw Error(ErrorCode::kInvalidArgument, "--texture-size must be between 16 and 8192");
  }
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec || !fs::is_directory(directory)) throw Error(ErrorCode::kIo, directory.string() + ": cannot create the folder");

  const SyntheticFace face(options.expression, options.seed, options.head_motion_degrees, options.speech_rate);
  const TexturePainter painter(face, options.vertex_colour ? 16 : options.texture_size);  // no image to paint with vertex colours
  std::optional<MaterialSampling> fixed;
  if (!options.remesh) fixed = sample_material_ellipse(options.vertices, false, 0);

  if (options.shared_texture && options.vertex_colour) throw Error(ErrorCode::kInvalidArgument, "--shared-texture and --vertex-colour exclude each other");
  if (options.shared_texture) write_texture(directory / kSharedTextureName, painter, 0.0);
  parallel_for(options.frames, 0, [&](int i) { write_frame(directory, options, face, painter, fixed ? &*fixed : nullptr, i); },
               progress);

  Capture capture;
  capture.root = directory;
  capture.description = std::string("fmsynth synthetic face, expression ") + expression_name(options.expression);
  capture.fps = options.fps;
  capture.units = "m";
  const std::string extension = options.vertex_colour ? ".ply" : ".obj";
  for (int i = 0; i < options.frames; ++i) capture.frames.push_back({frame_stem(i, options.frames) + extension, i / options.fps});
  for (const NamedPoint& l : face.landmarks()) capture.landmark_names.push_back(l.name);
  capture.landmarks.resize(capture.frames.size());
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    for (const NamedPoint& l : face.landmarks()) capture.landmarks[i].push_back(face.position(l.material, capture.frames[i].time));
  }
  capture.generator = {{"name", "fmsynth"},
                       {"expression", expression_name(options.expression)},
                       {"seed", std::to_string(options.seed)},
                       {"head_motion_degrees", std::to_string(options.head_motion_degrees)},
                       {"vertices", std::to_string(options.vertices)},
                       {"remesh", options.remesh ? "true" : "false"},
                       {"noise", std::to_string(options.noise)},
                       {"colour", options.vertex_colour ? "vertex" : options.shared_texture ? "one shared texture" : "texture"}};
  if (options.speech_rate != 1) capture.generator.emplace_back("speech_rate", std::to_string(options.speech_rate));  // 1: manifests as before
  if (options.defects != 0) capture.generator.emplace_back("defects", defect_names(options.defects));
  write_capture_manifest(capture);
}

}  // namespace facemorph
