// fmsynth's capture writer: meshes, per-frame textures, landmarks and the manifest.
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "format/error.hpp"

#include "format/file_io.hpp"

#include "codec/encoder/imageio/opencv_codecs.hpp"

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
  const OpenCvImageCodecs& codecs = opencv_image_codecs(path.string());
  std::vector<uint8_t> jpeg;
  if (!codecs.imencode(".jpg", painter.render(time), jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}))
    throw Error(ErrorCode::kIo, path.string() + ": JPEG encoding failed");
  format::write_file_atomically(path, jpeg);
}

std::string frame_stem(int index, int frames) {
  const int width = std::max(4, static_cast<int>(std::to_string(std::max(frames - 1, 0)).size()));
  std::string digits = std::to_string(index);
  return "frame_" + std::string(static_cast<size_t>(std::max(0, width - static_cast<int>(digits.size()))), '0') + digits;
}

// The back of the head's texture coordinates: its stereographic plane (within about ±2.5) squeezed
// into the texture's lower left corner, outside the face's ellipse, where the skin's colour is
// painted without features.
Vec2 back_texture_coordinate(const Vec2& plane) {
  return Vec2(0.01, 0.01) + 0.02 * (plane.cwiseMax(Vec2(-2.5, -2.5)).cwiseMin(Vec2(2.5, 2.5)) + Vec2(2.5, 2.5));
}

// The whole head's frame: the face's vertices, then the back's; the rim vertices take a second
// texture coordinate for the back's triangles (a seam), so no triangle spans the texture.
TriangleMesh head_frame(const SynthOptions& options, const SyntheticFace& face, const HeadSampling& head, double time,
                        std::mt19937_64& rng) {
  std::normal_distribution<double> gaussian(0.0, 1.0);
  const MaterialSampling& sampling = head.face;
  TriangleMesh mesh;
  mesh.faces = head.faces;
  for (const Vec2& m : sampling.points) {
    Vec3 p = face.position(m, time);
    if (options.noise > 0) p += options.noise * gaussian(rng) * face.normal(m, time);
    mesh.positions.push_back(p);
    mesh.uvs.push_back(SyntheticFace::texture_coordinate(m));
  }
  for (const HeadVertex& v : head.back) {
    Vec3 p = face.head_point(v, time);
    if (options.noise > 0) p += options.noise * gaussian(rng) * v.normal;  // the rays are near the normals: noise, not geometry
    mesh.positions.push_back(p);
    mesh.uvs.push_back(back_texture_coordinate(v.plane));
  }
  const auto rim_uv = static_cast<int32_t>(mesh.uvs.size());
  for (const Vec2& plane : head.rim_plane) mesh.uvs.push_back(back_texture_coordinate(plane));
  mesh.uv_faces = mesh.faces;
  for (size_t f = head.face_faces; f < mesh.uv_faces.size(); ++f) {
    for (int32_t& v : mesh.uv_faces[f]) {
      if (v < sampling.boundary_count) v += rim_uv;
    }
  }
  return mesh;
}

// A head-and-shoulders frame (--surround, --no-face): the scan's fixed points and triangles, noise
// along the view (+z), its own texture.
void write_surrounded_frame(const fs::path& directory, const SynthOptions& options, const SyntheticFace& face,
                            const std::vector<Vec2>& material, const std::vector<Face>& faces, int index) {
  const double time = index / options.fps;
  const std::string stem = frame_stem(index, options.frames);
  SurroundedFrame frame = surrounded_frame(face, material, faces, time, Eigen::Matrix3d::Identity(), !options.no_face);
  std::mt19937_64 rng(options.seed * 7919 + static_cast<uint64_t>(index) * 104729 + 1);
  std::normal_distribution<double> gaussian(0.0, 1.0);
  if (options.noise > 0) {
    for (Vec3& p : frame.mesh.positions) p.z() += options.noise * gaussian(rng);
  }
  frame.mesh.texture = directory / (stem + ".jpg");
  write_image(frame.mesh.texture, frame.texture, 95);
  write_mesh(directory / (stem + ".obj"), frame.mesh, {.significant_digits = 7});
}

void write_frame(const fs::path& directory, const SynthOptions& options, const SyntheticFace& face, const TexturePainter& painter,
                 const MaterialSampling* fixed, const HeadSampling* head, int index) {
  const double time = index / options.fps;
  const std::string stem = frame_stem(index, options.frames);
  if (head != nullptr && options.whole_head) {
    std::mt19937_64 rng(options.seed * 7919 + static_cast<uint64_t>(index) * 104729 + 1);
    TriangleMesh mesh = head_frame(options, face, *head, time, rng);
    const fs::path texture = directory / (options.shared_texture ? std::string(kSharedTextureName) : stem + ".jpg");
    if (!options.shared_texture) write_texture(texture, painter, time);
    mesh.texture = texture;
    write_mesh(directory / (stem + ".obj"), mesh, {.significant_digits = 7});
    return;
  }
  MaterialSampling own =
      fixed ? MaterialSampling{} : sample_material_ellipse(options.vertices, true, options.seed * 1000003 + static_cast<uint64_t>(index));
  if (!fixed && options.holes) {
    std::erase_if(own.faces, [&](const Face& f) {
      return SyntheticFace::in_hole(
          (own.points[static_cast<size_t>(f[0])] + own.points[static_cast<size_t>(f[1])] + own.points[static_cast<size_t>(f[2])]) / 3.0);
    });
  }
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
  if (options.whole_head && (options.remesh || options.defects != 0 || options.vertex_colour)) {
    throw Error(ErrorCode::kInvalidArgument, "--head takes neither --remesh, --defects nor --vertex-colour");
  }
  if (options.no_face && !options.surround) throw Error(ErrorCode::kInvalidArgument, "--no-face needs --surround");
  if (options.surround &&
      (options.remesh || options.defects != 0 || options.holes || options.whole_head || options.vertex_colour || options.shared_texture)) {
    throw Error(ErrorCode::kInvalidArgument,
                "--surround takes neither --remesh, --defects, --holes, --head, --vertex-colour nor --shared-texture");
  }
  std::optional<MaterialSampling> fixed;
  std::optional<HeadSampling> head;
  std::vector<Vec2> surround;
  std::vector<Face> surround_faces;
  if (options.surround) {
    surround = surround_material(surround_spacing(options.vertices), options.seed);
    surround_faces = delaunay_triangulation(surround);
  } else if (!options.remesh) {
    head = sample_head(options.vertices, face, options.holes, options.whole_head);
    fixed = head->face;
    fixed->faces.assign(head->faces.begin(), head->faces.begin() + static_cast<long>(head->face_faces));
  }

  if (options.shared_texture && options.vertex_colour)
    throw Error(ErrorCode::kInvalidArgument, "--shared-texture and --vertex-colour exclude each other");
  if (options.shared_texture) write_texture(directory / kSharedTextureName, painter, 0.0);
  parallel_for(
      options.frames, 0,
      [&](int i) {
        if (options.surround) {
          write_surrounded_frame(directory, options, face, surround, surround_faces, i);
        } else {
          write_frame(directory, options, face, painter, fixed ? &*fixed : nullptr, head ? &*head : nullptr, i);
        }
      },
      progress);

  Capture capture;
  capture.root = directory;
  capture.description = std::string(options.no_face      ? "fmsynth head-and-shoulders scan with no face (a plain dome), expression "
                                    : options.surround   ? "fmsynth synthetic face in a head-and-shoulders scan, expression "
                                    : options.whole_head ? "fmsynth synthetic whole head, expression "
                                                         : "fmsynth synthetic face, expression ") +
                        expression_name(options.expression);
  capture.fps = options.fps;
  capture.units = "m";
  const std::string extension = options.vertex_colour ? ".ply" : ".obj";
  for (int i = 0; i < options.frames; ++i) capture.frames.push_back({frame_stem(i, options.frames) + extension, i / options.fps});
  // The whole head's rim markers lie on the neck's rim (its vertices, evenly spaced), not the face's.
  // A head-and-shoulders scan's rim is its extent's rectangle, not the face's: no rim markers; and
  // with no face, no landmarks at all.
  std::vector<const NamedPoint*> named;
  for (const NamedPoint& l : face.landmarks()) {
    if (options.no_face) break;
    if (!(options.whole_head || options.surround) || l.name.rfind("rim_", 0) != 0) named.push_back(&l);
  }
  constexpr int kNeckMarkers = 8;
  for (const NamedPoint* l : named) capture.landmark_names.push_back(l->name);
  if (options.whole_head) {
    for (int k = 0; k < kNeckMarkers; ++k) capture.landmark_names.push_back("rim_" + std::to_string(k));
  }
  capture.landmarks.resize(capture.frames.size());
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    const double time = capture.frames[i].time;
    for (const NamedPoint* l : named) capture.landmarks[i].push_back(face.position(l->material, time));
    if (options.whole_head) {
      for (int k = 0; k < kNeckMarkers; ++k)
        capture.landmarks[i].push_back(face.head_point(head->back[static_cast<size_t>(k * head->neck_count / kNeckMarkers)], time));
    }
  }
  capture.generator = {{"name", "fmsynth"},
                       {"expression", expression_name(options.expression)},
                       {"seed", std::to_string(options.seed)},
                       {"head_motion_degrees", std::to_string(options.head_motion_degrees)},
                       {"vertices", std::to_string(options.vertices)},
                       {"remesh", options.remesh ? "true" : "false"},
                       {"noise", std::to_string(options.noise)},
                       {"colour", options.vertex_colour    ? "vertex"
                                  : options.shared_texture ? "one shared texture"
                                                           : "texture"}};
  if (options.speech_rate != 1)
    capture.generator.emplace_back("speech_rate", std::to_string(options.speech_rate));  // 1: manifests as before
  if (options.defects != 0) capture.generator.emplace_back("defects", defect_names(options.defects));
  if (options.holes) capture.generator.emplace_back("holes", "eyes, mouth, nostrils");
  if (options.whole_head) capture.generator.emplace_back("surface", "whole head to the neck");
  if (options.surround)
    capture.generator.emplace_back(
        "surface", options.no_face ? "hair and a shoulder round a plain dome: no face" : "hair and a shoulder round the face");
  write_capture_manifest(capture);
}

}  // namespace facemorph
