// The header dictionary (spec/container.md §3.4): frozen bytes, part of the format from 2.5 on, that
// a chunk's zstd frame may be compressed against (chunk flag bit 2; zstd's raw-content prefix). The
// writer compresses the header (HEAD) against it: most of a header is the encoder's settings JSON
// and the landmark names, whose keys and words every file repeats, which a lone header pays for in
// full. The bytes are format/header_dictionary.bin, embedded when the library is built; every 2.5+
// decoder needs exactly these bytes, forever, so the file never changes (its SHA-256 is tested).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

namespace facemorph::format {

std::span<const uint8_t> header_dictionary();

// SHA-256 of format/header_dictionary.bin, as spec/container.md §3.4 states it.
inline constexpr std::string_view kHeaderDictionarySha256 = "10802765cbc988f0a160f39dad0392283aab712981e555587b0135ec352caee8";

}  // namespace facemorph::format
