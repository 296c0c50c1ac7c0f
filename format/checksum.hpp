// CRC-32 as PNG, zip and zlib compute it (ISO-HDLC: polynomial 0x04C11DB7 reflected, i.e.
// 0xEDB88320; initial value and final XOR 0xFFFFFFFF). spec/container.md §2 defines it for the
// container; crc32("123456789") = 0xCBF43926.
#pragma once

#include <cstdint>
#include <span>

namespace facemorph::format {

// The CRC of `bytes` continuing from `crc` (the CRC of what came before; 0 to start).
uint32_t crc32(std::span<const uint8_t> bytes, uint32_t crc = 0);

}  // namespace facemorph::format
