// fmbench --capture: texture PSNR on the disk, each frame's captured texture carried there through its
// own registration and map, against facemorph's decoded textures and the baselines' coded copies.
#include "tools/bench_capture_parts.hpp"

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/geometry/elementary.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/render/render.hpp"
#include "facemorph/decoder.hpp"

#include "tools/bench_sequence.hpp"
#include "tools/plot.hpp"
#include "tools/tool_support.hpp"

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

namespace facemorph::tools::capture_bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::array<uint8_t, 3> rounded(const std::array<double, 3>& rgb) {
  std::array<uint8_t, 3> out{};
  for (size_t c = 0; c < 3; ++c) out[c] = static_cast<uint8_t>(std::clamp(std::lround(rgb[c]), 0L, 255L));
  return out;
}

// `weight(k)`: texel k's share of the mean (1 each: over the disk).
template <typename Colour, typename Weight>
double texel_psnr(const DiskTexels& t, Colour&& colour, Weight&& weight) {
  double sum = 0, total = 0;
  for (size_t k = 0; k < t.texel.size(); ++k) {
    const std::array<uint8_t, 3> c = colour(k);
    const double w = weight(k);
    for (size_t j = 0; j < 3; ++j) {
      const double d = double(c[j]) - double(t.truth[3 * k + j]);
      sum += w * d * d;
    }
    total += 3 * w;
  }
  const double mse = total > 0 ? sum / total : 0.0;
  return psnr_of_mse(std::max(mse, 1e-12));
}

constexpr auto kEachTexel = [](size_t) { return 1.0; };

// Each texel's captured pixels: |det| of the uv's derivatives across the texel (differences to the
// next texel in x and in y, or the previous one at the disk's edge) times the image's pixels.
std::vector<double> captured_pixels(const DiskTexels& t, int width, int height) {
  std::vector<int> at(static_cast<size_t>(t.size) * static_cast<size_t>(t.size), -1);
  for (size_t k = 0; k < t.texel.size(); ++k) at[static_cast<size_t>(t.texel[k])] = static_cast<int>(k);
  const auto difference = [&](int x, int y, int dx, int dy) -> std::optional<Vec2> {
    const int k = at[static_cast<size_t>(y * t.size + x)];
    for (const int s : {1, -1}) {
      const int nx = x + s * dx, ny = y + s * dy;
      if (nx < 0 || ny < 0 || nx >= t.size || ny >= t.size) continue;
      const int n = at[static_cast<size_t>(ny * t.size + nx)];
      if (n >= 0) return s * (t.uv[static_cast<size_t>(n)] - t.uv[static_cast<size_t>(k)]);
    }
    return std::nullopt;
  };
  std::vector<double> pixels(t.texel.size(), 0.0);
  for (size_t k = 0; k < t.texel.size(); ++k) {
    const int x = t.texel[k] % t.size, y = t.texel[k] / t.size;
    const std::optional<Vec2> du = difference(x, y, 1, 0), dv = difference(x, y, 0, 1);
    if (du && dv) pixels[k] = std::abs(du->x() * dv->y() - du->y() * dv->x()) * width * height;
  }
  return pixels;
}

}  // namespace

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
  t.pixels = captured_pixels(t, captured.width, captured.height);
  return t;
}

namespace {

// A disk texture (facemorph's decode) against the captured texture, each texel's error weighted by `weight`.
template <typename Weight>
double disk_psnr(const DiskTexels& t, const Image& disk, Weight&& weight) {
  if (disk.width != t.size) throw Error(ErrorCode::kInternal, "decoded texture size differs from the measured one");
  return texel_psnr(
      t,
      [&](size_t k) {
        const uint8_t* p = disk.at(t.texel[k] % t.size, t.texel[k] / t.size);
        return std::array<uint8_t, 3>{p[0], p[1], p[2]};
      },
      weight);
}

}  // namespace

double psnr_of_disk(const DiskTexels& t, const Image& disk) { return disk_psnr(t, disk, kEachTexel); }

double pixel_psnr_of_disk(const DiskTexels& t, const Image& disk) {
  return disk_psnr(t, disk, [&](size_t k) { return t.pixels[k]; });
}

TexelDensity texel_density(const DiskTexels& t, const TriangleMesh& surface, int width, int height) {
  // Texels per captured pixel, each weighted by the pixels it stands for.
  std::vector<std::pair<double, double>> density;
  double total = 0;
  for (const double p : t.pixels) {
    if (p > 0) density.emplace_back(1 / p, p), total += p;
  }
  TexelDensity out;
  out.shown_pixels = total;
  for (const Face& f : surface.uv_faces) {
    const auto uv = [&](int j) { return surface.uvs[static_cast<size_t>(f[static_cast<size_t>(j)])]; };
    out.face_pixels += std::abs(signed_area(uv(0), uv(1), uv(2))) * width * height;
  }
  if (density.empty()) return out;
  std::sort(density.begin(), density.end());
  double below = 0;
  for (const auto& [texels, pixels] : density) {
    if (texels < 1) out.undersampled += pixels / total;
    if (below < total / 2) out.median_texels_per_pixel = texels;
    below += pixels;
  }
  return out;
}

// A coded copy of the captured texture (JPEG, an H.264 frame) against it, through the same map.
double psnr_of_copy(const DiskTexels& t, const Image& copy) {
  return texel_psnr(t, [&](size_t k) { return rounded(sample_bilinear(copy, t.uv[k].x(), t.uv[k].y())); }, kEachTexel);
}

}  // namespace facemorph::tools::capture_bench
