// The sequence's own checks and blends (sequence.hpp): what the decoder and the encoder both apply.
#include "codec/core/sequence/sequence.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cstdint>
#include <string>

namespace facemorph {

std::vector<double> Sequence::keyframe_times() const {
  std::vector<double> times;
  for (const Keyframe& k : keyframes) times.push_back(k.time);
  return times;
}

void validate_sequence(const Sequence& sequence) {
  const SequenceOutline outline = outline_of(sequence);
  validate_outline(outline);  // first: it refuses a sequence without keyframes
  const Keyframe& first = sequence.keyframes.front();
  for (size_t k = 0; k < sequence.keyframes.size(); ++k) {
    const Keyframe& key = sequence.keyframes[k];
    validate_keyframe(outline, first.fields.fixed_nodes, k, key);
    const auto fail = [&](const std::string& what) {
      throw Error(ErrorCode::kInvalidArgument, "sequence: keyframe " + std::to_string(k) + ": " + what);
    };
    if (key.texture.empty() != first.texture.empty()) fail("textures present in some keyframes only");
    if (!key.texture.empty() &&
        (key.texture.width != first.texture.width || key.texture.height != first.texture.height || key.texture.channels != 3 ||
         key.texture.pixels.size() != static_cast<size_t>(key.texture.width) * key.texture.height * 3)) {
      fail("the texture is not " + std::to_string(first.texture.width) + " x " + std::to_string(first.texture.height) + " RGB");
    }
  }
}

namespace {

// out[p] = Σ_k weight[k] · pixels[k][p] rounded to a byte, for a fixed number of keys K so that the
// key loop unrolls and the pixel loop vectorises. On x86-64 it is also built for AVX2 and picked at
// run time (twice the floats an instruction; the same sums, so the same bytes).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define FACEMORPH_PIXEL_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define FACEMORPH_PIXEL_CLONES
#endif
template <size_t K>
FACEMORPH_PIXEL_CLONES void blend_pixels(const uint8_t* const* pixels, const float* weights, uint8_t* __restrict out, size_t count) {
  // Local copies: `out` is bytes, which may alias anything, and through which the compiler would
  // otherwise reload the weights and pointers for every pixel (and not vectorise).
  float weight[K];
  const uint8_t* __restrict in[K];
  for (size_t i = 0; i < K; ++i) {
    weight[i] = weights[i];
    in[i] = pixels[i];
  }
  for (size_t p = 0; p < count; ++p) {
    float sum = 0.0f;
    for (size_t i = 0; i < K; ++i) sum += weight[i] * static_cast<float>(in[i][p]);
    // Truncating x + ½ within [0, 255] rounds x to the nearest byte.
    out[p] = static_cast<uint8_t>(std::min(std::max(sum + 0.5f, 0.0f), 255.0f));
  }
}

}  // namespace

// Σ w_k · texture of key k, rounded to the nearest byte and clamped to 0..255 (Catmull-Rom weights
// can be negative). One vectorised pass over the pixels with the keys' sum in a register: summed
// through a float image and rounded by lround, the blend was half of a frame's time at 1024² (14 of
// 27 ms at N = 129); now about 1 ms. The float sum is taken in the same order as before, so the
// bytes are the same but where adding ½ itself rounds (sums within a float ulp below a half).
Image blend_textures(const Sequence& sequence, const SplineWeights& w) {
  std::vector<const Image*> images;
  for (int32_t k : w.keys) images.push_back(&sequence.keyframes[static_cast<size_t>(k)].texture);
  return blend_images(images, w.weights);
}

Image blend_images(const std::vector<const Image*>& images, const std::vector<double>& weights) {
  const Image& first = *images.front();
  Image out(first.width, first.height, 3);
  std::vector<const uint8_t*> pixels;
  std::vector<float> weight;
  for (size_t i = 0; i < images.size(); ++i) {
    if (weights[i] == 0) continue;  // a keyframe time: one key has it all
    pixels.push_back(images[i]->pixels.data());
    weight.push_back(static_cast<float>(weights[i]));
  }
  const size_t count = out.pixels.size();
  switch (pixels.size()) {
    case 0: break;  // all weights zero: black, as the sum was
    case 1: blend_pixels<1>(pixels.data(), weight.data(), out.pixels.data(), count); break;
    case 2: blend_pixels<2>(pixels.data(), weight.data(), out.pixels.data(), count); break;
    case 3: blend_pixels<3>(pixels.data(), weight.data(), out.pixels.data(), count); break;
    case 4: blend_pixels<4>(pixels.data(), weight.data(), out.pixels.data(), count); break;
    default: {
      // More keys than any spline of today blends: the same sum, unvectorised.
      for (size_t p = 0; p < count; ++p) {
        float sum = 0.0f;
        for (size_t i = 0; i < pixels.size(); ++i) sum += weight[i] * static_cast<float>(pixels[i][p]);
        out.pixels[p] = static_cast<uint8_t>(std::min(std::max(sum + 0.5f, 0.0f), 255.0f));
      }
    }
  }
  return out;
}

}  // namespace facemorph
