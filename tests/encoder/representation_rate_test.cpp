// The representation chosen by bytes at equal error (representation_rate.hpp, spec/method.md §7.14):
// the rule on constructed candidates, the frames it measures, and the encoder's choice end to end.
#include "codec/encoder/encode/representation_rate.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/stages/choose_grid.hpp"
#include "codec/encoder/synth/synth.hpp"

#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

namespace facemorph {
namespace {

RateCandidate candidate(Representation r, uint64_t bytes, double rms, int grid = 257, bool coarser = false, int frames = 8) {
  return {r, grid, coarser, bytes, rms, frames};
}

// The frame patches' default bound (EncodeOptions::patch_bound): the worst trial p99 any candidate may reach.
constexpr double kPatchBound = 0.01;

// Where one candidate is clearly smaller at the same error it is kept, whichever it is; an error
// lower by more than the exchange rate pays for more bytes; nothing measured keeps the fields.
TEST(RepresentationRate, TheSmallerAtEqualErrorIsKept) {
  using enum Representation;
  // The same error: the fewer bytes.
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 55924, 0.002), candidate(kXYZ, 41178, 0.002)), kXYZ);
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 41178, 0.002), candidate(kXYZ, 55924, 0.002)), kHLT);
  // The same bytes: the lower error.
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.0021), candidate(kXYZ, 10000, 0.0020)), kXYZ);
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.0020), candidate(kXYZ, 10000, 0.0021)), kHLT);
  // 20% fewer bytes is worth up to 1/0.8 = 1.25 times the bytes, an error (1.25)^(1/2) = 1.118 times higher.
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.0020), candidate(kXYZ, 8000, 0.0022)), kXYZ);   // 1.10x
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.0020), candidate(kXYZ, 8000, 0.0023)), kHLT);   // 1.15x
  // A rotating head as §5.2 measured it (30°: the positions' chords 1.39x farther) at the 6-12%
  // fewer bytes xyz took on ICT: the fields kept.
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.0074), candidate(kXYZ, 8900, 0.0103)), kHLT);
  // A tie keeps the fields; a candidate not measured is never chosen.
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.002), candidate(kXYZ, 10000, 0.002)), kHLT);
  RateCandidate unmeasured = candidate(kXYZ, 100, 0.0001);
  unmeasured.frames = 0;
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.002), unmeasured), kHLT);
  EXPECT_EQ(cheaper_at_equal_error(candidate(kHLT, 10000, 0.002), candidate(kXYZ, 100, 0)), kHLT);  // no error read: not measured
  EXPECT_TRUE(std::isinf(rate_cost(unmeasured)));
  EXPECT_DOUBLE_EQ(rate_cost(candidate(kHLT, 1000, 0.5)), 1000 * std::pow(0.5, kRateErrorExponent));
}

// A coarser N competes only within the tolerance; at --grid auto's N every candidate does.
TEST(RepresentationRate, ACoarserGridIsKeptOnlyWithinTheTolerance) {
  using enum Representation;
  const std::vector<RateCandidate> ict2k = {candidate(kHLT, 53370, 0.002064), candidate(kXYZ, 50244, 0.002080),
                                            candidate(kHLT, 18923, 0.003061, 129, true), candidate(kXYZ, 14666, 0.003061, 129, true)};
  EXPECT_EQ(cheapest_at_equal_error(ict2k, 0.005, kPatchBound, false), 3u);  // ict2k24 as measured: xyz at N = 129
  EXPECT_EQ(cheapest_at_equal_error(ict2k, 0.003, kPatchBound, false), 1u);  // a tolerance under N = 129's error: xyz at 257
  std::vector<RateCandidate> far = ict2k;
  far[3].held_rms = 0.0045;  // within the tolerance, but 2.2x the error for 3.4x fewer bytes
  far[2].held_rms = 0.0045;
  EXPECT_EQ(cheapest_at_equal_error(far, 0.005, kPatchBound, false), 1u);
  // Two at the planned N: the rule of two.
  EXPECT_EQ(cheapest_at_equal_error({ict2k[0], ict2k[1]}, 0.005, kPatchBound, false), 1u);
  EXPECT_EQ(cheapest_at_equal_error({ict2k[0]}, 0.005, kPatchBound, false), 0u);

  EXPECT_EQ(worst_region_grid({{97, 0.00966}, {129, 0.00602}, {193, 0.0014}, {257, 0.00053}}, 0.0075, 257), 129);
  EXPECT_EQ(worst_region_grid({{129, 0.0195}, {193, 0.00809}, {257, 0.0005}}, 0.0075, 257), 0);  // ict24: none coarser
  EXPECT_EQ(worst_region_grid({{33, 0.002}, {41, 0.001}}, 0.0075, 33), 0);  // nothing coarser than N
}

// Where the capture's own error puts every candidate over the tolerance (its noise), a coarser one
// that adds none competes: within the tolerance, or no larger than the lowest held-out RMS at N.
TEST(RepresentationRate, ACoarserCandidateThatAddsNoErrorCompetesOverTheTolerance) {
  using enum Representation;
  // fmsynth --noise 0.002 --frames 12 as measured (N = 49; the field step x2 of xyz at N).
  std::vector<RateCandidate> noisy = {candidate(kHLT, 27955, 0.008379, 49), candidate(kXYZ, 11065, 0.006611, 49),
                                      candidate(kXYZ, 7024, 0.006594, 49, true)};
  EXPECT_TRUE(coarser_within_tolerance(noisy, 2, 0.005));
  EXPECT_EQ(cheapest_at_equal_error(noisy, 0.005, kPatchBound, false), 2u);
  // A candidate at N measured after it with a lower error (the density-equalised disk's, 11,151 B at
  // 0.6590%) does not take the admission back: the file stored is the one the report keeps.
  std::vector<RateCandidate> later = noisy;
  later.push_back(candidate(kXYZ, 11151, 0.006590, 49));
  EXPECT_TRUE(coarser_within_tolerance(later, 2, 0.005));
  EXPECT_EQ(cheapest_at_equal_error(later, 0.005, kPatchBound, false), 2u);
  // More error than xyz at N (though less than hl+t's, the first): over the tolerance, refused.
  noisy[2].held_rms = 0.0067;
  EXPECT_FALSE(coarser_within_tolerance(noisy, 2, 0.005));
  EXPECT_EQ(cheapest_at_equal_error(noisy, 0.005, kPatchBound, false), 1u);
  // Within the tolerance: competes whatever the others' error, as before.
  noisy[2].held_rms = 0.0049;
  EXPECT_TRUE(coarser_within_tolerance(noisy, 2, 0.005));
  // Not coarser: always competes.
  EXPECT_TRUE(coarser_within_tolerance(noisy, 0, 0.005));
}

// The kept candidate is tried once more at a coarser field step (coarser_step_candidate): the same
// representation and N, twice the target, nothing measured yet; kept by the same rule, and like a
// coarser N only within the tolerance.
TEST(RepresentationRate, TheKeptCandidateIsTriedAtACoarserFieldStep) {
  using enum Representation;
  const std::vector<RateCandidate> ict2k = {candidate(kHLT, 53370, 0.002064), candidate(kXYZ, 50244, 0.002080),
                                            candidate(kXYZ, 15674, 0.002259, 129, true)};
  const RateCandidate again = coarser_step_candidate(ict2k, 0.005, kPatchBound, false);
  EXPECT_EQ(again.representation, kXYZ);
  EXPECT_EQ(again.grid, 129);
  EXPECT_TRUE(again.coarser);
  EXPECT_DOUBLE_EQ(again.step_scale, kCoarserStepScale);
  EXPECT_EQ(again.frames, 0);
  EXPECT_TRUE(std::isinf(rate_cost(again)));  // not measured: never kept as it is
  // A tolerance the coarser N does not meet: the step is tried at the planned N's winner.
  EXPECT_EQ(coarser_step_candidate(ict2k, 0.002, kPatchBound, false).grid, 257);
  // Measured as fmbench's xyz row was (12,649 B at 0.2400%): bytes x RMS^2 729 against 800, kept.
  std::vector<RateCandidate> measured = ict2k;
  measured.push_back(candidate(kXYZ, 12649, 0.002400, 129, true));
  EXPECT_EQ(cheapest_at_equal_error(measured, 0.005, kPatchBound, false), 3u);
  // The same bytes for an error the exchange rate does not pay for: the step's target kept.
  measured.back().held_rms = 0.0026;
  EXPECT_EQ(cheapest_at_equal_error(measured, 0.005, kPatchBound, false), 2u);
  // Cheaper, but over the tolerance: not kept.
  measured.back().held_rms = 0.0024;
  EXPECT_EQ(cheapest_at_equal_error(measured, 0.0023, kPatchBound, false), 2u);
}

// An error under two fifths of the tolerance is not bought (kUnboughtErrorShare): ICT from 10.0 s
// decimated to 2k vertices, a face nearly still, its candidates as fmenc measured them (keyframes'
// bytes, held-out RMS on 8 frames). G's floor dominates there, so by bytes x RMS^2 alone every finer
// N paid, and N = 257 at 0.0755% was kept (61,743 B file); read at no less than 0.2%, the coarsest
// N within the tolerance is. Above the floor the exchange rate is as before.
TEST(RepresentationRate, AnErrorUnderTwoFifthsOfTheToleranceIsNotBought) {
  using enum Representation;
  const auto on_d = [](RateCandidate c, double step_scale = 1) {
    c.density_equalising = 0.5;
    c.step_scale = step_scale;
    return c;
  };
  std::vector<RateCandidate> still = {candidate(kHLT, 154427, 0.000895),
                                      candidate(kXYZ, 74539, 0.000896),
                                      candidate(kXYZ, 25048, 0.002165, 129, true),
                                      on_d(candidate(kXYZ, 77293, 0.000737)),
                                      on_d(candidate(kXYZ, 20957, 0.002203, 113, true)),
                                      on_d(candidate(kXYZ, 61355, 0.000755, 257, true), kCoarserStepScale)};
  EXPECT_LT(rate_cost(still[5]), rate_cost(still[4]));                       // bytes x RMS^2 as measured: N = 257
  EXPECT_EQ(cheapest_at_equal_error(still, 0.005, kPatchBound, false), 4u);  // within the 0.5% tolerance: N = 113
  EXPECT_DOUBLE_EQ(rate_cost(still[5], 0.005), 61355 * std::pow(0.002, kRateErrorExponent));
  EXPECT_DOUBLE_EQ(rate_cost(still[4], 0.005), rate_cost(still[4]));  // over the floor: as measured
  // A tighter tolerance (--max-error 0.25%) lowers the floor to 0.1%, and the finer error pays again.
  EXPECT_EQ(cheapest_at_equal_error(still, 0.0025, kPatchBound, false), 5u);
  // Two candidates over the floor are weighed as before, whatever the tolerance.
  const std::vector<RateCandidate> moving = {candidate(kHLT, 10000, 0.0030), candidate(kXYZ, 8000, 0.0034)};
  EXPECT_EQ(cheapest_at_equal_error(moving, 0.005, kPatchBound, false), 0u);  // 90,000 against 92,480
  EXPECT_EQ(cheapest_at_equal_error(moving, 0, kPatchBound, false), 0u);
}

// Bytes x RMS^2 weigh the mean; the worst region is held apart: a candidate other than the first is
// admitted only where its worst trial p99 is within the patches' bound, or within kWorstRegionRise
// times the first's (no worse than it with the patches off: admitted_worst_region). Here the coarser
// step is the cheapest by bytes x RMS^2 and is refused.
TEST(RepresentationRate, ACandidateWorseInTheWorstRegionIsRefused) {
  using enum Representation;
  const auto with_p99 = [](RateCandidate c, double p99) {
    c.worst_p99 = p99;
    return c;
  };
  // The first under the bound: another may rise to the bound, or to 1.25 times the first's 0.80%.
  std::vector<RateCandidate> under = {with_p99(candidate(kHLT, 53370, 0.002064), 0.0080), with_p99(candidate(kXYZ, 50244, 0.002080), 0.0095),
                                      with_p99(candidate(kXYZ, 15674, 0.002259, 129, true), 0.0100)};
  EXPECT_EQ(cheapest_at_equal_error(under, 0.005, kPatchBound, false), 2u);  // at the bound exactly: admitted
  RateCandidate step = with_p99(candidate(kXYZ, 12649, 0.002400, 129, true), 0.0104);
  step.step_scale = kCoarserStepScale;
  under.push_back(step);
  EXPECT_LT(rate_cost(under[3]), rate_cost(under[2]));               // the cheaper by bytes x RMS^2 ...
  EXPECT_EQ(cheapest_at_equal_error(under, 0.005, kPatchBound, false), 2u);  // ... refused: past the bound and 1.3x the first's
  EXPECT_FALSE(admitted_worst_region(under[3], under[0], kPatchBound));
  under[3].worst_p99 = 0.0099;
  EXPECT_EQ(cheapest_at_equal_error(under, 0.005, kPatchBound, false), 3u);  // within the bound: kept
  // The first over the bound (the patches bring its frames under): another within 1.25 times it.
  std::vector<RateCandidate> over = {with_p99(candidate(kHLT, 10000, 0.0020), 0.0130), with_p99(candidate(kXYZ, 8000, 0.0020), 0.0160)};
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, kPatchBound, false), 1u);  // 1.23x: admitted
  over[1].worst_p99 = 0.0165;
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, kPatchBound, false), 0u);  // 1.27x: refused
  // The patches off (bound 0): nothing worse than the first, however far under 1%.
  over[0].worst_p99 = 0.004;
  over[1].worst_p99 = 0.0041;
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, 0, false), 0u);
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, kPatchBound, false), 1u);
  over[1].worst_p99 = 0.004;
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, 0, false), 1u);  // no worse: admitted
  over[1].worst_p99 = std::nan("");  // not measured: not admitted
  EXPECT_EQ(cheapest_at_equal_error(over, 0.005, kPatchBound, false), 0u);
  // The step is tried on the admitted candidate, not the cheapest refused one.
  under.pop_back();
  under[2].worst_p99 = 0.0110;
  EXPECT_EQ(coarser_step_candidate(under, 0.005, kPatchBound, false).grid, 257);
  EXPECT_EQ(coarser_step_candidate(under, 0.005, kPatchBound, false).representation, kXYZ);
}

// On the keyframes alone (nothing predicted) every candidate was built to the same targets, so one
// that costs more bytes than the first buys only error below the user's tolerance: not kept, though
// the exchange rate alone keeps it (ICT's single frame as measured: xyz +51% bytes for -21% RMS).
// The same candidates between keyframes keep it; fewer or equal bytes on the keyframes still compete.
TEST(RepresentationRate, OnTheKeyframesAloneNoCandidateCostsMoreBytesThanTheFirst) {
  using enum Representation;
  const std::vector<RateCandidate> ict = {candidate(kHLT, 16937, 0.002144), candidate(kXYZ, 25510, 0.001686)};
  ASSERT_LT(rate_cost(ict[1]), rate_cost(ict[0]));  // the exchange rate alone keeps xyz
  // (At a tolerance of 0.4%, whose two fifths, 0.16%, are under xyz's 0.1686%: at 0.5% xyz's error
  // would read as the 0.2% no candidate is credited below, and the floor alone would refuse it.)
  EXPECT_EQ(cheapest_at_equal_error(ict, 0.004, kPatchBound, false), 1u);
  EXPECT_EQ(cheapest_at_equal_error(ict, 0.004, kPatchBound, true), 0u);
  EXPECT_TRUE(buys_only_error_below_the_target(ict[1], ict[0], true));
  EXPECT_FALSE(buys_only_error_below_the_target(ict[1], ict[0], false));
  // N's winner on the keyframes is then the fields, and the coarser N is tried in them.
  const auto met = [] { return 0.0061; };
  EXPECT_EQ(coarser_candidates(ict, 0.004, kPatchBound, true, 129, met, 0.0075),
            (std::vector<std::pair<Representation, int>>{{kHLT, 129}}));
  EXPECT_EQ(coarser_candidates(ict, 0.004, kPatchBound, false, 129, met, 0.0075),
            (std::vector<std::pair<Representation, int>>{{kXYZ, 129}}));
  // Fewer bytes at a lower error (the sample's frame 0), or the same bytes: still chosen by the rate.
  EXPECT_EQ(cheapest_at_equal_error({candidate(kHLT, 1132, 0.002393), candidate(kXYZ, 1050, 0.002324)}, 0.005, kPatchBound, true), 1u);
  EXPECT_EQ(cheapest_at_equal_error({candidate(kHLT, 1000, 0.0024), candidate(kXYZ, 1000, 0.0020)}, 0.005, kPatchBound, true), 1u);
  EXPECT_EQ(cheapest_at_equal_error({candidate(kHLT, 1000, 0.0024), candidate(kXYZ, 1001, 0.0020)}, 0.005, kPatchBound, true), 0u);
  // A coarser N with fewer bytes (ict2k24's 129 after xyz refused at 257) is kept on the keyframes.
  const std::vector<RateCandidate> ict2k = {candidate(kHLT, 8644, 0.002283), candidate(kXYZ, 9500, 0.002100),
                                            candidate(kXYZ, 7908, 0.002310, 129, true)};
  EXPECT_EQ(cheapest_at_equal_error(ict2k, 0.005, kPatchBound, true), 2u);
  EXPECT_EQ(cheapest_at_equal_error({ict2k[0], ict2k[1]}, 0.005, kPatchBound, true), 0u);
}

// The coarser N is tried in N's winner alone: xyz on ict2k24, hl+t on fmsynth's 30° turning head
// (both as measured, §7.14); none where no N is coarser.
TEST(RepresentationRate, TheCoarserGridIsTriedInTheWinnerAtN) {
  using enum Representation;
  using Tried = std::vector<std::pair<Representation, int>>;
  int decoded = 0;
  const auto met = [&] { ++decoded; return 0.0061; };
  const std::vector<RateCandidate> ict2k = {candidate(kHLT, 53370, 0.002064), candidate(kXYZ, 50244, 0.002080)};
  EXPECT_EQ(coarser_candidates(ict2k, 0.005, kPatchBound, false, 129, met, 0.0075), (Tried{{kXYZ, 129}}));
  EXPECT_EQ(decoded, 0);  // positions won at N: the fields' floor is not decoded
  const std::vector<RateCandidate> rot30 = {candidate(kHLT, 4151, 0.002582), candidate(kXYZ, 5010, 0.002434)};
  EXPECT_EQ(coarser_candidates(rot30, 0.005, kPatchBound, false, 33, met, 0.0075), (Tried{{kHLT, 33}}));
  EXPECT_EQ(coarser_candidates({ict2k[0]}, 0.005, kPatchBound, false, 129, met, 0.0075), (Tried{{kHLT, 129}}));  // xyz did not converge at N
  EXPECT_TRUE(coarser_candidates(ict2k, 0.005, kPatchBound, false, 0, met, 0.0075).empty());
}

// The fields at the coarser N are a candidate only where the reference rebuilt from them meets the
// worst region's share: the resampled floor that allowed the N is not what a decoder shows (§7.6's
// whole head: 0.48% resampled, 3.79% decoded). Positions decode as sampled: tried there instead.
TEST(RepresentationRate, TheFieldsAtACoarserGridAreTriedOnlyWhereTheirDecodedFloorMeetsTheShare) {
  using enum Representation;
  using Tried = std::vector<std::pair<Representation, int>>;
  const std::vector<RateCandidate> fields_won = {candidate(kHLT, 4151, 0.002582), candidate(kXYZ, 5010, 0.002434)};
  const auto floor = [](double p99) { return [p99] { return p99; }; };
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 129, floor(0.0061), 0.0075), (Tried{{kHLT, 129}}));
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 129, floor(0.0075), 0.0075), (Tried{{kHLT, 129}}));  // met exactly
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 33, floor(0.0379), 0.0075), (Tried{{kXYZ, 33}}));  // the whole head's decoded floor
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 33, floor(0.0076), 0.0075), (Tried{{kXYZ, 33}}));
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 33, floor(std::numeric_limits<double>::infinity()), 0.0075), (Tried{{kXYZ, 33}}));  // not rebuilt
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 33, floor(std::nan("")), 0.0075), (Tried{{kXYZ, 33}}));
  EXPECT_EQ(coarser_candidates(fields_won, 0.005, kPatchBound, false, 33, floor(0.012), 0.0125), (Tried{{kHLT, 33}}));  // a noisy capture's raised share
}

TEST(RepresentationRate, TrialFramesAreSpreadBetweenTheKeyframes) {
  EXPECT_EQ(rate_trial_frames({0, 1, 2}), (std::vector<int>{0, 1, 2}));  // nothing between: the keyframes themselves
  EXPECT_EQ(rate_trial_frames({0}), std::vector<int>{0});                // one frame
  EXPECT_EQ(rate_trial_frames({0, 1, 3}), std::vector<int>{2});          // one frame between: it alone, no keyframe
  EXPECT_EQ(rate_trial_frames({0, 3, 5}), (std::vector<int>{1, 2, 4}));
  std::vector<int> every(20);
  for (int i = 0; i < 20; ++i) every[static_cast<size_t>(i)] = i;
  const std::vector<int> keys = rate_trial_frames(every);  // every frame a keyframe: 8 of them, ends kept
  ASSERT_EQ(keys.size(), static_cast<size_t>(kRateTrials));
  EXPECT_EQ(keys.front(), 0);
  EXPECT_EQ(keys.back(), 19);
  const std::vector<int> spread = rate_trial_frames({0, 23});  // 22 frames between: 8 of them, ends kept
  ASSERT_EQ(spread.size(), static_cast<size_t>(kRateTrials));
  EXPECT_EQ(spread.front(), 1);
  EXPECT_EQ(spread.back(), 22);
  for (size_t i = 1; i < spread.size(); ++i) EXPECT_GT(spread[i], spread[i - 1]);
}

// The encoder's defaults without textures, on two threads: what the end-to-end tests encode with.
EncodeOptions untextured() {
  EncodeOptions options;
  options.texture = false;
  options.threads = 2;
  return options;
}

// End to end on a turning head (fmsynth's face, 30°): both candidates measured, the file stores the
// one the rule picks, and that is hl+t (its keyframes take fewer bytes at an error within 1%; the
// positions do not pay here). Each candidate's bytes are those its representation alone gives.
TEST(SequenceEncoder, TheRepresentationIsChosenByBytesAtEqualError) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 30);
  const EncodeOptions options = untextured();
  EncodeReport report;
  const Sequence chosen = encode_capture(capture, options, &report);
  const RepresentationRate& rate = report.representation_rate;
  ASSERT_TRUE(rate.measured);
  ASSERT_GE(rate.candidates.size(), 2u);
  const RateCandidate& fields = rate.candidates[0];
  const RateCandidate& positions = rate.candidates[1];
  EXPECT_EQ(fields.representation, Representation::kHLT);
  EXPECT_EQ(positions.representation, Representation::kXYZ);
  EXPECT_EQ(fields.grid, positions.grid);
  for (const RateCandidate& c : rate.candidates) {
    EXPECT_EQ(c.coarser, c.grid != fields.grid || c.step_scale != 1) << "a coarser N or field step is held to the tolerance";
    EXPECT_GT(c.bytes, 500u);
    EXPECT_GT(c.held_rms, 0);
    EXPECT_LT(c.held_rms, 0.01);  // a decoded face, not a failed one
    EXPECT_GE(c.frames, 1);
  }
  EXPECT_EQ(rate.chosen, cheapest_at_equal_error(rate.candidates, rate.tolerance, rate.worst_bound, rate.on_keyframes));
  const RateCandidate& kept = rate.candidates[rate.chosen];
  // Each candidate's worst region measured on the trial frames, and the kept one admitted for it.
  EXPECT_DOUBLE_EQ(rate.worst_bound, options.patch_bound);
  for (const RateCandidate& c : rate.candidates) {
    EXPECT_GT(c.worst_p99, 0);
    EXPECT_LT(c.worst_p99, 0.05);
  }
  EXPECT_TRUE(admitted_worst_region(kept, fields, rate.worst_bound));
  EXPECT_EQ(report.representation, kept.representation);
  EXPECT_EQ(chosen.representation, kept.representation);
  EXPECT_EQ(chosen.grid_n, kept.grid);
  EXPECT_EQ(report.representation, Representation::kHLT);
  // A coarser N: the fields there were decoded once and tried only within the worst region's share;
  // kept, the rounding's p99 budget is what their decoded floor left of the 1%.
  for (const RateCandidate& c : rate.candidates) {
    if (c.grid == fields.grid) continue;
    const auto floor = std::find_if(report.grid_decoded_floors.begin(), report.grid_decoded_floors.end(),
                                    [&](const EncodeReport::DecodedFloor& d) { return d.n == c.grid; });
    ASSERT_NE(floor, report.grid_decoded_floors.end()) << "N = " << c.grid;
    if (c.representation != Representation::kHLT) continue;
    EXPECT_LE(floor->p99, report.grid_worst_target);
    if (&c == &kept) {
      double resampled = 0;
      for (const auto& [n, p99] : report.grid_floor_p99s) {
        if (n == c.grid) resampled = p99;
      }
      const double target = kWorstRegionTarget * std::max(1.0, report.grid_worst_target / kGridWorstTarget);
      EXPECT_NEAR(report.field_precision.rounding_p99_budget, target - std::max(resampled, floor->p99), 1e-12);
    }
  }
  // The conformal disk's last candidate: the one kept of those before it, at twice the rounding's
  // target (the density-equalised disk's come after it); kept or not, the stored rounding's p99s are
  // within the worst region's budget.
  const auto step_at = std::find_if(rate.candidates.begin(), rate.candidates.end(),
                                    [](const RateCandidate& c) { return c.step_scale != 1 && c.density_equalising == 0; });
  ASSERT_NE(step_at, rate.candidates.end()) << "the coarser field step is tried on the conformal disk";
  const RateCandidate& step = *step_at;
  EXPECT_DOUBLE_EQ(step.step_scale, kCoarserStepScale);
  const std::vector<RateCandidate> before(rate.candidates.begin(), step_at);
  const RateCandidate& kept_before = before[cheapest_at_equal_error(before, rate.tolerance, rate.worst_bound, rate.on_keyframes)];
  EXPECT_EQ(step.representation, kept_before.representation);
  EXPECT_EQ(step.grid, kept_before.grid);
  EXPECT_LT(step.bytes, kept_before.bytes) << "rounded coarser: fewer bytes";
  for (const RateCandidate& c : before) EXPECT_DOUBLE_EQ(c.step_scale, 1);
  if (report.field_precision.rounding_p99_budget > 0) {
    for (const double q : report.field_precision.keyframe_p99s) EXPECT_LE(q, report.field_precision.rounding_p99_budget);
  }
  // The rounded keyframes as either representation asked for alone: the same bytes. The candidates
  // are measured before frame patches are fitted to the file's choice (xyz here patches a frame the
  // rounding took over the bound: 59 B more), so the forced encodes fit none.
  for (const Representation r : {Representation::kHLT, Representation::kXYZ}) {
    EncodeOptions forced = options;
    forced.representation = r;
    forced.patch_bound = 0;
    EncodeReport forced_report;
    const std::unique_ptr<StoredSequence> stored = encode_capture_stored(capture, forced, &forced_report);
    EXPECT_FALSE(forced_report.representation_rate.measured);  // asked for: nothing chosen
    EXPECT_EQ(geometry_bytes(*stored, forced_report.field_coding), r == Representation::kHLT ? fields.bytes : positions.bytes);
  }
}

// Where --grid auto's worst region allows a coarser N, the reference's fields there are decoded once
// and the floor reported; the fields are a candidate there only within the share, and where kept the
// rounding's p99 budget is what the larger of the two floors leaves of the 1%. The face looks ahead
// (0°): the fields win at N = 81 there, so the coarser N is tried in them (turned 60°, positions,
// rounded each to its nearest step, win at N and the coarser N is theirs).
TEST(SequenceEncoder, TheFieldsAtACoarserGridAreHeldToTheirDecodedFloor) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 0);
  EncodeReport report;
  encode_capture(capture, untextured(), &report);
  const RepresentationRate& rate = report.representation_rate;
  ASSERT_TRUE(rate.measured);
  const int grid = rate.candidates[0].grid;
  const auto coarser =
      std::find_if(rate.candidates.begin(), rate.candidates.end(), [&](const RateCandidate& c) { return c.grid != grid; });
  ASSERT_NE(coarser, rate.candidates.end()) << "no coarser N on this capture";
  const auto floor = std::find_if(report.grid_decoded_floors.begin(), report.grid_decoded_floors.end(),
                                  [&](const EncodeReport::DecodedFloor& d) { return d.n == coarser->grid; });
  ASSERT_NE(floor, report.grid_decoded_floors.end());
  const bool fields_tried = std::any_of(rate.candidates.begin(), rate.candidates.end(), [&](const RateCandidate& c) {
    return c.grid != grid && c.representation == Representation::kHLT;
  });
  EXPECT_EQ(fields_tried, floor->p99 <= report.grid_worst_target);
}

// End to end where the rule keeps another candidate than the planned one (fmsynth's blinking face
// at seed 4, 24 frames of 3,000 vertices remeshed: xyz at the coarser N = 33 over hl+t at 49,
// 1,654 B at 0.2058% against 2,559 B at 0.1799% on the reviewer's machine): the file holds the
// kept candidate's keyframes, not the planned ones with the kept one's name, and a coarser N kept
// is within the tolerance.
TEST(SequenceEncoder, TheKeptCandidateIsTheOneStored) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 24;
  synth.expression = Expression::kBlink;
  synth.vertices = 3000;
  synth.remesh = true;
  synth.seed = 4;
  synth.texture_size = 64;
  write_synthetic_capture(dir.path(), synth);
  const Capture capture = read_capture(dir.path());
  EncodeOptions options = untextured();
  options.residual_frames = false;  // the stored keyframes alone, as the candidates' bytes count them
  options.patch_bound = 0;
  EncodeReport report;
  const std::unique_ptr<StoredSequence> stored = encode_capture_stored(capture, options, &report);
  const RepresentationRate& rate = report.representation_rate;
  ASSERT_TRUE(rate.measured);
  ASSERT_GE(rate.candidates.size(), 2u);
  ASSERT_NE(rate.chosen, 0u) << "a capture where the planned hl+t is not the cheapest: the test needs another pick";
  const RateCandidate& kept = rate.candidates[rate.chosen];
  for (const RateCandidate& c : rate.candidates) EXPECT_EQ(c.coarser, c.grid != rate.candidates[0].grid || c.step_scale != 1);
  if (kept.coarser) {
    EXPECT_LE(kept.held_rms, rate.tolerance);
  }
  EXPECT_EQ(stored->shape().representation, kept.representation);
  EXPECT_EQ(stored->shape().grid_n, kept.grid);
  EXPECT_EQ(report.grid, kept.grid);
  EXPECT_EQ(geometry_bytes(*stored, report.field_coding), kept.bytes) << "the file's keyframes are the kept candidate's";
  EXPECT_DOUBLE_EQ(rate.tolerance, kDefaultKeyframeErrorBound);

  // The default budget given as fmenc --keyframes 10% gives it (the error bound set to 0): the same
  // tolerance, so the same pick and file (before, a tolerance of 0 refused every coarser N).
  EncodeOptions budget = options;
  budget.keyframe_error_bound = 0;
  EncodeReport budget_report;
  const std::unique_ptr<StoredSequence> budget_stored = encode_capture_stored(capture, budget, &budget_report);
  EXPECT_DOUBLE_EQ(budget_report.representation_rate.tolerance, kDefaultKeyframeErrorBound);
  EXPECT_EQ(budget_report.representation_rate.chosen, rate.chosen);
  EXPECT_EQ(geometry_bytes(*budget_stored, budget_report.field_coding), kept.bytes);
}

// A one-frame capture (fmsynth's face, 5,000 vertices with the scanner's noise): no frame lies
// between keyframes, so each candidate is measured on the keyframe itself, decoded against its
// captured frame, and the file keeps the one the rule keeps (where before it kept hl+t unmeasured).
// Which one that is is a close race on this face: when written the positions won (979 B at 0.217%
// against the fields' 1,131 B at 0.247%); at caad362 xyz through the density-equalised disk, 876 B
// at 0.2095% against hl+t's 939 B at 0.2251%; since the QIEM steps' lagged factor (stop 78) hl+t,
// 875 B at 0.2161%. So the test holds the file to the rule and to hl+t asked for, not to a winner.
TEST(SequenceEncoder, AOneFrameCaptureIsChosenForOnItsKeyframe) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 1;
  synth.vertices = 5000;
  synth.texture_size = 32;
  write_synthetic_capture(dir.path(), synth);
  const Capture capture = read_capture(dir.path());
  const EncodeOptions options = untextured();
  EncodeReport report;
  const std::unique_ptr<StoredSequence> stored = encode_capture_stored(capture, options, &report);
  const RepresentationRate& rate = report.representation_rate;
  ASSERT_TRUE(rate.measured) << "a one-frame capture is chosen for, not left hl+t";
  EXPECT_TRUE(rate.on_keyframes);
  ASSERT_GE(rate.candidates.size(), 2u);
  for (const RateCandidate& c : rate.candidates) {
    EXPECT_EQ(c.frames, 1);
    EXPECT_GT(c.held_rms, 0);
    EXPECT_LT(c.held_rms, 0.01);  // a decoded face, not a failed one
  }
  const RateCandidate& kept = rate.candidates[rate.chosen];
  EXPECT_EQ(report.representation, kept.representation);
  EXPECT_EQ(stored->shape().representation, kept.representation);
  // Against hl+t asked for (what this capture was stored as before): no more bytes, and no higher a
  // cost bytes · RMS^k (the rule's weighing), each the keyframe's own as fmbench measures it.
  const std::vector<int> frame{0};
  const std::optional<std::vector<TriangleMesh>> captured = trial_meshes(capture, frame, options.threads);
  ASSERT_TRUE(captured);
  EncodeOptions forced = options;
  forced.representation = Representation::kHLT;
  EncodeReport forced_report;
  const std::unique_ptr<StoredSequence> fields = encode_capture_stored(capture, forced, &forced_report);
  const uint64_t kept_bytes = geometry_bytes(*stored, report.field_coding);
  EXPECT_EQ(kept_bytes, rate.candidates[rate.chosen].bytes);
  const uint64_t forced_bytes = geometry_bytes(*fields, forced_report.field_coding);
  EXPECT_LE(kept_bytes, forced_bytes);
  const double kept_rms = held_out_error(capture, *stored, frame, *captured, options.threads).rms;
  const double forced_rms = held_out_error(capture, *fields, frame, *captured, options.threads).rms;
  const auto measured = [](uint64_t bytes, double rms) { return candidate(Representation::kHLT, bytes, rms, 257, false, 1); };
  EXPECT_LE(rate_cost(measured(kept_bytes, kept_rms), rate.tolerance),
            rate_cost(measured(forced_bytes, forced_rms), rate.tolerance) * (1 + 1e-12));
}

}  // namespace
}  // namespace facemorph
