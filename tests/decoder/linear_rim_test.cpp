// Format 2.5's linear predictor along a sequence (spec/container.md §7.2): predictor id 2 on an
// array that lies on no lattice (the band, the rim) is 2 d(i−1) − d(i−2) in a file stamped 2.5 or
// later and corrupt in an older one. The writer chooses it where it leaves the fewest bits; a
// crafted group checks the decoder's arithmetic against the formula and refuses what it must.
#include "codec/core/container/file_layout.hpp"
#include "codec/core/container/keyframe_group_coding.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/chunk_writers.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/container.hpp"
#include "format/ranged_residuals.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace facemorph {
namespace {

constexpr size_t kRimX = 10;  // the rim's x, y, z are arrays 10–12 (§7.1)

// A keyframe's codes at the file's steps (its values are steps × codes exactly).
std::vector<std::vector<int64_t>> codes_of(const Keyframe& key, const FieldCoding& coding) {
  const std::vector<std::vector<double>> arrays = file_layout::keyframe_arrays(key);
  std::vector<std::vector<int64_t>> codes(arrays.size());
  for (size_t a = 0; a < arrays.size(); ++a) {
    for (double v : arrays[a]) codes[a].push_back(std::llround(v / coding.steps[a]));
  }
  return codes;
}

struct Crafted {
  std::vector<uint8_t> file;
  std::vector<std::vector<int64_t>> rim_x;  // the codes the decoder must give keyframe 0's rim x
};

// The small sequence's file with its first group (keyframes 0 and 1, both intra) written by hand:
// every array under predictor none with its codes as residuals, but the rim's x under predictor id
// `rim_id` with every residual 1. Under linear (d₀ = 0 + 1, d₁ = d₀ + 1, then 2 d(i−1) − d(i−2) + 1:
// second differences of 1) its codes are 1 + i (i + 1) / 2.
Crafted crafted_rim(uint8_t rim_id) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(17, 8), crafted::predicted_metadata());
  Crafted out;
  out.file = crafted::with_first_group_by_hand(bytes, false, [&](crafted::HandCodedKeyframe& key) {
    key.ids[kRimX] = rim_id;
    std::vector<int64_t> expected;
    for (size_t i = 0; i < key.residuals[kRimX].size(); ++i) {
      key.residuals[kRimX][i] = 1;
      expected.push_back(static_cast<int64_t>(1 + i * (i + 1) / 2));
    }
    out.rim_x.push_back(expected);
  });
  return out;
}

TEST(LinearRim, TheWriterChoosesItForASmoothRimWhichRoundTripsExactly) {
  const Sequence s = crafted::small_sequence(17, 8);
  const SequenceFileMetadata m = crafted::predicted_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "linear.fmv", &info);
  EXPECT_EQ(info.minor_version, 6);
  ASSERT_EQ(back.keyframes.size(), s.keyframes.size());
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    const std::vector<std::vector<double>> written = file_layout::keyframe_arrays(s.keyframes[k]);
    const std::vector<std::vector<double>> read = file_layout::keyframe_arrays(back.keyframes[k]);
    for (size_t a = kRimX; a < kRimX + 3; ++a) {
      ASSERT_EQ(read[a].size(), written[a].size());
      ASSERT_GT(read[a].size(), 40u);
      for (size_t i = 0; i < read[a].size(); ++i) {
        const double step = m.field_coding.steps[a];
        ASSERT_EQ(read[a][i], step * file_layout::field_code(written[a][i], step)) << k << " " << a << " " << i;
      }
    }
  }
  // The same bytes stamped 2.4: the rim's predictor id 2 is what an older file cannot hold, so the
  // writer did choose linear for it (a circle's second difference is far below its first).
  testing::expect_error(ErrorCode::kCorrupt, "array 10 has predictor 2, not one for that array in a 2.4 file",
                        [&] { decode_sequence_file(crafted::restamped(bytes, 4), "old.fmv"); });
}

TEST(LinearRim, TheDecoderExtrapolatesTheTwoCodesBeforeFromTheFirstNodeOn) {
  const FieldCoding coding = crafted::predicted_metadata().field_coding;
  const Crafted linear = crafted_rim(2);
  const Sequence back = decode_sequence_file(linear.file, "crafted.fmv");
  for (size_t k = 0; k < 2; ++k) EXPECT_EQ(codes_of(back.keyframes[k], coding)[kRimX], linear.rim_x[k]) << k;
  // The same stream under previous (id 1) gives 1, 2, 3, …: the crafted bytes are what decides.
  const Sequence previous = decode_sequence_file(crafted_rim(1).file, "previous.fmv");
  const std::vector<int64_t> rim = codes_of(previous.keyframes[0], coding)[kRimX];
  for (size_t i = 0; i < rim.size(); ++i) ASSERT_EQ(rim[i], static_cast<int64_t>(i + 1)) << i;
}

TEST(LinearRim, IdTwoOnASequenceIsCorruptBefore25AndIdThreeAlways) {
  const Crafted linear = crafted_rim(2);
  for (uint8_t minor : {0, 3, 4}) {
    testing::expect_error(ErrorCode::kCorrupt,
                          "(keyframe 0): array 10 has predictor 2, not one for that array in a 2." + std::to_string(minor) + " file",
                          [&] { decode_sequence_file(crafted::restamped(linear.file, minor), "old.fmv"); });
  }
  for (uint8_t minor : {4, 5, 6}) {
    testing::expect_error(ErrorCode::kCorrupt, "(keyframe 0): array 10 has predictor 3, not one for that array",
                          [&] { decode_sequence_file(crafted::restamped(crafted_rim(3).file, minor), "three.fmv"); });
  }
}

// The one rule the writer and the reader share (allowed_predictors), by id: a lattice's four at
// every version; a sequence's none and previous, and linear as id 2 from 2.5 on only.
TEST(LinearRim, TheAllowedPredictorsAreTheLatticesFourAndASequencesLinearFrom25) {
  using format::SpatialPredictor;
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(17);
  const std::vector<SpatialPredictor> lattice = {SpatialPredictor::kNone, SpatialPredictor::kPrevious, SpatialPredictor::kGradient,
                                                 SpatialPredictor::kMedian};
  const std::vector<SpatialPredictor> old_sequence = {SpatialPredictor::kNone, SpatialPredictor::kPrevious};
  const std::vector<SpatialPredictor> new_sequence = {SpatialPredictor::kNone, SpatialPredictor::kPrevious, SpatialPredictor::kLinear};
  const auto allowed = [](const format::LatticeNeighbours* on, uint16_t minor) {
    const std::span<const SpatialPredictor> ids = file_layout::allowed_predictors(on, minor);
    return std::vector<SpatialPredictor>(ids.begin(), ids.end());
  };
  for (uint16_t minor : {0, 3, 4}) {
    EXPECT_EQ(allowed(&grid->interior, minor), lattice) << minor;
    EXPECT_EQ(allowed(nullptr, minor), old_sequence) << minor;
  }
  for (uint16_t minor : {5, 6}) {
    EXPECT_EQ(allowed(&grid->all_nodes, minor), lattice) << minor;
    EXPECT_EQ(allowed(nullptr, minor), new_sequence) << minor;
  }
  for (uint8_t id = 0; id < 3; ++id) EXPECT_EQ(file_layout::predictor_id(new_sequence[id]), id);
}

// The writer's side of the rule, without the reader: a smooth rim's bits as the writer predicts it
// (keyframe_array_bits, fminfo --field-bytes' figures too) are the fewer of none's and previous's
// in a 2.4 file, and linear's, fewer still, in a 2.5 file.
TEST(LinearRim, TheWriterOfA24FileChoosesNoneOrPreviousAlongTheRim) {
  const Sequence s = crafted::small_sequence(17, 8);
  const FieldCoding coding = crafted::predicted_metadata().field_coding;
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(s.grid_n);
  const Keyframe& key = s.keyframes[0];
  const std::vector<double> rim = file_layout::keyframe_arrays(key)[kRimX];
  std::vector<int32_t> codes;
  for (double v : rim) codes.push_back(file_layout::field_code(v, coding.steps[kRimX]));
  ASSERT_GT(codes.size(), 40u);
  const auto bits = [&](format::SpatialPredictor p) {
    return format::ranged_residual_bits(format::spatial_residuals(codes, p, nullptr), nullptr);
  };
  const double older = std::min(bits(format::SpatialPredictor::kNone), bits(format::SpatialPredictor::kPrevious));
  const double linear = bits(format::SpatialPredictor::kLinear);
  ASSERT_LT(linear, older);
  EXPECT_EQ(file_layout::keyframe_array_bits(key, nullptr, coding, *grid, 4)[kRimX], older);
  EXPECT_EQ(file_layout::keyframe_array_bits(key, nullptr, coding, *grid, 5)[kRimX], linear);
}

// The rim's x and the band's first component zigzag between the code bounds in keyframe 0 and the
// other way round in keyframe 1, coded from keyframe 0: the change d alternates ±(2^31 − 2), its
// linear prediction reaches 3 × (2^31 − 2) and the residuals 4 × (2^31 − 2), near §7.3's 2^34.
// Every code decodes exactly (64-bit arithmetic, no overflow).
TEST(LinearRim, TheWidestSwingAlongASequenceDecodesExactlyFromThePreviousKeyframe) {
  constexpr size_t kBandX = 4;
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(17, 8), crafted::predicted_metadata());
  std::vector<std::vector<int32_t>> expected(2);
  int64_t widest = 0;
  const std::vector<uint8_t> file = crafted::with_first_group_by_hand(bytes, true, [&](crafted::HandCodedKeyframe& key) {
    for (size_t a : {kBandX, kRimX}) {
      ASSERT_GE(key.residuals[a].size(), 3u) << a;
      ASSERT_EQ(key.from_previous, key.k == 1);
      const std::vector<int32_t> codes = crafted::linear_swing(key, a);
      for (int64_t r : key.residuals[a]) widest = std::max(widest, std::abs(r));
      if (a == kRimX) expected[key.k] = codes;
    }
  });
  EXPECT_EQ(widest, 4 * (2 * (file_layout::kMaxFieldCode - 1)));
  const FieldCoding coding = crafted::predicted_metadata().field_coding;
  const Sequence back = decode_sequence_file(file, "swing.fmv");
  for (size_t k = 0; k < 2; ++k) {
    const std::vector<int64_t> rim = codes_of(back.keyframes[k], coding)[kRimX];
    EXPECT_EQ(rim, std::vector<int64_t>(expected[k].begin(), expected[k].end())) << k;
  }
}

// Residuals that lead a linear prediction past 32 bits, or a code past §7's 2^30, are the file's
// fault, named with the keyframe (never wrapped, never undefined behaviour).
TEST(LinearRim, ACodePast32BitsOr2To30AlongTheRimIsCorruptNamingTheKeyframe) {
  const std::vector<uint8_t> bytes = encode_sequence_file(crafted::small_sequence(17, 8), crafted::predicted_metadata());
  const auto rim_residuals = [&](size_t keyframe, std::vector<int64_t> first) {
    return crafted::with_first_group_by_hand(bytes, false, [&](crafted::HandCodedKeyframe& key) {
      if (key.k != keyframe) return;
      key.ids[kRimX] = 2;
      std::fill(key.residuals[kRimX].begin(), key.residuals[kRimX].end(), 0);
      std::copy(first.begin(), first.end(), key.residuals[kRimX].begin());
    });
  };
  const int64_t top = std::numeric_limits<int32_t>::max();
  // d = 2^31 − 1, −2^31, then 2 d₁ − d₀ − 2^34: about −2^34.6.
  testing::expect_error(ErrorCode::kCorrupt, "(keyframe 1): a field code outside 32 bits",
                        [&] { decode_sequence_file(rim_residuals(1, {top, -2 * top - 1, -(int64_t{1} << 34)}), "past32.fmv"); });
  // d = 0, 2^30, 0, 0, …: within 32 bits, node 1 past the code bound.
  std::vector<int32_t> d(crafted::small_sequence(17, 8).keyframes[0].fields.rim.size(), 0);
  d[1] = 1 << 30;
  const std::vector<int64_t> to_2_30 = format::spatial_residuals(d, format::SpatialPredictor::kLinear, nullptr);
  testing::expect_error(ErrorCode::kCorrupt, "(keyframe 0): a field code beyond 2^30",
                        [&] { decode_sequence_file(rim_residuals(0, to_2_30), "past30.fmv"); });
}

}  // namespace
}  // namespace facemorph
