// libFuzzer target: the .fmv reader. Random bytes rarely pass a CRC-32, so the harness first mends
// every chunk checksum it can find (and the preamble's): the fuzzer then reaches the payload parsers,
// the zstd frames, the index and the validators, which is where a reader's bugs live. The reader
// itself is the production code, checksums included.
#include "facemorph/error.hpp"
#include "facemorph/sequence_file.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"

#include <cstring>
#include <vector>

namespace {

uint64_t read_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

void write_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

void mend_checksums(std::vector<uint8_t>& bytes) {
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  mend_checksums(bytes);
  try {
    facemorph::decode_sequence_file(bytes, "fuzz.fmv");
  } catch (const facemorph::Error&) {
    // A named error is the right answer to a bad file; anything else (a crash, a sanitizer report,
    // another exception type escaping) is a bug.
  }
  return 0;
}
