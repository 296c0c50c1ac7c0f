// What every side does with an image: sample it, hash it.
#include "codec/core/image/image.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {

std::array<double, 3> sample_bilinear(const Image& image, double u, double v) {
  if (image.empty()) return {128, 128, 128};
  const double x = std::clamp(u, 0.0, 1.0) * image.width - 0.5;
  const double y = (1.0 - std::clamp(v, 0.0, 1.0)) * image.height - 0.5;
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, image.width - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, image.height - 1);
  const int x1 = std::min(x0 + 1, image.width - 1), y1 = std::min(y0 + 1, image.height - 1);
  const double fx = std::clamp(x - x0, 0.0, 1.0), fy = std::clamp(y - y0, 0.0, 1.0);
  std::array<double, 3> out{};
  for (int c = 0; c < 3; ++c) {
    const int cc = std::min(c, image.channels - 1);
    const double top = image.at(x0, y0)[cc] * (1 - fx) + image.at(x1, y0)[cc] * fx;
    const double bottom = image.at(x0, y1)[cc] * (1 - fx) + image.at(x1, y1)[cc] * fx;
    out[static_cast<size_t>(c)] = top * (1 - fy) + bottom * fy;
  }
  return out;
}

uint64_t image_content_hash(const Image& image) {
  uint64_t hash = 1469598103934665603ull;
  const auto mix = [&hash](uint64_t byte) { hash = (hash ^ byte) * 1099511628211ull; };
  for (int v : {image.width, image.height, image.channels}) mix(static_cast<uint32_t>(v));
  for (uint8_t byte : image.pixels) mix(byte);
  return hash;
}

}  // namespace facemorph
