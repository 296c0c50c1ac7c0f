// What fmbench's commands read: meshes, capture folders (every frame) and in-memory synthetic
// faces ("synth:N"), one frame at a time, with the landmarks of the reference pose.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/synth/synth.hpp"

#include <functional>
#include <string>
#include <vector>

namespace facemorph::tools {

struct BenchFrame {
  TriangleMesh mesh;
  FrameLandmarks landmarks;  // rim markers and the reference pose (spec/method.md §3.5), where known
};

struct BenchSource {
  std::string label;
  size_t frames = 1;
  std::function<BenchFrame(size_t)> frame;
  std::function<std::string(size_t)> frame_name;
};

BenchSource open_bench_source(const std::string& input);

// The landmarks of a synthetic face at `time`, as a capture of it would list them.
FrameLandmarks synthetic_landmarks(const SyntheticFace& face, double time);

// The standard inputs: synthetic faces (20k; with `large_synthetic` also 50k and 100k), then the
// Medusa capture and the ICT face from `data` when they are there.
std::vector<std::string> default_bench_inputs(const std::string& data, bool large_synthetic);

// The q-quantile (0: min, 0.5: median, 1: max) of `values`; 0 when empty.
double percentile(std::vector<double> values, double q);

}  // namespace facemorph::tools
