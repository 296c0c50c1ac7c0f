// The texture stage: each keyframe's texture quality (from the texture blend's error beside it,
// spec/method.md §7.12), and keyframes painted from one captured image showing one texture
// (spec/method.md §7.16).
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/core/image/texture_codec.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/encode_options.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/frame_sampler.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/encode/texture_quality.hpp"

#include <filesystem>
#include <functional>
#include <vector>

namespace facemorph {

// What the texture stage reads of the capture's frames (by frame index); called from the threads.
struct FrameTextures {
  std::function<double(int)> time;         // seconds
  std::function<bool(int)> has_texture;    // whether the frame has colour to store
  std::function<Image(int, int)> texture;  // its own colour on the size × size disk texture, sampled as a keyframe's
};

struct TextureQualities {
  std::vector<int> qualities;              // per keyframe; empty for a sequence without texture
  std::vector<double> interpolation_psnr;  // auto quality: per interval, the blend's PSNR at the frame midway (0: none between)
  std::vector<QualityCurve> curves;        // auto quality: per keyframe, the errors its search measured (empty: none)
};

// Each keyframe of `stored` (frames `keyframes`) coded at `quality` of `codec`, or with
// kAutoTextureQuality at the quality that keeps its coding error within `coding`'s share of the
// interpolation error measured beside it. `hints`, one a keyframe (the curves the same keyframes'
// searches measured on another disk): each search starts where its hint meets its target
// (quality_hint). kInvalidArgument where `keyframes` are not the sequence's.
TextureQualities keyframe_texture_qualities(const StoredSequence& stored, const std::vector<int>& keyframes, const FrameTextures& frames,
                                            int quality, TextureCodec codec, const TextureQualityOptions& coding, int threads,
                                            const std::vector<QualityCurve>& hints = {});

struct TextureSharing {
  std::vector<int> shared_with;  // per keyframe: the earlier keyframe whose texture it shows, or -1
  std::vector<double> psnr;      // where shown, that texture's PSNR against its own (0 elsewhere)
};

// Keyframe k of `stored` takes the nearest earlier keyframe's texture painted from the same pixels
// (`images[k]`: its captured image; empty for vertex colours) where the two are within `min_psnr`
// dB of each other over the disk. Reads each image once.
TextureSharing share_keyframe_textures(StoredSequence& stored, const std::vector<std::filesystem::path>& images, double min_psnr);

// ---- The encoder's texture stage ----

// Exactly what the texture stage reads of the encode options (texture_settings).
struct TextureSettings {
  int quality = kAutoTextureQuality;  // the codec's quality, or kAutoTextureQuality
  TextureCodec codec = TextureCodec::kAvif;
  TextureQualityOptions coding;
  bool share = true;  // keyframes painted from one image share one texture
  int threads = 0;
};

// What the texture stage reads of the encode's frames: their times, texture paths and summaries
// (the map stage's), their colour sampled through their registrations. Holds references.
struct TextureFrameSource {
  const std::vector<CaptureFrame>& frames;
  const FrameMaps& maps;
  FrameSampler sampler;
};

// 8. Each keyframe's texture quality (settings.quality, or auto: the texture blend's error at the
// frame midway to each neighbouring keyframe, measured, and texture_quality.hpp's rule): what a
// file's SequenceFileMetadata::keyframe_texture_qualities holds. `keyframes` as given to build.
// Fills report.texture_qualities; empty for a sequence without texture. `hints`: as
// keyframe_texture_qualities reads them; `curves`: the curves its searches measured.
std::vector<int> choose_texture_qualities(const TextureSettings& settings, const TextureFrameSource& source, const StoredSequence& stored,
                                          const std::vector<int>& keyframes, EncodeReport& report,
                                          const std::vector<QualityCurve>& hints = {}, std::vector<QualityCurve>* curves = nullptr);
std::vector<int> choose_texture_qualities(const TextureSettings& settings, const TextureFrameSource& source, const Sequence& sequence,
                                          const std::vector<int>& keyframes, EncodeReport& report);
// 9. Keyframes whose textures are painted from one captured image (the same file, or the same
// pixels) share one (`share`, TextureSettings::share): keyframe k takes the nearest earlier such
// keyframe's texture where the two are within `min_psnr` (TextureSettings::coding.min_psnr) of each
// other over the disk (spec/method.md §7.16). A file stores a shared texture once (format 2.2).
// Fills report.texture_shared_with and texture_share_psnr.
void share_textures(bool share, double min_psnr, const TextureFrameSource& source, StoredSequence& stored,
                    const std::vector<int>& keyframes, EncodeReport& report);
void share_textures(bool share, double min_psnr, const TextureFrameSource& source, Sequence& sequence, const std::vector<int>& keyframes,
                    EncodeReport& report);
// 8 and 9: the texture stage as every encode runs it (one process, staged, a segment's).
void code_textures(const TextureSettings& settings, const TextureFrameSource& source, StoredSequence& stored,
                   const std::vector<int>& keyframes, EncodeReport& report, const std::vector<QualityCurve>& quality_hints = {},
                   std::vector<QualityCurve>* quality_curves = nullptr);

}  // namespace facemorph
