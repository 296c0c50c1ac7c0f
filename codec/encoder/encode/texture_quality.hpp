// How coarsely each keyframe's texture is coded (spec/method.md §7.12): from the error the texture
// blend already makes between keyframes, not at one quality for every capture. A frame between two
// keyframes shows their blend, which differs from its own texture by the interpolation error; a
// keyframe coded far finer than that spends bytes on detail no held-out frame shows. So each
// keyframe's quality (AVIF's or WebP's) is the lowest whose coding error is a share of the interpolation error
// measured beside it, within a PSNR range that keeps a paused keyframe presentable.
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/core/image/texture_codec.hpp"

#include <map>
#include <vector>

namespace facemorph {

struct TextureQualityOptions {
  // The coding error (MSE) a keyframe may add, as a share of the interpolation error (MSE) of the
  // frames midway to its neighbouring keyframes (the smaller of the two).
  double interpolation_share = 0.25;
  // Bounds on a keyframe's own PSNR over the disk (dB): never coarser than min_psnr (a player paused
  // on a keyframe shows it), never finer than max_psnr (beyond what any display shows).
  double min_psnr = 30;
  double max_psnr = 40;
  // Where nothing is measured (one keyframe, or keyframes on consecutive frames): this quality.
  int fallback_quality = 90;
};

// A texture's coding error (MSE, disk_texture_mse) by quality, as a quality search measured it.
using QualityCurve = std::map<int, double>;

// Mean squared error per channel (0..255 scale) of two RGB images of one size over the texels whose
// centres lie in the unit disk the image covers (spec/container.md §8): what a disk texture shows.
// Throws kInvalidArgument for images of other sizes or channel counts.
double disk_texture_mse(const Image& a, const Image& b);

// PSNR (dB, peak 255) of a mean squared error; +inf for 0.
double psnr_of_mse(double mse);
double mse_of_psnr(double psnr);

// The lowest quality in [0, 100] of `codec` (image_codec.hpp) whose decode of `texture` lies within
// `target_mse` of it over the disk (probes interpolated in log error, bracketing: the error falls as
// the quality rises, to a few percent). A target under 1.25 times the error at quality 100 (the
// lossy codec's floor: chroma rounding, its finest quantiser) is raised to that: closer to the
// floor costs bytes and shows nothing. `hint` in [1, 99] (quality_hint): the search starts there,
// two codings where the hint is the answer, and finds the same answer wherever the error falls with
// the quality. `measured`: each quality's error as coded, and 100's, the floor.
int texture_quality_for(TextureCodec codec, const Image& texture, double target_mse, int hint = -1, QualityCurve* measured = nullptr);

// Where `curve` (a similar texture's errors by quality, as texture_quality_for measured them: a
// neighbouring keyframe's, or the same keyframe's on another disk) meets `target_mse`: the quality
// interpolated in log(error) between the last it failed at and the first it met, in [1, 99]; -1 for
// an empty curve.
int quality_hint(const QualityCurve& curve, double target_mse);

// Per keyframe, the MSE its coding may add: options.interpolation_share times the smaller of the
// interpolation errors of the intervals beside it (`interval_mse[k]`: between keyframes k and k + 1,
// negative where not measured), clamped to [max_psnr, min_psnr]. A keyframe with neither neighbour
// measured takes the nearest measured interval in keyframe order (ties: the smaller MSE); negative
// only where no interval was measured at all. `keys` keyframes, keys - 1 intervals.
std::vector<double> texture_error_targets(const std::vector<double>& interval_mse, const TextureQualityOptions& options);

}  // namespace facemorph
