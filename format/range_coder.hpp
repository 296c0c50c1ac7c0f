// A binary adaptive range coder (spec/container.md §7.4): the carry-propagating coder of LZMA, with
// 12-bit probabilities that adapt towards every coded bit. It codes a sequence of yes/no decisions,
// each under a probability model the caller picks; how numbers become decisions is the caller's
// business (format/residual_coder.cpp).
//
// Both sides are defined to the bit by the spec: the encoder's bytes, and the decoder's reading of
// them, are the format. Changing a constant here changes the format.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

// The probability that the next decision is 0, in units of 1/4096: the mean of two estimates, one
// moved after each decision by an eighth of its distance to what happened, the other by a
// sixty-fourth. Fast, because arrays are a few thousand values and their statistics drift across
// the face (measured on Medusa: shifts 3 and 6 cost 1.5% less than 4 and 7, 3% less than 5 and 8).
// Both stay inside [7, 4089] and [63, 4033], so p0 lies in [35, 4061]: never 0 or 1.
class BitModel {
 public:
  static constexpr int kBits = 12;
  static constexpr uint32_t kOne = 1u << kBits;

  // The probability of 0 in 1/4096, within [1, 4095] by construction.
  uint32_t p0() const { return (fast_ + slow_) >> 1; }
  void update(int bit) {
    if (bit) {
      fast_ -= fast_ >> kFastShift;
      slow_ -= slow_ >> kSlowShift;
    } else {
      fast_ += (kOne - fast_) >> kFastShift;
      slow_ += (kOne - slow_) >> kSlowShift;
    }
  }

 private:
  static constexpr int kFastShift = 3, kSlowShift = 6;
  uint32_t fast_ = kOne / 2, slow_ = kOne / 2;
};

class RangeEncoder {
 public:
  // Codes `bit` (0 or 1) under `model`, then adapts the model.
  void encode(BitModel& model, int bit);
  // Codes `count` (≤ 32) low bits of `value`, high first, each at probability ½, no model.
  void encode_direct(uint32_t value, int count);
  // Flushes the coder's state and returns the bytes; the encoder is spent afterwards.
  std::vector<uint8_t> finish();

 private:
  void shift_low();
  uint64_t low_ = 0;
  uint32_t range_ = 0xFFFFFFFFu;
  uint8_t cache_ = 0;
  uint64_t cache_size_ = 1;
  std::vector<uint8_t> out_;
};

class RangeDecoder {
 public:
  // Throws kCorrupt naming `source` when `bytes` is too short to start, or does not start with the
  // zero byte every encoder writes first.
  RangeDecoder(std::span<const uint8_t> bytes, std::string source);

  // The next decision under `model` (which then adapts), and `count` (≤ 32) direct bits. Both throw
  // kCorrupt naming the source when the stream ends before the decision does.
  int decode(BitModel& model);
  uint32_t decode_direct(int count);
  // Throws kCorrupt unless the decisions read so far consumed every byte, no more and no fewer: the
  // check that the stream ends where the encoder ended it.
  void expect_end() const;
  // Bytes of the stream read so far (the first five on construction).
  size_t position() const { return pos_; }
  // Decisions and direct bits read so far: what decoding the stream has cost, which grows with the
  // magnitudes it holds (a residual near 2^30 is about 69 of them, a zero 1), so that a decoder
  // charges its work by them (spec/container.md §10.3) and not by the values alone.
  uint64_t decisions() const { return decisions_; }

 private:
  void normalize();
  uint8_t next_byte();
  std::span<const uint8_t> bytes_;
  std::string source_;
  size_t pos_ = 0;
  uint32_t range_ = 0xFFFFFFFFu;
  uint32_t code_ = 0;
  uint64_t decisions_ = 0;
};

}  // namespace facemorph::format
