// What fmbench's commands read: meshes, capture folders (every frame) and in-memory synthetic
// faces ("synth:N"), one frame at a time, with the landmarks of the reference pose.
#pragma once

#include "facemorph/encoder/frame.hpp"
#include "facemorph/mesh.hpp"

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace facemorph::tools {

struct BenchSource {
  std::string label;
  size_t frames = 1;
  // The frame's mesh and what prepare_frame needs to find its rim.
  std::function<std::pair<TriangleMesh, PrepareOptions>(size_t)> frame;
  std::function<std::string(size_t)> frame_name;
  // The reference pose (spec/method.md §3.5): points for the centre and the up direction.
  std::function<std::optional<std::pair<Vec3, Vec3>>(size_t)> pose = [](size_t) { return std::nullopt; };
};

BenchSource open_bench_source(const std::string& input);

// The standard inputs: synthetic faces (20k; with `large_synthetic` also 50k and 100k), then the
// Medusa capture and the ICT face from `data` when they are there.
std::vector<std::string> default_bench_inputs(const std::string& data, bool large_synthetic);

// The q-quantile (0: min, 0.5: median, 1: max) of `values`; 0 when empty.
double percentile(std::vector<double> values, double q);

}  // namespace facemorph::tools
