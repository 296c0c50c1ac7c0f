// Each keyframe's texture quality from the interpolation error beside it (spec/method.md §7.12).
#include "codec/encoder/encode/texture_quality.hpp"

#include "codec/decoder/image/image_decode.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace facemorph {

double disk_texture_mse(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height || a.channels != 3 || b.channels != 3 || a.pixels.size() != b.pixels.size()) {
    throw Error(ErrorCode::kInvalidArgument, "disk_texture_mse: the images differ in size or are not RGB");
  }
  double sum = 0;
  size_t count = 0;
  for (int y = 0; y < a.height; ++y) {
    const double v = 1 - 2 * (y + 0.5) / a.height;
    for (int x = 0; x < a.width; ++x) {
      const double u = 2 * (x + 0.5) / a.width - 1;
      if (u * u + v * v > 1) continue;
      const uint8_t *p = a.at(x, y), *q = b.at(x, y);
      for (int c = 0; c < 3; ++c) {
        const double d = static_cast<double>(p[c]) - q[c];
        sum += d * d;
      }
      count += 3;
    }
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

double psnr_of_mse(double mse) { return mse > 0 ? 10 * std::log10(255.0 * 255.0 / mse) : std::numeric_limits<double>::infinity(); }

double mse_of_psnr(double psnr) { return 255.0 * 255.0 * std::pow(10.0, -psnr / 10); }

int quality_hint(const QualityCurve& curve, double target_mse) {
  int failed = -1;
  double failed_error = 0;
  for (const auto& [quality, error] : curve) {
    if (error <= target_mse) {
      if (failed < 0 || !(failed_error > error) || !(error > 0)) return std::clamp(quality, 1, 99);
      // Between the last quality that failed and this one, where log(error) meets the target.
      const double t = std::log(failed_error / target_mse) / std::log(failed_error / error);
      const int between = std::clamp(failed + static_cast<int>(std::ceil(t * (quality - failed))), failed + 1, quality);
      return std::clamp(between, 1, 99);  // 100 (the floor, met) after 99 failed: 99, the hint nearest
    }
    failed = quality;
    failed_error = error;
  }
  return failed < 0 ? -1 : std::clamp(failed + 1, 1, 99);
}

int texture_quality_for(TextureCodec codec, const Image& texture, double target_mse, int hint, QualityCurve* measured) {
  constexpr double kFloorMargin = 1.25;
  // Each quality's error, coded once (AVIF's 101 qualities fall on 64 quantisers: qualities of one
  // quantiser are the same bytes, coded once too).
  std::map<int, double> coded;
  const TextureStill still(codec, texture);
  auto error_at = [&](int quality) {
    const int key = codec == TextureCodec::kAvif ? avif_quantizer(quality) : quality;
    const auto found = coded.find(key);
    if (found != coded.end()) return found->second;
    const double error = disk_texture_mse(texture, decode_texture(codec, still.encode(quality), "texture_quality_for"));
    coded.emplace(key, error);
    if (measured) measured->emplace(quality, error);
    return error;
  };
  // A lossy codec cannot go below its floor (chroma rounding, the finest quantiser): a target near
  // or under it would buy bytes and no quality, so the target is at least a quarter above the floor.
  // AVIF's floor is its colour conversion alone (quality 100 is lossless AV1), found without the
  // lossless encode, which costs as much as four lossy ones.
  const double floor = codec == TextureCodec::kAvif ? disk_texture_mse(texture, still.colour_round_trip()) : error_at(100);
  if (measured) measured->emplace(100, floor);
  target_mse = std::max(target_mse, kFloorMargin * floor);
  // The lowest quality that meets the target within [lo, hi]: lo fails (or is 0), hi meets (100
  // meets: the target is above the floor). The error falls about exponentially with the quality,
  // so each probe is where log(error) interpolated between the bracket's ends meets the target, and
  // its neighbour on the other side is probed next: an answer is the boundary between a failing
  // quality and the next, met. The same boundary bisection finds where the error falls with the
  // quality, in 3-4 codings instead of 8.
  int lo = 0, hi = 100;
  double lo_error = 0, hi_error = floor;
  // Probes `quality`: it becomes the bracket's end on its side. Returns whether it met the target.
  const auto probe = [&](int quality) {
    const double error = error_at(quality);
    const bool met = error <= target_mse;
    (met ? hi : lo) = quality;
    (met ? hi_error : lo_error) = error;
    return met;
  };
  if (hint > 0 && hint < 100) {
    // A hint (quality_hint: where a similar texture's errors met this target): the bracket closed
    // around it by probes stepping away from it, one quality, one more, then two, four..., until one
    // lands on the other side. Where the hint is right, two codings find the answer (the hint met,
    // the one below it not) where the search from [0, 100] takes four or five; one too low, two
    // (the hint failed, the next met); one too high, three (Medusa's hints: 2.4 codings a keyframe).
    // The error falling with the quality, the boundary found is the same either way.
    const auto step = [](int n) { return n < 2 ? 1 : 1 << (n - 1); };
    if (probe(hint)) {
      for (int n = 0;; ++n) {
        const int quality = std::max(hi - step(n), 0);
        if (!probe(quality)) break;  // lo: the coarser end, measured
        if (quality == 0) return 0;
      }
    } else {
      for (int n = 0; lo + step(n) < hi; ++n) {
        if (probe(lo + step(n))) break;  // hi: the finer end (100, the floor, meets unmeasured)
      }
    }
  } else {
    lo_error = error_at(lo);
    if (lo_error <= target_mse) return 0;
  }
  while (hi - lo > 1) {
    int quality = (lo + hi) / 2;
    if (lo_error > 0 && hi_error > 0 && lo_error > hi_error) {
      const double t = std::log(lo_error / target_mse) / std::log(lo_error / hi_error);
      quality = lo + static_cast<int>(std::lround(t * (hi - lo)));
    }
    const bool met = probe(std::clamp(quality, lo + 1, hi - 1));
    if (hi - lo > 1) probe(met ? hi - 1 : lo + 1);  // its neighbour on the other side
  }
  return hi;
}

std::vector<double> texture_error_targets(const std::vector<double>& interval_mse, const TextureQualityOptions& options) {
  if (!(options.interpolation_share > 0) || !(options.min_psnr <= options.max_psnr)) {
    throw Error(ErrorCode::kInvalidArgument, "texture quality: the interpolation share must be positive and min_psnr at most max_psnr");
  }
  const size_t keys = interval_mse.size() + 1;
  std::vector<double> targets(keys, -1.0);
  const size_t intervals = interval_mse.size();
  for (size_t k = 0; k < keys; ++k) {
    // The measured intervals nearest keyframe k: at `reach` 0 the two beside it (k - 1 and k), then
    // one further out on each side, until one is measured (an interval between adjacent frames has
    // no frame to measure). The blend's error varies slowly in time, so a keyframe with unmeasured
    // neighbours takes the nearest measured one's rather than the fixed fallback quality; of two
    // at the same reach, the smaller error (the finer target).
    double smallest = std::numeric_limits<double>::infinity();
    for (size_t reach = 0; !std::isfinite(smallest) && (reach < k || k + reach < intervals); ++reach) {
      if (reach < k && interval_mse[k - 1 - reach] >= 0) smallest = std::min(smallest, interval_mse[k - 1 - reach]);
      if (k + reach < intervals && interval_mse[k + reach] >= 0) smallest = std::min(smallest, interval_mse[k + reach]);
    }
    if (!std::isfinite(smallest)) continue;  // nothing measured at all: the fallback quality
    targets[k] = std::clamp(options.interpolation_share * smallest, mse_of_psnr(options.max_psnr), mse_of_psnr(options.min_psnr));
  }
  return targets;
}

}  // namespace facemorph
