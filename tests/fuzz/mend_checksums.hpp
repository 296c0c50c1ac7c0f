// What the .fmv fuzz targets share: random bytes rarely pass a CRC-32, so a harness first mends
// every chunk checksum it can find (and the preamble's). The fuzzer then reaches the payload
// parsers, the zstd frames, the index, the validators and the decoder, which is where the bugs live.
#pragma once

#include "format/checksum.hpp"
#include "format/container.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace facemorph::fuzz {

inline uint64_t read_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

inline void write_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

inline void mend_checksums(std::vector<uint8_t>& bytes) {
  using namespace facemorph::format;
  if (bytes.size() < kPreambleBytes) return;
  write_u32(bytes.data() + 12, crc32(std::span(bytes).first(12)));
  size_t at = kPreambleBytes;
  while (at + kChunkHeaderBytes <= bytes.size()) {
    const uint64_t stored = read_u64(bytes.data() + at + 8);
    if (stored > bytes.size() - at - kChunkHeaderBytes || bytes.size() - at - kChunkHeaderBytes - stored < kChunkTrailerBytes) return;
    const size_t end = at + kChunkHeaderBytes + static_cast<size_t>(stored);
    write_u32(bytes.data() + end, crc32(std::span(bytes).subspan(at, end - at)));
    at = end + kChunkTrailerBytes;
  }
}

}  // namespace facemorph::fuzz
