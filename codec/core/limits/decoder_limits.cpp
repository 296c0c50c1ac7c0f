// DecoderLimits (codec/core/limits/decoder_limits.hpp): what a file may make a decoder allocate, estimated from its
// header before anything is decoded (spec/container.md §10.1).
#include "codec/core/limits/decoder_limits.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "format/error.hpp"

#include <limits>

namespace facemorph {

namespace {

// Saturating arithmetic: an estimate that overflows is over every budget.
uint64_t add(uint64_t a, uint64_t b) { return a > std::numeric_limits<uint64_t>::max() - b ? std::numeric_limits<uint64_t>::max() : a + b; }
uint64_t mul(uint64_t a, uint64_t b) {
  return b != 0 && a > std::numeric_limits<uint64_t>::max() / b ? std::numeric_limits<uint64_t>::max() : a * b;
}

}  // namespace

uint64_t estimated_memory_bytes(int grid_n, uint64_t keyframes, int texture_size, uint64_t values_per_keyframe) {
  // Measured peaks (spec/container.md §10.1): the multigrid solver took 421 bytes a node at N = 257
  // and 513, G alone 108; fmdec --null of an encoder's N = 257 file (3 keyframes of 1024²) peaked at
  // 92 MB above the process's own 8 MB, which these constants put at 106 MB (G, geometry, solver,
  // the decoder's work arrays, the decode's temporaries: counted as 1.5 kB a node).
  constexpr uint64_t kSolverBytesPerNode = 1024, kFrameBytesPerNode = 512;
  const DiskGridShape shape = disk_grid_shape(grid_n);
  const auto nodes = static_cast<uint64_t>(shape.interior_count) + static_cast<uint64_t>(shape.rim_count);
  const auto texels = mul(static_cast<uint64_t>(texture_size), static_cast<uint64_t>(texture_size));
  // Per keyframe: its float64 arrays, its reconstructed surface (3 doubles a node), its RGB texture.
  const uint64_t per_keyframe = add(add(mul(values_per_keyframe, 8), mul(nodes, 24)), mul(texels, 3));
  // A decoded frame: the blended texture (RGB) and the caller's RGBA copy.
  const uint64_t frame = add(mul(nodes, kFrameBytesPerNode), mul(texels, 7));
  return add(add(mul(keyframes, per_keyframe), mul(nodes, kSolverBytesPerNode)), frame);
}

uint64_t index_memory_bytes(uint64_t keyframes) {
  // Counted: the time (8), index entry (24), pose (96) and its unwrapped rotation vector (24), the
  // byte counts fminfo shows (16), a decoder's empty surface slot and failure string (64): 232.
  constexpr uint64_t kBytesPerKeyframe = 256;
  return mul(keyframes, kBytesPerKeyframe);
}

void WorkMeter::refuse(const std::string& what) {
  stopped_ = true;
  throw Error(ErrorCode::kLimit, (where_.empty() ? std::string() : where_ + ": ") + what + " would take the call past its work limit of " +
                                     std::to_string(limit_) + " units (max_work, --max-work; " + std::to_string(spent_) +
                                     " spent): call again to go on from here, or raise the limit");
}

void check_decoder_limits(const DecoderLimits& limits, const std::string& what) {
  if (limits.max_grid_n < kMinGridSize)
    throw Error(ErrorCode::kInvalidArgument, what + ": the largest grid must be at least " + std::to_string(kMinGridSize));
  if (limits.max_keyframes < 1) throw Error(ErrorCode::kInvalidArgument, what + ": at least one keyframe must be allowed");
  if (limits.max_texture_size < 0) throw Error(ErrorCode::kInvalidArgument, what + ": a negative texture size");
  if (limits.max_memory_bytes == 0) throw Error(ErrorCode::kInvalidArgument, what + ": no memory allowed");
}

}  // namespace facemorph
