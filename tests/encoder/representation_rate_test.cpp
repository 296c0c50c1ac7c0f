// The representation chosen by bytes at equal error (representation_rate.hpp, spec/method.md §7.14):
// the rule on constructed candidates, the frames it measures, and the encoder's choice end to end.
#include "codec/encoder/encode/representation_rate.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

namespace facemorph {
namespace {

RateCandidate candidate(Representation r, uint64_t bytes, double rms) { return {r, bytes, rms, 8}; }

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

TEST(RepresentationRate, TrialFramesAreSpreadBetweenTheKeyframes) {
  EXPECT_EQ(rate_trial_frames({0, 1, 2}), std::vector<int>{});  // nothing between
  EXPECT_EQ(rate_trial_frames({0}), std::vector<int>{});
  EXPECT_EQ(rate_trial_frames({0, 3, 5}), (std::vector<int>{1, 2, 4}));
  const std::vector<int> spread = rate_trial_frames({0, 23});  // 22 frames between: 8 of them, ends kept
  ASSERT_EQ(spread.size(), static_cast<size_t>(kRateTrials));
  EXPECT_EQ(spread.front(), 1);
  EXPECT_EQ(spread.back(), 22);
  for (size_t i = 1; i < spread.size(); ++i) EXPECT_GT(spread[i], spread[i - 1]);
}

// End to end on a turning head (fmsynth's face, 30°): both candidates measured, the file stores the
// one the rule picks, and that is hl+t (its keyframes take fewer bytes at an error within 1%; the
// positions do not pay here). Each candidate's bytes are those its representation alone gives.
TEST(SequenceEncoder, TheRepresentationIsChosenByBytesAtEqualError) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 30);
  EncodeOptions options;
  options.texture = false;
  options.threads = 2;
  EncodeReport report;
  const Sequence chosen = encode_capture(capture, options, &report);
  const RepresentationRate& rate = report.representation_rate;
  ASSERT_TRUE(rate.measured);
  EXPECT_EQ(rate.fields.representation, Representation::kHLT);
  EXPECT_EQ(rate.positions.representation, Representation::kXYZ);
  for (const RateCandidate* c : {&rate.fields, &rate.positions}) {
    EXPECT_GT(c->bytes, 1000u);
    EXPECT_GT(c->held_rms, 0);
    EXPECT_LT(c->held_rms, 0.01);  // a decoded face, not a failed one
    EXPECT_GE(c->frames, 1);
  }
  EXPECT_EQ(report.representation, cheaper_at_equal_error(rate.fields, rate.positions));
  EXPECT_EQ(chosen.representation, report.representation);
  EXPECT_EQ(report.representation, Representation::kHLT);
  // The rounded keyframes as either representation asked for alone: the same bytes.
  for (const Representation r : {Representation::kHLT, Representation::kXYZ}) {
    EncodeOptions forced = options;
    forced.representation = r;
    EncodeReport forced_report;
    const std::unique_ptr<StoredSequence> stored = encode_capture_stored(capture, forced, &forced_report);
    EXPECT_FALSE(forced_report.representation_rate.measured);  // asked for: nothing chosen
    EXPECT_EQ(geometry_bytes(*stored, forced_report.field_coding), r == Representation::kHLT ? rate.fields.bytes : rate.positions.bytes);
  }
}

}  // namespace
}  // namespace facemorph
