// Frame patches range-coded (PTCH from format 2.5, spec/container.md §7.5.1): each patch's time
// change, lattice size and moving nodes as adaptive decisions on one stream. A patch moves a few
// neighbouring nodes of a mostly still C × C lattice, often where the patch before it moved them,
// by codes of a few units: the nodes as occupancy flags under their neighbours' and the previous
// patch's flags, the codes as §7.3's residuals under their lattice neighbours' codes. On Medusa
// that is about two thirds of the zigzag varints zstd'd (format 2.4's coding).
//
// This layer knows integers and lattice indices only; what a patch means is the container's
// (codec/core/sequence/frame_patch.hpp). Both sides are the format, to the bit.
#pragma once

#include "format/range_coder.hpp"
#include "format/ranged_residuals.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace facemorph::format {

// The largest lattice a patch may have (C ≤ 129: §7.5), so that what the coder keeps of a lattice,
// two of them of 4 bytes a node, stays within 2 · 4 · 129² bytes whatever a file states.
inline constexpr int32_t kMaxRangedPatchLattice = 129;

// One patch as the stream holds it. `nodes`: increasing lattice indices b·C + a below C²; `codes`:
// one x, y, z each (|code| ≤ kMaxRangedResidual).
struct CodedPatch {
  int64_t time_change = 0;  // 64ths of a frame period since the previous patch's time, ≥ 1
  int32_t lattice = 0;      // C, 2 … kMaxRangedPatchLattice
  std::vector<int32_t> nodes;
  std::vector<std::array<int64_t, 3>> codes;
};

// What a patch stream adapts, carried from patch to patch (spec/container.md §7.5.1).
struct PatchModels {
  BitModel off_frame, new_lattice, empty;
  NumberModels frames, remainder, lattice;
  std::array<BitModel, 32> occupied;  // by the left, up, up-left, up-right flags and the previous patch's
  std::array<ResidualModels, 3> codes;  // x, y, z: one set each
};

// A patch's lattice as the next one's contexts read it: for each node its place among the moving
// nodes (−1: still), and their codes.
struct PatchLattice {
  int32_t lattice = 0;          // C; 0 before the first patch
  std::vector<int32_t> element;  // C² entries; empty where no node moved
  std::vector<std::array<int64_t, 3>> codes;
};

// kInvalidArgument for a patch the stream cannot hold (a time change below 1 or of 2^42 frames or more, a
// lattice outside 2 … 129, nodes not increasing within C², codes beyond 2^34, a code count other
// than the nodes').
class PatchStreamWriter {
 public:
  void add(const CodedPatch& patch);
  std::vector<uint8_t> finish() { return stream_.finish(); }

 private:
  RangedStreamWriter stream_;
  PatchModels models_;
  PatchLattice previous_;
};

// The reader of a PatchStreamWriter's stream, a patch at a time so that its caller checks each
// value (times against the keyframes, memory against the budget) before the next is read. Every
// error is kCorrupt naming `source`: a stream that ends before its last decision or runs on after
// it (expect_end), a value out of its range.
class PatchStreamReader {
 public:
  PatchStreamReader(std::span<const uint8_t> bytes, std::string source);
  // The next patch's time change (≥ 1) and lattice size (2 … 129).
  int64_t time_change();
  int32_t lattice();
  // Its moving nodes: decodes the lattice's flags (held here, C² entries) and returns their count.
  size_t occupancy();
  // The nodes occupancy() found, in increasing order, and their codes: both spans of its count.
  void nodes_and_codes(std::span<int32_t> nodes, std::span<std::array<int64_t, 3>> codes);
  void expect_end() const { stream_.expect_end(); }

 private:
  RangedStreamReader stream_;
  std::string source_;
  PatchModels models_;
  PatchLattice previous_, current_;
};

}  // namespace facemorph::format
