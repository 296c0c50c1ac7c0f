// The binary range coder and the range-coded residuals of field codings 2 to 4 (spec/container.md §7.4, §7.5):
// exact round trips, sizes near the information the data holds, and damaged streams named, never
// read past their end.
#include "format/range_coder.hpp"
#include "format/ranged_residuals.hpp"
#include "format/spatial_predictor.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace facemorph {
namespace {

double entropy_bits(double p, size_t n) { return -static_cast<double>(n) * (p * std::log2(p) + (1 - p) * std::log2(1 - p)); }

// Skewed bits under one adapting model, mixed with direct bits: the decoder reads back every bit,
// consumes exactly the encoder's bytes, and the model's bits come near the source's entropy (within
// 10%: the models adapt fast, which costs on a stationary source what it gains on a keyframe's).
TEST(RangeCoder, RoundTripsAndApproachesTheEntropy) {
  for (double p1 : {0.02, 0.2, 0.5}) {
    std::mt19937 rng(7);
    std::bernoulli_distribution one(p1);
    std::vector<int> bits(20000);
    std::vector<uint32_t> direct(bits.size() / 100);
    for (int& b : bits) b = one(rng) ? 1 : 0;
    for (uint32_t& d : direct) d = static_cast<uint32_t>(rng());
    format::RangeEncoder encoder;
    format::BitModel model;
    for (size_t i = 0; i < bits.size(); ++i) {
      encoder.encode(model, bits[i]);
      if (i % 100 == 99) encoder.encode_direct(direct[i / 100], 32);
    }
    const std::vector<uint8_t> bytes = encoder.finish();
    format::RangeDecoder decoder(bytes, "bits");
    format::BitModel read_model;
    for (size_t i = 0; i < bits.size(); ++i) {
      ASSERT_EQ(decoder.decode(read_model), bits[i]) << "bit " << i;
      if (i % 100 == 99) {
        ASSERT_EQ(decoder.decode_direct(32), direct[i / 100]);
      }
    }
    decoder.expect_end();
    const double payload_bits = 8.0 * static_cast<double>(bytes.size()) - 32.0 * static_cast<double>(direct.size());
    EXPECT_LT(payload_bits, 1.10 * entropy_bits(p1, bits.size()) + 64) << "p(1) = " << p1;
  }
}

TEST(RangeCoder, StreamsThatEndEarlyOrLateAreCorrupt) {
  format::RangeEncoder encoder;
  format::BitModel model;
  for (int i = 0; i < 500; ++i) encoder.encode(model, i % 3 == 0);
  std::vector<uint8_t> bytes = encoder.finish();
  const auto read_all = [](std::span<const uint8_t> b) {
    format::RangeDecoder decoder(b, "s.bits");
    format::BitModel m;
    for (int i = 0; i < 500; ++i) decoder.decode(m);
    decoder.expect_end();
  };
  read_all(bytes);
  testing::expect_error(ErrorCode::kCorrupt, "s.bits: the range-coded stream ends before its last value",
                        [&] { read_all(std::span(bytes).first(bytes.size() - 1)); });
  testing::expect_error(ErrorCode::kCorrupt, "s.bits: a range-coded stream of 4 bytes", [&] { read_all(std::span(bytes).first(4)); });
  bytes.push_back(0);
  testing::expect_error(ErrorCode::kCorrupt, "s.bits: 1 bytes after", [&] { read_all(bytes); });
  bytes.pop_back();
  bytes[0] = 1;
  testing::expect_error(ErrorCode::kCorrupt, "does not start with 0", [&] { read_all(bytes); });
}

// Residuals like a keyframe's: small (two-sided geometric, as noise-shaped rounding leaves), larger in
// a patch of the lattice (a feature), and a few extremes that take the escape, up to ±2^34.
struct ResidualArrays {
  std::vector<std::vector<int64_t>> arrays;
  std::vector<const format::LatticeNeighbours*> lattices;
  std::vector<uint8_t> model_sets;
  std::vector<size_t> lengths() const {
    std::vector<size_t> out;
    for (const auto& a : arrays) out.push_back(a.size());
    return out;
  }
};

ResidualArrays keyframe_like_residuals(const format::LatticeNeighbours& lattice, int w) {
  std::mt19937 rng(11);
  std::geometric_distribution<int> small(0.55), large(0.08);
  std::bernoulli_distribution negative(0.5);
  ResidualArrays r;
  for (int a = 0; a < 3; ++a) {
    std::vector<int64_t> values;
    for (int i = 0; i < w * w; ++i) {
      const bool feature = (i % w) > w / 2 && i / w < w / 3;
      const int64_t m = feature ? large(rng) : small(rng);
      values.push_back(negative(rng) ? -m : m);
    }
    r.arrays.push_back(std::move(values));
    r.lattices.push_back(&lattice);
    r.model_sets.push_back(a == 2 ? 1 : static_cast<uint8_t>(a));
  }
  // A sequence, no lattice, to the coder's range of ±2^34.
  r.arrays.push_back({0, 1, -1, 300, -70000, (int64_t{1} << 34) - 1, -(int64_t{1} << 34), 5, 0, 0});
  r.lattices.push_back(nullptr);
  r.model_sets.push_back(3);
  r.arrays.push_back({});  // an array the representation leaves empty
  r.lattices.push_back(nullptr);
  r.model_sets.push_back(4);
  return r;
}

TEST(RangedResiduals, RoundTripExactlyAtTheirEstimatedCost) {
  const int w = 37;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  const ResidualArrays r = keyframe_like_residuals(lattice, w);
  const std::vector<uint8_t> bytes = format::encode_ranged_residuals(r.arrays, r.lattices, r.model_sets);
  EXPECT_EQ(format::decode_ranged_residuals(bytes, r.lengths(), r.lattices, r.model_sets, "k.res"), r.arrays);
  EXPECT_EQ(format::encode_ranged_residuals(r.arrays, r.lattices, r.model_sets), bytes);  // deterministic
  // The estimate the writer chooses predictors by is the coder's own cost, to within the stream's end
  // and the models the real call shares between arrays.
  double estimate = 0;
  for (size_t a = 0; a < r.arrays.size(); ++a) estimate += format::ranged_residual_bits(r.arrays[a], r.lattices[a]);
  EXPECT_NEAR(8.0 * static_cast<double>(bytes.size()), estimate, 0.05 * estimate + 64);
}

// The estimate the writer chooses predictors by, and the encoder its dead zone and candidates (files
// depend on it to the bit): each decision's cost −log2 p, read from a table of BitModel's
// probabilities rather than a log2 a decision. Pinned to what a log2 a decision gave (main 1b7911e),
// so that a table off by one probability, or with a 0's and a 1's costs swapped, fails here.
TEST(RangedResiduals, TheEstimateIsEachDecisionsLogToTheBit) {
  const int w = 37;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  const ResidualArrays r = keyframe_like_residuals(lattice, w);
  const std::vector<double> pinned = {0x1.0a9dd3d71f774p+12, 0x1.07d4f1b4c6777p+12, 0x1.08d52d5569bd5p+12, 0x1.9d94b73e56eedp+7, 0};
  ASSERT_EQ(r.arrays.size(), pinned.size());
  for (size_t a = 0; a < r.arrays.size(); ++a) {
    EXPECT_EQ(format::ranged_residual_bits(r.arrays[a], r.lattices[a]), pinned[a]) << "array " << a;
  }
}

// Field coding 3: a second keyframe's stream continues the models where the first's left them. It
// decodes with the same models, costs less than starting afresh (the models know the statistics
// already), and is not the stream that fresh models read.
TEST(RangedResiduals, CarriedModelsContinueWhereTheLastStreamEnded) {
  const int w = 37;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  const ResidualArrays first = keyframe_like_residuals(lattice, w);
  ResidualArrays second = first;
  std::reverse(second.arrays[0].begin(), second.arrays[0].end());  // the same statistics, other values
  std::vector<format::ResidualModels> written, read;
  format::encode_ranged_residuals(first.arrays, first.lattices, first.model_sets, &written);
  const std::vector<uint8_t> carried = format::encode_ranged_residuals(second.arrays, second.lattices, second.model_sets, &written);
  const std::vector<uint8_t> fresh = format::encode_ranged_residuals(second.arrays, second.lattices, second.model_sets);
  EXPECT_LT(carried.size(), fresh.size());
  format::decode_ranged_residuals(format::encode_ranged_residuals(first.arrays, first.lattices, first.model_sets), first.lengths(),
                                  first.lattices, first.model_sets, "k0.res", &read);
  EXPECT_EQ(format::decode_ranged_residuals(carried, second.lengths(), second.lattices, second.model_sets, "k1.res", &read), second.arrays);
  try {
    EXPECT_NE(format::decode_ranged_residuals(carried, second.lengths(), second.lattices, second.model_sets, "k1.res"), second.arrays);
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kCorrupt) << e.what();  // or the stream does not even fit
  }
  std::vector<format::ResidualModels> wrong_count(2);
  testing::expect_error(ErrorCode::kInvalidArgument, "carried models",
                        [&] { format::encode_ranged_residuals(first.arrays, first.lattices, first.model_sets, &wrong_count); });
}

// Field coding 4's stream: decisions, numbers and arrays of residuals interleaved in one stream
// (spec/container.md §7.5) read back in the same order. Numbers of every size up to 2^42 - 1 round
// trip; a small number costs a few bits, a large one its bits plus about seven; a number the writer
// cannot code is its error, and a length the format does not allow is corrupt.
TEST(RangedStream, InterleavedDecisionsNumbersAndArraysRoundTrip) {
  const int w = 11;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  const ResidualArrays r = keyframe_like_residuals(lattice, w);
  const int64_t largest = (int64_t{1} << format::kMaxNumberBits) - 1;
  const std::vector<int64_t> numbers = {0, 1, -1, 2, -3, 255, -256, int64_t{1} << 32, -(int64_t{1} << 33) - 5, largest, -largest};
  format::RangedStreamWriter writer;
  format::BitModel decision;
  format::NumberModels number_models;
  std::vector<format::ResidualModels> residual_models;
  for (int round = 0; round < 2; ++round) {
    writer.decision(decision, round == 1);
    for (int64_t n : numbers) writer.number(number_models, n);
    writer.residual_arrays(r.arrays, r.lattices, r.model_sets, residual_models);
  }
  const std::vector<uint8_t> bytes = writer.finish();
  format::RangedStreamReader reader(bytes, "g.stream");
  format::BitModel read_decision;
  format::NumberModels read_numbers;
  std::vector<format::ResidualModels> read_models;
  size_t position = reader.position();
  for (int round = 0; round < 2; ++round) {
    EXPECT_EQ(reader.decision(read_decision), round == 1);
    for (int64_t n : numbers) EXPECT_EQ(reader.number(read_numbers), n);
    EXPECT_EQ(reader.residual_arrays(r.lengths(), r.lattices, r.model_sets, read_models), r.arrays);
    EXPECT_GT(reader.position(), position);
    position = reader.position();
  }
  reader.expect_end();
  EXPECT_EQ(position, bytes.size());
  testing::expect_error(ErrorCode::kInvalidArgument, "beyond 2^42", [&] { writer.number(number_models, largest + 1); });

  // Sizes: a thousand zeros take a few bytes; numbers of 16 bits take about 16 + 7 bits each.
  const auto stream_bytes = [](const std::vector<int64_t>& values) {
    format::RangedStreamWriter s;
    format::NumberModels m;
    for (int64_t v : values) s.number(m, v);
    return static_cast<double>(s.finish().size());
  };
  EXPECT_LT(stream_bytes(std::vector<int64_t>(1000, 0)), 50);  // six decisions each, at the models' floor of 0.0124 bits
  std::mt19937 rng(3);
  std::vector<int64_t> sixteen(1000);
  for (int64_t& v : sixteen) v = (int64_t{1} << 15) + static_cast<int64_t>(rng() % (1u << 15));
  EXPECT_LT(stream_bytes(sixteen), 1000 * (16 + 7) / 8.0);
  EXPECT_GT(stream_bytes(sixteen), 1000 * 15 / 8.0);

  // A length beyond 42 bits: all six length decisions 1 (63) under fresh models.
  // (Fresh models all give 1/2, so six fresh ones write what the tree's fresh nodes read.)
  format::RangedStreamWriter bad;
  std::array<format::BitModel, 6> ones;
  for (format::BitModel& m : ones) bad.decision(m, true);
  const std::vector<uint8_t> long_number = bad.finish();
  format::RangedStreamReader long_reader(long_number, "l.stream");
  format::NumberModels fresh;
  testing::expect_error(ErrorCode::kCorrupt, "l.stream: a number longer than 42 bits", [&] { long_reader.number(fresh); });
}

TEST(RangedResiduals, OutOfRangeAndMismatchedInputIsTheWritersError) {
  const format::LatticeNeighbours lattice = testing::square_lattice(3);
  const std::vector<const format::LatticeNeighbours*> none = {nullptr};
  const std::vector<uint8_t> own = {0};
  const std::vector<std::vector<int64_t>> extremes = {{int64_t{1} << 34, -(int64_t{1} << 34)}};
  const std::vector<size_t> two = {2};
  EXPECT_EQ(format::decode_ranged_residuals(format::encode_ranged_residuals(extremes, none, own), two, none, own, "x"), extremes);
  testing::expect_error(ErrorCode::kInvalidArgument, "beyond 2^34", [&] {
    const std::vector<std::vector<int64_t>> big = {{(int64_t{1} << 34) + 1}};
    format::encode_ranged_residuals(big, none, own);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "another size", [&] {
    const std::vector<std::vector<int64_t>> four = {{1, 2, 3, 4}};
    const std::vector<const format::LatticeNeighbours*> nine = {&lattice};
    format::encode_ranged_residuals(four, nine, own);
  });
  testing::expect_error(ErrorCode::kInvalidArgument, "model set", [&] {
    const std::vector<std::vector<int64_t>> one = {{1}};
    const std::vector<uint8_t> later = {1};
    format::encode_ranged_residuals(one, none, later);
  });
}

// Every cut and every changed byte of a stream: an error naming the source or, where the damage
// happens to decode, values within the format's range. Never a crash or a read past the end.
TEST(RangedResiduals, DamagedStreamsAreNamed) {
  const int w = 12;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  const ResidualArrays r = keyframe_like_residuals(lattice, w);
  const std::vector<uint8_t> bytes = format::encode_ranged_residuals(r.arrays, r.lattices, r.model_sets);
  const std::vector<size_t> lengths = r.lengths();
  for (size_t cut = 0; cut < bytes.size(); ++cut) {
    testing::expect_error(ErrorCode::kCorrupt, "k.res", [&] {
      format::decode_ranged_residuals(std::span(bytes).first(cut), lengths, r.lattices, r.model_sets, "k.res");
    });
  }
  for (size_t at = 0; at < bytes.size(); ++at) {
    for (uint8_t flip : {uint8_t{0x01}, uint8_t{0xA5}}) {
      std::vector<uint8_t> damaged = bytes;
      damaged[at] ^= flip;
      try {
        for (const auto& a : format::decode_ranged_residuals(damaged, lengths, r.lattices, r.model_sets, "k.res")) {
          for (int64_t v : a) EXPECT_LE(std::abs(v), format::kMaxRangedResidual);
        }
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kCorrupt) << e.what();
        EXPECT_NE(std::string(e.what()).find("k.res"), std::string::npos);
      }
    }
  }
  // More values than the bytes could hold are refused before they are allocated.
  std::vector<size_t> huge = lengths;
  huge[0] = size_t{1} << 40;
  testing::expect_error(ErrorCode::kCorrupt, "cannot hold",
                        [&] { format::decode_ranged_residuals(bytes, huge, r.lattices, r.model_sets, "k.res"); });
}

}  // namespace
}  // namespace facemorph
