// Frame patches, PTCH (spec/container.md §7.5): sparse lattice displacements of the decoded surface
// at frames between keyframes (frame_patch.hpp). In a file stamped 2.4: each time as its change in
// 64ths of a frame period, the lattice size, the moving nodes as gaps, each displacement component as
// a whole multiple of the chunk's step, all zigzag varints, zstd-compressed where that is smaller.
// From 2.5 (§7.5.1) the same values as one range-coded stream (format/ranged_patches.hpp), about
// two thirds of the bytes.
#include "codec/decoder/container/chunk_readers.hpp"

#include "format/ranged_patches.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph::file_layout {

using format::ByteReader;

namespace {

// The stream's own bounds are the chunk's (§7.5, §7.5.1).
static_assert(format::kMaxRangedPatchLattice == kMaxPatchLattice);
static_assert(kMaxRangedPatchCode == static_cast<double>(format::kMaxRangedResidual));

// The memory the patches hold, charged before each allocation (§10.1).
class PatchBudget {
 public:
  PatchBudget(const std::string& source, uint32_t count, uint64_t max_memory_bytes)
      : source_(source), memory_(uint64_t{count} * kPatchMemoryBytes), max_(max_memory_bytes) {
    if (memory_ > max_) refuse(std::to_string(count) + " frame patches");
  }
  // `what`: a literal, made a string only for the error (this runs once a patch).
  void charge(uint64_t bytes, const char* what) {
    memory_ += bytes;
    if (memory_ > max_) refuse(what);
  }

 private:
  [[noreturn]] void refuse(const std::string& what) const {
    over_limit(source_, what + " need " + std::to_string(memory_) + " bytes, more than max_memory_bytes (" + std::to_string(max_) + ")");
  }
  const std::string& source_;
  uint64_t memory_, max_;
};

int read_step_exponent(ByteReader& r) {
  const int e = r.read<int8_t>("the step exponent");
  if (e < kMinPatchStepExponent || e > kMaxPatchStepExponent) {
    corrupt(r.source(), "step exponent " + std::to_string(e) + " outside " + std::to_string(kMinPatchStepExponent) + ".." +
                            std::to_string(kMaxPatchStepExponent));
  }
  return e;
}

// |code · 2^e| ≤ kMaxCoordinate (a displacement as large as a pose's translation may be, no
// larger), and |code| within the coding's own bound.
double max_code_for(int e, double coding_bound) { return std::min(coding_bound, std::floor(std::ldexp(kMaxCoordinate, -e))); }

void check_lattice(int64_t lattice, const std::string& source, ItemName name) {
  if (lattice < kMinPatchLattice || lattice > kMaxPatchLattice) {
    corrupt(source, name.str() + ": lattice " + std::to_string(lattice) + " outside " + std::to_string(kMinPatchLattice) + ".." +
                        std::to_string(kMaxPatchLattice));
  }
}

// Format 2.4's coding: varints.
std::vector<FramePatch> read_varint_patches(ByteReader& r, const Sequence& shape, const std::vector<double>& key_times,
                                            uint64_t max_memory_bytes) {
  // Each patch takes at least three bytes (its time's change, C, its node count).
  const uint32_t count = read_item_count(r, "the patch count", "frame patches", kMaxPatches, 3);
  PatchBudget budget(r.source(), count, max_memory_bytes);
  const int e = read_step_exponent(r);
  const double max_code = max_code_for(e, kMaxPatchCode);
  std::vector<FramePatch> patches(count);
  int64_t q = 0;
  for (uint32_t p = 0; p < count; ++p) {
    const ItemName name{"frame patch", p};
    FramePatch& f = patches[p];
    f.time = read_item_time(r, "a patch time's change", name, shape, key_times, q).time;
    const int64_t lattice = read_varint(r, "a patch's lattice size");
    check_lattice(lattice, r.source(), name);
    f.lattice = static_cast<int>(lattice);
    const int64_t lattice_nodes = lattice * lattice;
    const int64_t nodes = read_varint(r, "a patch's node count");
    // Each node takes at least four bytes (its gap and three components).
    if (nodes < 0 || nodes > lattice_nodes || static_cast<uint64_t>(nodes) > r.remaining() / 4) {
      corrupt(r.source(), name.str() + ": states " + std::to_string(nodes) + " nodes; its lattice has " + std::to_string(lattice_nodes) +
                              " and the chunk's " + std::to_string(r.remaining()) + " bytes left hold " +
                              std::to_string(r.remaining() / 4));
    }
    budget.charge(static_cast<uint64_t>(nodes) * kPatchNodeMemoryBytes, "frame patches' nodes");
    f.nodes.resize(static_cast<size_t>(nodes));
    f.displacements.resize(static_cast<size_t>(nodes));
    int64_t node = -1;
    for (int64_t n = 0; n < nodes; ++n) {
      const int64_t gap = read_varint(r, "a patch node's gap");
      if (gap < 0 || gap >= lattice_nodes - node - 1)
        corrupt(r.source(), name.str() + ": node gap " + std::to_string(gap) + " leaves its lattice of " + std::to_string(lattice_nodes));
      node += gap + 1;
      f.nodes[static_cast<size_t>(n)] = static_cast<int32_t>(node);
      for (int c = 0; c < 3; ++c) {
        const int64_t code = read_varint(r, "a patch displacement");
        if (std::abs(static_cast<double>(code)) > max_code)
          corrupt(r.source(), name.str() + ": a displacement code " + std::to_string(code) + " beyond ±" + std::to_string(max_code));
        f.displacements[static_cast<size_t>(n)][c] = std::ldexp(static_cast<double>(code), e);
      }
    }
  }
  return patches;
}

// Format 2.5's coding (§7.5.1): the count, the step, the stream's length and the stream, all but
// the step varints.
std::vector<FramePatch> read_ranged_patches(ByteReader& r, const Sequence& shape, const std::vector<double>& key_times,
                                            uint64_t max_memory_bytes) {
  const int64_t stated = read_varint(r, "the patch count");
  const int e = read_step_exponent(r);
  const int64_t length = read_varint(r, "the patch stream's length");
  if (length < 0 || static_cast<uint64_t>(length) > r.remaining()) {
    corrupt(r.source(), "a patch stream of " + std::to_string(length) + " bytes; " + std::to_string(r.remaining()) + " follow");
  }
  const auto stream_bytes = static_cast<uint64_t>(length);
  const uint64_t most = std::min<uint64_t>(kMaxPatches, kMaxRangedPatchesPerByte * stream_bytes);
  if (stated < 1 || static_cast<uint64_t>(stated) > most) {
    corrupt(r.source(), "states " + std::to_string(stated) + " frame patches; its stream of " + std::to_string(stream_bytes) +
                            " bytes holds 1 to " + std::to_string(most));
  }
  const auto count = static_cast<uint32_t>(stated);
  PatchBudget budget(r.source(), count, max_memory_bytes);
  const double max_code = max_code_for(e, kMaxRangedPatchCode);
  format::PatchStreamReader stream(r.bytes(static_cast<size_t>(stream_bytes), "the patch stream"), r.source());
  std::vector<FramePatch> patches(count);
  int64_t q = 0;
  for (uint32_t p = 0; p < count; ++p) {
    const ItemName name{"frame patch", p};
    FramePatch& f = patches[p];
    f.time = item_time(stream.time_change(), r.source(), name, shape, key_times, q).time;
    f.lattice = stream.lattice();  // 2 … 129, checked by the stream
    const size_t nodes = stream.occupancy();  // at most C² ≤ 129², held by the stream
    budget.charge(nodes * kPatchNodeMemoryBytes, "frame patches' nodes");
    f.nodes.resize(nodes);
    std::vector<std::array<int64_t, 3>> codes(nodes);
    stream.nodes_and_codes(f.nodes, codes);
    f.displacements.resize(nodes);
    for (size_t n = 0; n < nodes; ++n) {
      for (int c = 0; c < 3; ++c) {
        if (std::abs(static_cast<double>(codes[n][c])) > max_code)
          corrupt(r.source(), name.str() + ": a displacement code " + std::to_string(codes[n][c]) + " beyond ±" + std::to_string(max_code));
        f.displacements[n][c] = std::ldexp(static_cast<double>(codes[n][c]), e);
      }
    }
  }
  stream.expect_end();
  return patches;
}

}  // namespace

std::vector<FramePatch> read_patches(std::span<const uint8_t> payload, const std::string& source, const Sequence& shape,
                                     const std::vector<double>& key_times, uint64_t max_memory_bytes, uint16_t minor_version) {
  ByteReader r(payload, source + ": frame patches");
  std::vector<FramePatch> patches = minor_version >= kRangedPatchMinorVersion
                                        ? read_ranged_patches(r, shape, key_times, max_memory_bytes)
                                        : read_varint_patches(r, shape, key_times, max_memory_bytes);
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
