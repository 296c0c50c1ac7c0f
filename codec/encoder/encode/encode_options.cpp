// The options' ranges, checked once where an encoder takes them (encode_options.hpp).
#include "codec/encoder/encode/encode_options.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "format/error.hpp"

#include <string>

namespace facemorph {

void check_encode_options(const EncodeOptions& options, int count) {
  if (!(options.landmark_tolerance > 0)) throw Error(ErrorCode::kInvalidArgument, "the landmark tolerance must be positive");
  if (options.reference_frame < 0 || options.reference_frame >= count) {
    throw Error(ErrorCode::kInvalidArgument,
                "reference frame " + std::to_string(options.reference_frame) + " is not a frame of the capture");
  }
  if (!(options.keyframe_fraction > 0 && options.keyframe_fraction <= 1) && !(options.max_error > 0)) {
    throw Error(ErrorCode::kInvalidArgument, "the keyframe budget must be in (0, 100%]");
  }
  if (!(options.keyframe_error_bound >= 0)) throw Error(ErrorCode::kInvalidArgument, "the keyframe error bound must be >= 0");
  if (!(options.keyframe_p99_bound >= 0)) throw Error(ErrorCode::kInvalidArgument, "the keyframe 99th-percentile bound must be >= 0");
  if (!(options.keyframe_fit_weight >= 0) || !(options.keyframe_fit_noise >= 0)) {
    throw Error(ErrorCode::kInvalidArgument, "the keyframe fit's weight and noise factor must be >= 0");
  }
  if (options.grid != 0 && (options.grid < kMinGridSize || options.grid > kMaxGridSize)) {
    throw Error(ErrorCode::kInvalidArgument,
                "grid size N must be 0 (auto) or in [" + std::to_string(kMinGridSize) + ", " + std::to_string(kMaxGridSize) + "]");
  }
  const double strength = options.density_equalising.strength;
  if (!(strength >= 0 && strength <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "density-equalising strength must be in [0, 1], not " + std::to_string(strength));
  }
  const double radial = options.density_equalising.radial;
  if (radial != kAutoRadial && !(radial >= 0 && radial <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "radial-equalising strength must be auto or in [0, 1], not " + std::to_string(radial));
  }
  // Two reparametrisations of the disk; the flow, asked for, turns the radial map off, so asking for
  // both would silently drop one (a whole head then fails to converge with nothing saying why).
  if (radial != kAutoRadial && radial > 0 && strength > 0) {
    throw Error(ErrorCode::kInvalidArgument, "radial equalising (" + std::to_string(radial) + ") and density equalising (" +
                                                 std::to_string(strength) + ") are two reparametrisations of the disk: ask for one");
  }
  if (options.texture && options.texture_size != 0 && (options.texture_size < kMinTextureSize || options.texture_size > kMaxTextureSize)) {
    throw Error(ErrorCode::kInvalidArgument,
                "texture size must be 0 (auto) or in [" + std::to_string(kMinTextureSize) + ", " + std::to_string(kMaxTextureSize) + "]");
  }
  if (options.texture_quality != kAutoTextureQuality && (options.texture_quality < 0 || options.texture_quality > kMaxTextureQuality)) {
    throw Error(ErrorCode::kInvalidArgument, "texture quality must be auto or in [0, " + std::to_string(kMaxTextureQuality) + "], not " + std::to_string(options.texture_quality));
  }
  const TextureQualityOptions& coding = options.texture_coding;
  if (!(coding.interpolation_share > 0) || !(coding.min_psnr <= coding.max_psnr) || coding.fallback_quality < 0 ||
      coding.fallback_quality > 101) {
    throw Error(ErrorCode::kInvalidArgument,
                "texture coding: the interpolation share must be positive, min_psnr at most max_psnr, the fallback quality in [0, 101]");
  }
}

}  // namespace facemorph
