// Frame patches, PTCH (spec/container.md §7.5, format 2.4): sparse lattice displacements of the
// decoded surface at frames between keyframes (frame_patch.hpp). A few bytes a frame: each time as
// its change in 64ths of a frame period, the lattice size, the moving nodes as gaps, each
// displacement component as a whole multiple of the chunk's step, all zigzag varints; the chunk is
// zstd-compressed where that is smaller.
#include "codec/decoder/container/chunk_readers.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph::file_layout {

using format::ByteReader;

std::vector<FramePatch> read_patches(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                     const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version) {
  ByteReader r(payload, source + ": frame patches");
  // Each patch takes at least three bytes (its time's change, C, its node count).
  const uint32_t count = read_item_count(r, "the patch count", "frame patches", kMaxPatches, 3);
  uint64_t memory = uint64_t{count} * kPatchMemoryBytes;
  const auto charge = [&](uint64_t bytes, const std::string& what) {
    memory += bytes;
    if (memory > max_memory_bytes) {
      over_limit(r.source(), what + " need " + std::to_string(memory) + " bytes, more than max_memory_bytes (" +
                                 std::to_string(max_memory_bytes) + ")");
    }
  };
  charge(0, std::to_string(count) + " frame patches");
  const int e = r.read<int8_t>("the step exponent");
  if (e < kMinPatchStepExponent || e > kMaxPatchStepExponent) {
    corrupt(r.source(), "step exponent " + std::to_string(e) + " outside " + std::to_string(kMinPatchStepExponent) + ".." +
                            std::to_string(kMaxPatchStepExponent));
  }
  // |code · 2^e| ≤ kMaxCoordinate (a displacement as large as a pose's translation may be, no
  // larger), and |code| ≤ 2^40, the varint's bound.
  const double max_code = std::min(kMaxPatchCode, std::floor(std::ldexp(kMaxCoordinate, -e)));
  std::vector<FramePatch> patches(count);
  int64_t q = 0;
  for (uint32_t p = 0; p < count; ++p) {
    const std::string name = "frame patch " + std::to_string(p);
    FramePatch& f = patches[p];
    f.time = read_item_time(r, "a patch time's change", name, shape, key_times, q).time;
    const int64_t lattice = read_varint(r, "a patch's lattice size");
    if (lattice < kMinPatchLattice || lattice > kMaxPatchLattice) {
      corrupt(r.source(), name + ": lattice " + std::to_string(lattice) + " outside " + std::to_string(kMinPatchLattice) + ".." +
                              std::to_string(kMaxPatchLattice));
    }
    f.lattice = static_cast<int>(lattice);
    const int64_t lattice_nodes = lattice * lattice;
    const int64_t nodes = read_varint(r, "a patch's node count");
    // Each node takes at least four bytes (its gap and three components).
    if (nodes < 0 || nodes > lattice_nodes || static_cast<uint64_t>(nodes) > r.remaining() / 4) {
      corrupt(r.source(), name + ": states " + std::to_string(nodes) + " nodes; its lattice has " + std::to_string(lattice_nodes) +
                              " and the chunk's " + std::to_string(r.remaining()) + " bytes left hold " +
                              std::to_string(r.remaining() / 4));
    }
    charge(static_cast<uint64_t>(nodes) * kPatchNodeMemoryBytes, "frame patches' nodes");
    f.nodes.resize(static_cast<size_t>(nodes));
    f.displacements.resize(static_cast<size_t>(nodes));
    int64_t node = -1;
    for (int64_t n = 0; n < nodes; ++n) {
      const int64_t gap = read_varint(r, "a patch node's gap");
      if (gap < 0 || gap >= lattice_nodes - node - 1)
        corrupt(r.source(), name + ": node gap " + std::to_string(gap) + " leaves its lattice of " + std::to_string(lattice_nodes));
      node += gap + 1;
      f.nodes[static_cast<size_t>(n)] = static_cast<int32_t>(node);
      for (int c = 0; c < 3; ++c) {
        const int64_t code = read_varint(r, "a patch displacement");
        if (std::abs(static_cast<double>(code)) > max_code)
          corrupt(r.source(), name + ": a displacement code " + std::to_string(code) + " beyond ±" + std::to_string(max_code));
        f.displacements[static_cast<size_t>(n)][c] = std::ldexp(static_cast<double>(code), e);
      }
    }
  }
  // Later minor versions may append here; this reader skips them (a bounded number of bytes).
  check_appended_bytes(r.remaining(), minor_version, r.source());
  try {
    validate_patches(key_times, patches);  // what the decoder relies on, each already checked above
  } catch (const Error& error) {
    corrupt(r.source(), error.what());
  }
  return patches;
}

}  // namespace facemorph::file_layout
