// One bounds-checked reader for every binary parser in facemorph (PLY bodies, the .fmv container).
// Reading past the end is always an error (ErrorCode::kTruncated) naming the source and the field;
// it never yields a silent zero.
#pragma once

#include "format/error.hpp"

#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>

namespace facemorph::format {

class ByteReader {
 public:
  // `source` names the input in error messages, e.g. the file path.
  ByteReader(std::span<const uint8_t> bytes, std::string source) : bytes_(bytes), source_(std::move(source)) {}

  size_t position() const { return pos_; }
  size_t remaining() const { return bytes_.size() - pos_; }
  size_t size() const { return bytes_.size(); }
  const std::string& source() const { return source_; }

  // Throws kTruncated unless `count` more bytes are available; `what` names the field.
  void require(size_t count, const char* what) const {
    if (count > remaining()) {
      throw Error(ErrorCode::kTruncated, source_ + ": truncated: " + what + " needs " + std::to_string(count) + " bytes at offset " +
                                             std::to_string(pos_) + ", only " + std::to_string(remaining()) + " left");
    }
  }

  std::span<const uint8_t> bytes(size_t count, const char* what) {
    require(count, what);
    auto out = bytes_.subspan(pos_, count);
    pos_ += count;
    return out;
  }

  void skip(size_t count, const char* what) { (void)bytes(count, what); }

  // Reads an arithmetic value stored little-endian (or big-endian when `big_endian`).
  template <typename T>
  T read(const char* what, bool big_endian = false) {
    static_assert(std::is_arithmetic_v<T>);
    auto raw = bytes(sizeof(T), what);
    uint8_t buffer[sizeof(T)];
    std::memcpy(buffer, raw.data(), sizeof(T));
    const bool host_little = std::endian::native == std::endian::little;
    if (big_endian == host_little) {
      for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(buffer[i], buffer[sizeof(T) - 1 - i]);
    }
    T value;
    std::memcpy(&value, buffer, sizeof(T));
    return value;
  }

  void seek(size_t position, const char* what) {
    if (position > bytes_.size()) {
      throw Error(ErrorCode::kTruncated, source_ + ": truncated: " + what + " at offset " + std::to_string(position) +
                                             " lies past the end (" + std::to_string(bytes_.size()) + " bytes)");
    }
    pos_ = position;
  }

 private:
  std::span<const uint8_t> bytes_;
  std::string source_;
  size_t pos_ = 0;
};

}  // namespace facemorph::format
