// What a decoder may spend on a file it did not write (spec/container.md §10): the largest grid,
// keyframe count and texture a file may state, and a memory budget. Every size a file states is
// compared with these and with the bytes the file actually has before anything is allocated; a file
// over a limit is refused with kLimit naming the limit (zstd's ZSTD_d_windowLogMax, libavif's
// imageDimensionLimit). The defaults hold every grid and texture size facemorph's encoder chooses
// automatically (N <= 1025, M <= 1024). Keyframes are decoded on demand (open_sequence_source): the
// memory budget sets how many an opened file and a decoder on it keep at once, never fewer than a
// frame blends (§10.1), whatever the file's length. decode_sequence_file, which decodes a file
// whole, holds every keyframe and is refused where they exceed the budget.
#pragma once

#include <cstdint>
#include <string>

namespace facemorph {

struct DecoderLimits {
  int max_grid_n = 1025;               // N of the disk grid G (the format allows up to 4097)
  uint32_t max_keyframes = 65536;      // keyframes in one file (the format allows up to 2^20)
  int max_texture_size = 4096;         // M, texels per side (the format allows up to 16384)
  uint64_t max_memory_bytes = uint64_t{512} << 20;  // what an opened file and one decoder on it may hold, bytes
};

inline constexpr DecoderLimits kDefaultDecoderLimits{};

// What decoding from a file holds at most, in bytes, from what its header states, with `keyframes`
// keyframes held at once: their fields (`values_per_keyframe` float64 values), textures (RGB8) and
// reconstructed surfaces, G with its multigrid solver, and one decoded frame. An
// estimate that errs high (spec/container.md §10.1 gives the constants); it saturates at
// UINT64_MAX instead of overflowing.
uint64_t estimated_memory_bytes(int grid_n, uint64_t keyframes, int texture_size, uint64_t values_per_keyframe);

// What an opened file holds per keyframe whatever is decoded: its time, pose, index entry and
// byte counts, a decoder's slot for its surface (spec/container.md §10.1: 256 bytes a keyframe).
uint64_t index_memory_bytes(uint64_t keyframes);

// Throws kInvalidArgument for limits a decoder cannot run under (a grid below 5, no keyframe, no
// memory); `what` names the caller's option.
void check_decoder_limits(const DecoderLimits& limits, const std::string& what = "decoder limits");

}  // namespace facemorph
