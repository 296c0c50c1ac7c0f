// The texture stage: each keyframe's texture quality (from the texture blend's error beside it,
// spec/method.md §7.12), and keyframes painted from one captured image sharing one texture
// (spec/method.md §7.16).
#include "codec/encoder/encode/texture_stage.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/sequence/spline.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "format/error.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <optional>

namespace facemorph {

TextureQualities keyframe_texture_qualities(const StoredSequence& stored, const std::vector<int>& keyframes, const FrameTextures& frames,
                                            int quality, TextureCodec codec, const TextureQualityOptions& coding, int threads,
                                            const std::vector<QualityCurve>& hints) {
  TextureQualities chosen;
  const Sequence& sequence = stored.shape();
  if (stored.size() == 0 || stored.texture(0)->empty()) return chosen;
  const size_t keys = sequence.keyframes.size();
  if (keyframes.size() != keys) throw Error(ErrorCode::kInvalidArgument, "choose_texture_qualities: the keyframes are not the sequence's");
  std::vector<int> qualities(keys, quality);
  if (quality == kAutoTextureQuality) {
    // The blend's error at the frame midway between each pair of neighbouring keyframes, against
    // that frame's own texture on the disk (sampled as a keyframe's would be).
    std::vector<double> times;
    for (const Keyframe& key : sequence.keyframes) times.push_back(key.time);
    const KeyframeSpline spline(times, sequence.spline);
    const int size = stored.texture(0)->width;
    std::vector<double> interval_mse(keys - 1, -1.0);
    parallel_for(static_cast<int>(keys) - 1, threads, [&](int k) {
      const int middle = (keyframes[static_cast<size_t>(k)] + keyframes[static_cast<size_t>(k) + 1]) / 2;
      if (middle == keyframes[static_cast<size_t>(k)] || !frames.has_texture(middle)) return;
      const Image own = frames.texture(middle, size);
      const SplineWeights w = spline.weights(frames.time(middle));
      std::vector<std::shared_ptr<const Image>> held;  // the keyframes' textures the blend reads, one frame's at a time
      std::vector<const Image*> images;
      for (int32_t key : w.keys) images.push_back(held.emplace_back(stored.texture(static_cast<size_t>(key))).get());
      interval_mse[static_cast<size_t>(k)] = disk_texture_mse(own, blend_images(images, w.weights));
    });
    const std::vector<double> targets = texture_error_targets(interval_mse, coding);
    chosen.curves.resize(keys);
    // Keyframe k's quality: the fallback where nothing was measured beside it, else its search,
    // started where `from` (a similar texture's curve; none: the whole range) meets its target.
    const auto search = [&](size_t k, const QualityCurve* from) {
      if (targets[k] < 0) {
        qualities[k] = coding.fallback_quality;
        return;
      }
      const int hint = from ? quality_hint(*from, targets[k]) : -1;
      qualities[k] = texture_quality_for(codec, *stored.texture(k), targets[k], hint, &chosen.curves[k]);
    };
    if (hints.size() == keys) {
      parallel_for(static_cast<int>(keys), threads, [&](int k) { search(static_cast<size_t>(k), &hints[static_cast<size_t>(k)]); });
    } else {
      // Keyframes in levels: every fourth searched from the whole range (every other where there
      // are under nine), then at each level those halfway between two searched, each from where the
      // errors of the neighbour whose target is nearer its own meet its target (neighbours share an
      // interval, so most often the same target). A hinted search takes two or three codings,
      // against four or five from the whole range (AV1 was 40% of Medusa's encode). The levels
      // depend on the keyframes alone: the same qualities whatever the threads.
      const size_t top = keys >= 9 ? 4 : 2;
      for (size_t stride = top; stride >= 1; stride /= 2) {
        std::vector<size_t> level;
        for (size_t k = stride == top ? 0 : stride; k < keys; k += stride == top ? top : 2 * stride) level.push_back(k);
        parallel_for(static_cast<int>(level.size()), threads, [&](int i) {
          const size_t k = level[static_cast<size_t>(i)];
          if (stride == top || targets[k] < 0) return search(k, nullptr);  // (a negative target: no distance to weigh)
          const auto distance = [&](size_t n) { return targets[n] < 0 ? HUGE_VAL : std::abs(std::log(targets[n] / targets[k])); };
          const size_t nearer = k + stride < keys && distance(k + stride) < distance(k - stride) ? k + stride : k - stride;
          search(k, &chosen.curves[nearer]);
        });
      }
    }
    for (double mse : interval_mse) chosen.interpolation_psnr.push_back(mse < 0 ? 0.0 : psnr_of_mse(mse));
  }
  chosen.qualities = std::move(qualities);
  return chosen;
}

TextureSharing share_keyframe_textures(StoredSequence& stored, const std::vector<std::filesystem::path>& images, double min_psnr) {
  const size_t keys = stored.size();
  TextureSharing sharing{std::vector<int>(keys, -1), std::vector<double>(keys, 0.0)};
  if (keys == 0 || stored.texture(0)->empty()) return sharing;
  if (images.size() != keys) throw Error(ErrorCode::kInvalidArgument, "share_textures: the keyframes are not the sequence's");
  // Each keyframe's captured image by its pixels (a file read once however many frames name it);
  // vertex colours have none.
  std::map<std::filesystem::path, uint64_t> pixels_of_file;
  std::vector<std::optional<uint64_t>> image(keys);
  for (size_t k = 0; k < keys; ++k) {
    if (images[k].empty()) continue;
    auto it = pixels_of_file.find(images[k]);
    if (it == pixels_of_file.end()) it = pixels_of_file.emplace(images[k], image_content_hash(read_image(images[k]))).first;
    image[k] = it->second;
  }
  std::map<uint64_t, int> keyframes_of_image;
  bool any = false;
  for (const std::optional<uint64_t>& pixels : image) any = any || (pixels && ++keyframes_of_image[*pixels] > 1);
  if (!any) return sharing;                        // no two keyframes were painted from one image
  std::map<uint64_t, std::vector<size_t>> owners;  // per image, the keyframes showing their own texture of it
  // What sharing may cost a keyframe: its texture coding's coarsest (min_psnr, 30 dB by default).
  // Keyframes painted from one image differ only where their registrations place the skin apart
  // (a slide of a texel or two at feature edges), which PSNR counts as error though the skin is the
  // same; a frame whose UVs changed, or whose registration failed, differs far more.
  const double allowed = mse_of_psnr(min_psnr);
  for (size_t k = 0; k < keys; ++k) {
    if (!image[k]) continue;
    std::vector<size_t>& same_image = owners[*image[k]];
    // The nearest in time first: its registration drifted least from k's.
    for (auto owner = same_image.rbegin(); owner != same_image.rend(); ++owner) {
      const std::shared_ptr<const Image> owner_texture = stored.texture(*owner);
      const double mse = disk_texture_mse(*owner_texture, *stored.texture(k));
      if (mse <= allowed) {
        stored.put_texture(k, Image(*owner_texture));
        sharing.shared_with[k] = static_cast<int>(*owner);
        sharing.psnr[k] = psnr_of_mse(mse);
        break;
      }
    }
    if (sharing.shared_with[k] < 0) same_image.push_back(k);
  }
  return sharing;
}

// ---- The encoder's texture stage: the frames' textures as it keeps them ----

std::vector<int> choose_texture_qualities(const TextureSettings& settings, const TextureFrameSource& source, const Sequence& sequence,
                                          const std::vector<int>& keyframes, EncodeReport& report) {
  return choose_texture_qualities(settings, source, *StoredSequence::of(Sequence(sequence), SpillMode::kMemory), keyframes, report);
}

std::vector<int> choose_texture_qualities(const TextureSettings& settings, const TextureFrameSource& source, const StoredSequence& stored,
                                          const std::vector<int>& keyframes, EncodeReport& report, const std::vector<QualityCurve>& hints,
                                          std::vector<QualityCurve>* curves) {
  const auto start = std::chrono::steady_clock::now();
  report.texture_qualities.clear();
  report.texture_interpolation_psnr.clear();
  FrameTextures frames;
  frames.time = [&](int i) { return source.frames[static_cast<size_t>(i)].time; };
  frames.has_texture = [&](int i) { return source.maps.has_texture(i); };
  frames.texture = [&](int i, int size) { return source.sampler.frame_texture(i, size); };
  TextureQualities chosen =
      keyframe_texture_qualities(stored, keyframes, frames, settings.quality, settings.codec, settings.coding, settings.threads, hints);
  report.texture_qualities = chosen.qualities;
  report.texture_interpolation_psnr = std::move(chosen.interpolation_psnr);
  if (curves) *curves = std::move(chosen.curves);
  report.seconds_texture = seconds_since(start);
  return std::move(chosen.qualities);
}

void share_textures(bool share, double min_psnr, const TextureFrameSource& source, Sequence& sequence, const std::vector<int>& keyframes,
                    EncodeReport& report) {
  StoredSequence::around(sequence, SpillMode::kMemory,
                         [&](StoredSequence& stored) { share_textures(share, min_psnr, source, stored, keyframes, report); });
}

void share_textures(bool share, double min_psnr, const TextureFrameSource& source, StoredSequence& stored,
                    const std::vector<int>& keyframes, EncodeReport& report) {
  const size_t keys = stored.size();
  report.texture_shared_with.assign(keys, -1);
  report.texture_share_psnr.assign(keys, 0.0);
  if (!share) return;
  // Each keyframe's image where painted from one with UVs; where `keyframes` are not the
  // sequence's, none (share_keyframe_textures refuses them if there is texture to share).
  std::vector<std::filesystem::path> images;
  if (keyframes.size() == keys) {
    images.resize(keys);
    for (size_t k = 0; k < keys; ++k) {
      const auto i = static_cast<size_t>(keyframes[k]);
      if (!source.maps.textures[i].empty() && source.maps.summaries[i].has_uvs) images[k] = source.maps.textures[i];
    }
  }
  TextureSharing sharing = share_keyframe_textures(stored, images, min_psnr);
  report.texture_shared_with = std::move(sharing.shared_with);
  report.texture_share_psnr = std::move(sharing.psnr);
}

void code_textures(const TextureSettings& settings, const TextureFrameSource& source, StoredSequence& stored,
                   const std::vector<int>& keyframes, EncodeReport& report, const std::vector<QualityCurve>& quality_hints,
                   std::vector<QualityCurve>* quality_curves) {
  choose_texture_qualities(settings, source, stored, keyframes, report, quality_hints, quality_curves);
  share_textures(settings.share, settings.coding.min_psnr, source, stored, keyframes, report);
}

}  // namespace facemorph
