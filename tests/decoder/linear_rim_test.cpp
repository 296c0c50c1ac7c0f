// Format 2.5's linear predictor along a sequence (spec/container.md §7.2): predictor id 2 on an
// array that lies on no lattice (the band, the rim) is 2 d(i−1) − d(i−2) in a file stamped 2.5 or
// later and corrupt in an older one. The writer chooses it where it leaves the fewest bits; a
// crafted group checks the decoder's arithmetic against the formula and refuses what it must.
#include "codec/core/container/file_layout.hpp"
#include "codec/core/container/keyframe_group_coding.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/byte_reader.hpp"
#include "format/byte_writer.hpp"
#include "format/container.hpp"
#include "format/ranged_residuals.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace facemorph {
namespace {

using file_layout::kKeyframeArrays;
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

// The small sequence's file with its first group (keyframes 0 and 1, both intra) replaced by a
// stream written here: every array under predictor none with its codes as residuals, but the rim's
// x under predictor id `rim_id` with every residual 1. Under linear (d₀ = 0 + 1, d₁ = d₀ + 1, then
// 2 d(i−1) − d(i−2) + 1: second differences of 1) its codes are 1 + i (i + 1) / 2.
Crafted crafted_rim(uint8_t rim_id) {
  const Sequence s = crafted::small_sequence(17, 8);
  const SequenceFileMetadata m = crafted::predicted_metadata();  // intra period 2
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  const Sequence back = decode_sequence_file(bytes, "written.fmv");
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(17);
  Crafted out;
  const auto edit = [&](const std::string& type, std::vector<uint8_t>& payload) {
    if (type != "KGOP") return;
    format::ByteReader r(payload, "KGOP");
    if (r.read<uint32_t>("first") != 0) return;
    format::RangedStreamWriter stream;
    file_layout::GroupModels models;
    for (size_t k = 0; k < 2; ++k) {
      std::vector<std::vector<int64_t>> residuals = codes_of(back.keyframes[k], m.field_coding);
      if (k > 0) stream.decision(models.reference, false);  // intra
      for (size_t a = 0; a < kKeyframeArrays; ++a) {
        if (residuals[a].empty()) continue;
        const unsigned p = a == kRimX ? rim_id : 0;
        stream.decision(models.predictor[a][0], (p >> 1) != 0);
        stream.decision(models.predictor[a][1 + (p >> 1)], (p & 1) != 0);
      }
      std::vector<int64_t> expected;
      for (size_t i = 0; i < residuals[kRimX].size(); ++i) {
        residuals[kRimX][i] = 1;
        expected.push_back(static_cast<int64_t>(1 + i * (i + 1) / 2));
      }
      out.rim_x.push_back(expected);
      const std::vector<const format::LatticeNeighbours*> lattices = file_layout::lattices_of(file_layout::lengths_of(residuals), *grid);
      stream.residual_arrays(residuals, lattices, file_layout::kRangeModelSets, models.residuals);
    }
    format::ByteWriter w;
    w.write(uint32_t{0});
    w.bytes(stream.finish());
    payload = w.take();
  };
  out.file = crafted::rebuild(bytes, edit);
  return out;
}

TEST(LinearRim, TheWriterChoosesItForASmoothRimWhichRoundTripsExactly) {
  const Sequence s = crafted::small_sequence(17, 8);
  const SequenceFileMetadata m = crafted::predicted_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "linear.fmv", &info);
  EXPECT_EQ(info.minor_version, 5);
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

}  // namespace
}  // namespace facemorph
