// Frame patches, PTCH (spec/container.md §7.5, format 2.4), as the writer codes them; the reader is
// codec/decoder/container/patch_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include <cmath>
#include <optional>

namespace facemorph::file_layout {

using format::ByteWriter;

namespace {

// The coarsest step 2^e (kMinPatchStepExponent ≤ e ≤ kMaxPatchStepExponent) of which every
// displacement component is a whole multiple, with every code within the varint's 2^40.
std::optional<int> patch_step_exponent(const std::vector<FramePatch>& patches) {
  for (int e = kMaxPatchStepExponent; e >= kMinPatchStepExponent; --e) {
    bool exact = true;
    for (const FramePatch& f : patches) {
      for (const Vec3& d : f.displacements) {
        for (int c = 0; c < 3 && exact; ++c) {
          const double code = std::ldexp(d[c], -e);
          exact = code == std::nearbyint(code) && std::abs(code) <= kMaxPatchCode;
        }
      }
    }
    if (exact) return e;
  }
  return std::nullopt;
}

}  // namespace

std::vector<uint8_t> write_patches(const SequenceOutline& o) {
  const std::vector<FramePatch>& patches = o.patches;
  const auto fail = [](size_t p, const std::string& what) {
    throw Error(ErrorCode::kInvalidArgument, "frame patch " + std::to_string(p) + ": " + what);
  };
  if (patches.empty() || patches.size() > kMaxPatches) throw Error(ErrorCode::kInvalidArgument, "frame patches: 1 to 2^24 of them");
  validate_patches(o.times, patches);
  const std::optional<int> e = patch_step_exponent(patches);
  if (!e) {
    throw Error(ErrorCode::kInvalidArgument, "frame patches: displacements are not whole multiples of one power of two 2^" +
                                                 std::to_string(kMinPatchStepExponent) + " … 2^" + std::to_string(kMaxPatchStepExponent) +
                                                 " with codes within 2^40");
  }
  ByteWriter w;
  w.write(static_cast<uint32_t>(patches.size()));
  w.write(static_cast<int8_t>(*e));
  int64_t previous = 0;
  for (size_t p = 0; p < patches.size(); ++p) {
    const FramePatch& f = patches[p];
    if (!write_item_time(w, f.time, o, previous))
      fail(p, "its time is not a 64th of a frame period after the previous one's (residual_time)");
    write_varint(w, f.lattice);
    write_varint(w, static_cast<int64_t>(f.nodes.size()));
    int64_t node = -1;
    for (size_t n = 0; n < f.nodes.size(); ++n) {
      write_varint(w, f.nodes[n] - node - 1);
      node = f.nodes[n];
      for (int c = 0; c < 3; ++c) write_varint(w, static_cast<int64_t>(std::ldexp(f.displacements[n][c], -*e)));
    }
  }
  return w.take();
}

}  // namespace facemorph::file_layout
