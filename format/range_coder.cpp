#include "format/range_coder.hpp"

#include "format/error.hpp"

namespace facemorph::format {

namespace {
constexpr uint32_t kTop = 1u << 24;  // the range is renormalised below 2^24: a byte at a time
}  // namespace

void RangeEncoder::encode(BitModel& model, int bit) {
  const uint32_t bound = (range_ >> BitModel::kBits) * model.p0();
  if (bit == 0) {
    range_ = bound;
  } else {
    low_ += bound;
    range_ -= bound;
  }
  model.update(bit);
  while (range_ < kTop) {
    range_ <<= 8;
    shift_low();
  }
}

void RangeEncoder::encode_direct(uint32_t value, int count) {
  for (int i = count - 1; i >= 0; --i) {
    range_ >>= 1;
    if ((value >> i) & 1u) low_ += range_;
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
}

// Emits the top byte of `low_`. A byte of 0xFF may still change by a carry, so it and those before it
// wait in `cache_` until a byte arrives that cannot carry.
void RangeEncoder::shift_low() {
  if (static_cast<uint32_t>(low_) < 0xFF000000u || (low_ >> 32) != 0) {
    const auto carry = static_cast<uint8_t>(low_ >> 32);
    uint8_t pending = cache_;
    do {
      out_.push_back(static_cast<uint8_t>(pending + carry));
      pending = 0xFF;
    } while (--cache_size_ != 0);
    cache_ = static_cast<uint8_t>(static_cast<uint32_t>(low_) >> 24);
  }
  ++cache_size_;
  low_ = static_cast<uint64_t>(static_cast<uint32_t>(low_) << 8);
}

std::vector<uint8_t> RangeEncoder::finish() {
  for (int i = 0; i < 5; ++i) shift_low();
  return std::move(out_);
}

RangeDecoder::RangeDecoder(std::span<const uint8_t> bytes, std::string source) : bytes_(bytes), source_(std::move(source)) {
  if (bytes_.size() < 5)
    throw Error(ErrorCode::kCorrupt, source_ + ": a range-coded stream of " + std::to_string(bytes_.size()) + " bytes (at least 5)");
  if (bytes_[0] != 0) throw Error(ErrorCode::kCorrupt, source_ + ": a range-coded stream that does not start with 0");
  pos_ = 1;
  for (int i = 0; i < 4; ++i) code_ = (code_ << 8) | next_byte();
}

uint8_t RangeDecoder::next_byte() {
  if (pos_ >= bytes_.size()) throw Error(ErrorCode::kCorrupt, source_ + ": the range-coded stream ends before its last value");
  return bytes_[pos_++];
}

void RangeDecoder::normalize() {
  while (range_ < kTop) {
    range_ <<= 8;
    code_ = (code_ << 8) | next_byte();
  }
}

int RangeDecoder::decode(BitModel& model) {
  const uint32_t bound = (range_ >> BitModel::kBits) * model.p0();
  int bit;
  if (code_ < bound) {
    range_ = bound;
    bit = 0;
  } else {
    code_ -= bound;
    range_ -= bound;
    bit = 1;
  }
  model.update(bit);
  normalize();
  ++decisions_;
  return bit;
}

uint32_t RangeDecoder::decode_direct(int count) {
  if (count > 0) decisions_ += static_cast<uint64_t>(count);
  uint32_t value = 0;
  for (int i = 0; i < count; ++i) {
    range_ >>= 1;
    uint32_t bit = 0;
    if (code_ >= range_) {
      code_ -= range_;
      bit = 1;
    }
    value = (value << 1) | bit;
    normalize();
  }
  return value;
}

void RangeDecoder::expect_end() const {
  if (pos_ != bytes_.size()) {
    throw Error(ErrorCode::kCorrupt,
                source_ + ": " + std::to_string(bytes_.size() - pos_) + " bytes after the range-coded stream's last value");
  }
}

}  // namespace facemorph::format
