#include "tools/bench_inputs.hpp"

#include "facemorph/encoder/capture.hpp"
#include "facemorph/mesh_io.hpp"
#include "facemorph/encoder/synth.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

namespace facemorph::tools {
namespace fs = std::filesystem;

BenchSource open_bench_source(const std::string& input) {
  BenchSource source;
  source.label = input;
  if (input.rfind("synth:", 0) == 0) {
    const int vertices = std::stoi(input.substr(6));
    source.frame = [vertices](size_t) {
      const SyntheticFace face(Expression::kMixed, 1);
      return std::make_pair(face.truth_mesh(0.5, vertices), PrepareOptions{});
    };
    source.frame_name = [input](size_t) { return input; };
    source.pose = [](size_t) {
      const SyntheticFace face(Expression::kMixed, 1);
      return std::make_optional(std::make_pair(face.position({0, -0.014}, 0.5), face.position({0, 0.012}, 0.5)));
    };
    return source;
  }
  std::error_code ec;
  if (fs::is_directory(input, ec) || fs::path(input).filename() == "capture.json") {
    auto capture = std::make_shared<Capture>(read_capture(input));
    source.frames = capture->frames.size();
    source.frame = [capture](size_t i) {
      PrepareOptions options;
      for (size_t l = 0; l < capture->landmark_names.size(); ++l) {
        if (capture->landmark_names[l].rfind("rim_", 0) == 0 && capture->landmarks[i][l].allFinite()) {
          options.rim_markers.push_back(capture->landmarks[i][l]);
        }
      }
      return std::make_pair(read_mesh(capture->mesh_path(i), {.allow_missing_texture = true}), options);
    };
    source.frame_name = [capture](size_t i) { return capture->frames[i].mesh.string(); };
    source.pose = [capture](size_t i) -> std::optional<std::pair<Vec3, Vec3>> {
      const int centre = capture->landmark_index("nose_tip");
      int up = capture->landmark_index("nose_bridge");
      if (up < 0) up = capture->landmark_index("between_eyes");
      if (centre < 0 || up < 0) return std::nullopt;
      const Vec3 &c = capture->landmarks[i][static_cast<size_t>(centre)], &u = capture->landmarks[i][static_cast<size_t>(up)];
      if (!c.allFinite() || !u.allFinite()) return std::nullopt;
      return std::make_pair(c, u);
    };
    return source;
  }
  source.frame = [input](size_t) { return std::make_pair(read_mesh(input, {.allow_missing_texture = true}), PrepareOptions{}); };
  source.frame_name = [input](size_t) { return fs::path(input).filename().string(); };
  return source;
}

std::vector<std::string> default_bench_inputs(const std::string& data, bool large_synthetic) {
  std::vector<std::string> inputs = {"synth:20000"};
  if (large_synthetic) {
    inputs.push_back("synth:50000");
    inputs.push_back("synth:100000");
  }
  const fs::path root(data);
  std::error_code ec;
  if (fs::is_directory(root / "medusa-mediapipe-4d/capture", ec)) inputs.push_back((root / "medusa-mediapipe-4d/capture").string());
  if (fs::exists(root / "ict-facekit/derived/face_area_neutral.obj", ec)) inputs.push_back((root / "ict-facekit/derived/face_area_neutral.obj").string());
  return inputs;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(std::lround(q * static_cast<double>(values.size() - 1))));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

}  // namespace facemorph::tools
