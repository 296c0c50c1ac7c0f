// fmbench --capture: facemorph's own encodes of the capture, through the encoder's driver steps as fmenc
// runs them, each file written, read back and measured on every frame.
#include "tools/bench_capture_parts.hpp"

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/decoder/container/sequence_file.hpp"
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

FacemorphPoints measure_facemorph(const Context& context, const CapturedFrames& c, StageSeconds& stage_seconds, TextureBaselines& texture) {
  const CaptureBenchOptions& options = context.options;
  const Plan& plan = context.plan;
  const int count = c.count;
  // facemorph, stage by stage, with fmenc's defaults (the texture smaller with --quick).
  EncodeOptions encode;
  encode.texture = c.textured;
  encode.texture_size = plan.texture_size;
  encode.residual_frames = options.residual_frames;
  Progress progress(c.label, options.quiet);
  encode.progress = [&](const std::string&, int done, int total) { progress.update(done, total); };
  SequenceFileInfo given_info;
  std::optional<Sequence> given;
  if (!options.fmv.empty()) {
    given = read_sequence_file(options.fmv, &given_info);
    const json settings = json::parse(given_info.metadata.settings.empty() ? "{}" : given_info.metadata.settings, nullptr, false);
    if (settings.is_object() && settings.contains("registration"))
      encode.registration.method = parse_registration_method(settings["registration"]);
    // The disk the file was sampled on (spec/method.md §7.11): asked (--density-equalising) or chosen
    // by bytes at equal error (density_equalising_chosen); the frames' reference texels are sampled
    // through it as the file's were, or the texture PSNR compares two parametrisations (fast24: 21.4 dB).
    if (settings.is_object()) {
      const double chosen = settings.value("density_equalising_chosen", 0.0);
      encode.density_equalising.strength = chosen > 0 ? chosen : settings.value("density_equalising", encode.density_equalising.strength);
    }
    encode.representation = given->representation;
  }
  SequenceEncoder encoder(c.capture, encode);
  auto timed = [&](const char* stage, auto&& body) {
    const auto start = std::chrono::steady_clock::now();
    body();
    stage_seconds[stage] += seconds_since(start);
  };
  timed("mapping", [&] { map_frames(encoder); });
  timed("registration", [&] { register_frames(encoder); });
  timed("sampling", [&] { sample_frames(encoder); });
  // fmenc's order: the keyframes first, then the grid their predicted error allows.
  FacemorphPoints points;
  KeyframeSelection main_chosen;
  if (!given) timed("selection", [&] { main_chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection()); });
  int& grid = points.grid;
  timed("grid", [&] {
    grid = given ? given->grid_n : choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report(), &main_chosen);
  });
  if (!given) timed("representation", [&] { adopt_chosen_representation(encoder, main_chosen, grid); });
  Representation main_representation = given ? given->representation : encoder.representation();
  progress.finish();

  // Facemorph's texture PSNR per frame (and the baselines' on the sample frames) as frames decode.
  auto measure = [&](const std::string& name, double budget, const std::vector<int>& keyframes, const Sequence& sequence, uint64_t bytes,
                     const SequenceFileInfo& info, bool all_textures,
                     const std::function<void(int, const DiskTexels&, const DecodedFrame&)>& also = {}) {
    Encoded out;
    out.label = name;
    out.budget = budget;
    out.keyframes = keyframes;
    out.bytes = bytes;
    out.info = info;
    out.texture_bytes = chunk_bytes(info, "TEXR") + chunk_bytes(info, "TGOP");  // stills, or one sequence per group (2.1)
    out.evaluation = evaluate(encoder, sequence, keyframes, c.meshes, c.every, false, [&](int i, const DecodedFrame& decoded) {
      const bool measured =
          c.textured && !decoded.texture.empty() && (all_textures || std::binary_search(c.sample.begin(), c.sample.end(), i));
      if (!measured && !also) return;
      if (!measured) return also(i, DiskTexels{}, decoded);
      const Image source = read_image(c.textures[static_cast<size_t>(i)]);
      const DiskTexels texels = disk_texels(encoder, i, source, decoded.texture.width);
      out.psnr[i] = psnr_of_disk(texels, decoded.texture);
      out.pixel_psnr[i] = pixel_psnr_of_disk(texels, decoded.texture);
      if (out.pixel_psnr.size() == 1) out.density = texel_density(texels, encoder.frame(i)->map.surface, source.width, source.height);
      if (also) also(i, texels, decoded);
    });
    for (const auto& [i, db] : out.psnr) out.evaluation.frames[static_cast<size_t>(i)].psnr = db;  // frames_to_decode is every frame
    return out;
  };
  // As fmenc stores it: the driver's steps once the keyframes are chosen (SequenceEncoder::code: the
  // keyframes built, their fields rounded, the residual frames fitted to them as stored, the
  // textures' qualities and sharing), the file written with the coding they chose and read back.
  // An unset representation is the encoder's to choose, with N, by bytes at equal error, as fmenc's is
  // (SequenceEncoder::choose_by_bytes; the main point only).
  auto encode_file = [&](const KeyframeSelection& chosen, int n, std::optional<Representation> representation, std::vector<uint8_t>& bytes,
                         SequenceFileInfo& info) {
    const std::string variant = representation == Representation::kXYZ && main_representation != Representation::kXYZ ? " (xyz)" : "";
    encoder.options().representation = representation;
    const std::unique_ptr<StoredSequence> stored = encoder.code(stage_settings(encoder.options()), chosen, n);
    const EncodeReport& r = encoder.report();
    stage_seconds["keyframes" + variant] += r.seconds_keyframes;
    if (encoder.options().predicted_fields) stage_seconds["field precision" + variant] += r.seconds_precision;
    if (encoder.options().residual_frames) stage_seconds["residual frames" + variant] += r.residual_fit.seconds;
    stage_seconds["texture quality" + variant] += r.seconds_texture;
    Sequence back;
    timed(("file" + variant).c_str(),
          [&] { back = file_round_trip(stored->to_sequence(), r.texture_qualities, &bytes, &info, r.field_coding); });
    return back;
  };

  // The texture baselines are measured while facemorph's main encode decodes (one pass over the
  // captured textures): JPEG at every quality, and H.264 at every CRF.
  std::unique_ptr<H264Readers> h264;
  if (c.textured) {
    Progress h264_progress(c.label + " h264", true);
    int width = 0, height = 0;
    const auto start = std::chrono::steady_clock::now();
    texture.h264_bytes = encode_h264(c.textures, c.capture.fps, plan.h264_crf, c.scratch, width, height);
    stage_seconds["baseline h264 encode"] = seconds_since(start);
    h264 = std::make_unique<H264Readers>(plan.h264_crf, c.scratch, width, height);
  }
  auto baselines_at = [&](int i, const DiskTexels& texels, const DecodedFrame&) {
    if (!h264) return;
    const std::vector<Image> videos = h264->next();  // every frame is read, the sample ones measured
    if (texels.texel.empty() || !std::binary_search(c.sample.begin(), c.sample.end(), i)) return;
    for (size_t k = 0; k < plan.h264_crf.size(); ++k) texture.h264_psnr[plan.h264_crf[k]].push_back(psnr_of_copy(texels, videos[k]));
    const Image source = rgb_of(read_image(c.textures[static_cast<size_t>(i)]));
    for (int q : plan.jpeg_quality) {
      const std::vector<uint8_t> jpeg = encode_image(source, ".jpg", q);
      texture.jpeg_sample_bytes[q] += jpeg.size();
      texture.jpeg_psnr[q].push_back(psnr_of_copy(texels, decode_image(jpeg, "jpeg")));
    }
  };

  // The main point: fmenc's default budget (or the file given), every frame's texture measured.
  std::vector<uint8_t> main_bytes;
  SequenceFileInfo main_info;
  Sequence main_sequence;
  std::vector<int>& main_keys = points.main_keys;
  if (given) {
    for (const Keyframe& key : given->keyframes) main_keys.push_back(nearest_frame(c.capture, key.time));
    main_chosen.keyframes = main_keys;  // without predicted errors the xyz variant gets auto field error's default (1e-4)
    main_sequence = *given;
    main_info = given_info;
    main_bytes.resize(given_info.file_bytes);
  } else {
    main_keys = main_chosen.keyframes;
    main_sequence = encode_file(main_chosen, grid, encode.representation ? std::optional(main_representation) : std::nullopt, main_bytes,
                                main_info);
    main_representation = main_sequence.representation;
    grid = main_sequence.grid_n;
  }
  points.residual_frames = main_sequence.residuals.size();
  points.shown = [&] {
    for (int d = 0; d < count; ++d) {
      for (int i : {count / 2 - d, count / 2 + d}) {
        if (i >= 0 && i < count && !std::binary_search(main_keys.begin(), main_keys.end(), i)) return i;
      }
    }
    return count / 2;
  }();
  const auto decode_start = std::chrono::steady_clock::now();
  points.main = measure(given ? "facemorph (" + options.fmv + ")" : "facemorph", encode.keyframe_fraction, main_keys, main_sequence,
                        main_bytes.size(), main_info, true, [&](int i, const DiskTexels& texels, const DecodedFrame& decoded) {
                          baselines_at(i, texels, decoded);
                          if (i == points.shown) points.shown_decoded = decoded;
                        });
  stage_seconds["measuring facemorph and the texture baselines"] = seconds_since(decode_start);
  h264.reset();

  // Facemorph's xyz variant: the same keyframes, grid and spline.
  std::vector<uint8_t> xyz_bytes;
  SequenceFileInfo xyz_info;
  const Sequence xyz_sequence = encode_file(main_chosen, grid, Representation::kXYZ, xyz_bytes, xyz_info);
  points.xyz = measure("facemorph xyz", points.main.budget, main_keys, xyz_sequence, xyz_bytes.size(), xyz_info, false);
  encoder.options().representation = encode.representation;

  // Keyframe budgets: facemorph's rate-distortion curve (and xyz's), texture on the sample frames.
  for (double budget : plan.budgets) {
    if (!given && std::abs(budget - encode.keyframe_fraction) < 1e-9) {
      points.curve.push_back(points.main);
      points.xyz_curve.push_back(points.xyz);
      continue;
    }
    encoder.options().keyframe_fraction = budget;
    const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
    const int budget_grid = given ? grid
                                  : choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report(),
                                                &chosen);  // as fmenc would for this budget
    std::vector<uint8_t> bytes;
    SequenceFileInfo info;
    const Sequence sequence = encode_file(chosen, budget_grid, main_sequence.representation, bytes, info);
    points.curve.push_back(measure("facemorph", budget, chosen.keyframes, sequence, bytes.size(), info, false));
    const Sequence xyz_at = encode_file(chosen, budget_grid, Representation::kXYZ, bytes, info);
    points.xyz_curve.push_back(measure("facemorph xyz", budget, chosen.keyframes, xyz_at, bytes.size(), info, false));
    encoder.options().representation = encode.representation;
    if (!options.quiet) std::fprintf(stderr, "fmbench --capture: %s: keyframe budget %g%% measured\n", c.label.c_str(), 100 * budget);
  }
  encoder.options().keyframe_fraction = encode.keyframe_fraction;
  return points;
}

}  // namespace facemorph::tools::capture_bench
