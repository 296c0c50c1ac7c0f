// Checksums and fingerprints. CRC-32 as PNG, zip and zlib compute it (ISO-HDLC: polynomial 0x04C11DB7 reflected, i.e.
// 0xEDB88320; initial value and final XOR 0xFFFFFFFF). spec/container.md §2 defines it for the
// container; crc32("123456789") = 0xCBF43926.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace facemorph::format {

// The CRC of `bytes` continuing from `crc` (the CRC of what came before; 0 to start).
uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

// FNV-1a, 64 bits, of `size` bytes at `data`, continuing from `hash` (kFnv1aStart to start): the
// fingerprints an encode's stages compare (a capture's, a segmented encode's), never stored where
// another program must compute them again.
inline constexpr uint64_t kFnv1aStart = 0xcbf29ce484222325ull;
inline uint64_t fnv1a(uint64_t hash, const void* data, size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) hash = (hash ^ p[i]) * 0x100000001b3ull;
  return hash;
}

}  // namespace facemorph::format
