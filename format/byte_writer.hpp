// The writing half of byte_reader.hpp: little-endian values appended to a growing buffer, so every
// structure of the container is written by the same few lines its reader mirrors.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>
#include <type_traits>
#include <vector>

namespace facemorph::format {

class ByteWriter {
 public:
  template <typename T>
  void write(T value) {
    static_assert(std::is_arithmetic_v<T>);
    uint8_t buffer[sizeof(T)];
    std::memcpy(buffer, &value, sizeof(T));
    if constexpr (std::endian::native == std::endian::big) {
      for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(buffer[i], buffer[sizeof(T) - 1 - i]);
    }
    // resize + memcpy, not insert: g++ 12 warns falsely (-Wstringop-overflow) on a vector insert.
    const size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, buffer, sizeof(T));
  }

  void bytes(std::span<const uint8_t> data) {
    if (data.empty()) return;
    const size_t at = bytes_.size();
    bytes_.resize(at + data.size());
    std::memcpy(bytes_.data() + at, data.data(), data.size());
  }

  // A string as the container stores one: u32 byte count, then the UTF-8 bytes (no terminator).
  void string(std::string_view text) {
    write(static_cast<uint32_t>(text.size()));
    bytes({reinterpret_cast<const uint8_t*>(text.data()), text.size()});
  }

  // Overwrites a u32 written earlier at `offset` (a length known only afterwards).
  void patch_u32(size_t offset, uint32_t value) {
    for (int i = 0; i < 4; ++i) bytes_[offset + static_cast<size_t>(i)] = static_cast<uint8_t>(value >> (8 * i));
  }

  size_t size() const { return bytes_.size(); }
  const std::vector<uint8_t>& data() const { return bytes_; }
  std::vector<uint8_t> take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

}  // namespace facemorph::format
