// libFuzzer target: the .fmv reader. Random bytes rarely pass a CRC-32, so the harness first mends
// every chunk checksum it can find (and the preamble's): the fuzzer then reaches the payload parsers,
// the zstd frames, the index and the validators, which is where a reader's bugs live. The reader
// itself is the production code, checksums included.
#include "codec/decoder/container/sequence_file.hpp"
#include "format/error.hpp"
#include "tests/fuzz/mend_checksums.hpp"

#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  facemorph::fuzz::mend_checksums(bytes);
  try {
    facemorph::decode_sequence_file(bytes, "fuzz.fmv");
  } catch (const facemorph::Error&) {
    // A named error is the right answer to a bad file; anything else (a crash, a sanitizer report,
    // another exception type escaping) is a bug.
  }
  return 0;
}
