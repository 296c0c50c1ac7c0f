// A plain 8-bit image buffer, the currency between the decoder (which must not depend on OpenCV)
// and whatever encodes pictures.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace facemorph {

struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;             // 3: RGB, 4: RGBA
  std::vector<uint8_t> pixels;  // row-major, top row first, channels interleaved

  Image() = default;
  Image(int w, int h, int c) : width(w), height(h), channels(c), pixels(static_cast<size_t>(w) * h * c, 0) {}
  bool empty() const { return width <= 0 || height <= 0; }
  uint8_t* at(int x, int y) { return pixels.data() + (static_cast<size_t>(y) * width + x) * channels; }
  const uint8_t* at(int x, int y) const { return pixels.data() + (static_cast<size_t>(y) * width + x) * channels; }
};

// Bilinear lookup at texture coordinate (u, v) ∈ [0,1]² (v up, as in OBJ), clamped at the edges.
// Returns RGB in 0..255 as doubles.
std::array<double, 3> sample_bilinear(const Image& image, double u, double v);

// A 64-bit hash (FNV-1a) of the image's size, channels and pixels: images of the same pixels hash
// alike (compare the pixels to be sure), whichever file or codec they came from.
uint64_t image_content_hash(const Image& image);

}  // namespace facemorph
