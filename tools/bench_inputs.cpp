#include "tools/bench_inputs.hpp"

#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

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
      return BenchFrame{face.truth_mesh(0.5, vertices), synthetic_landmarks(face, 0.5)};
    };
    source.frame_name = [input](size_t) { return input; };
    return source;
  }
  std::error_code ec;
  if (fs::is_directory(input, ec) || fs::path(input).filename() == "capture.json") {
    auto capture = std::make_shared<Capture>(read_capture(input));
    source.frames = capture->frames.size();
    source.frame = [capture](size_t i) {
      return BenchFrame{read_mesh(capture->mesh_path(i), {.allow_missing_texture = true}), capture_frame_landmarks(*capture, i)};
    };
    source.frame_name = [capture](size_t i) { return capture->frames[i].mesh.string(); };
    return source;
  }
  source.frame = [input](size_t) { return BenchFrame{read_mesh(input, {.allow_missing_texture = true}), {}}; };
  source.frame_name = [input](size_t) { return fs::path(input).filename().string(); };
  return source;
}

FrameLandmarks synthetic_landmarks(const SyntheticFace& face, double time) {
  FrameLandmarks landmarks;
  for (const NamedPoint& point : face.landmarks()) {
    const Vec3 x = face.position(point.material, time);
    if (point.name == "nose_tip")
      landmarks.centre = x;
    else if (point.name == "nose_bridge")
      landmarks.up = x;
    else if (point.name.rfind("rim_", 0) == 0)
      landmarks.rim_markers.push_back(x);
  }
  return landmarks;
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
  if (fs::exists(root / "ict-facekit/derived/face_area_neutral.obj", ec))
    inputs.push_back((root / "ict-facekit/derived/face_area_neutral.obj").string());
  return inputs;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(std::lround(q * static_cast<double>(values.size() - 1))));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

}  // namespace facemorph::tools
