// Frame patches, PTCH (spec/container.md §7.5, format 2.5's coding, §7.5.1), as the writer codes
// them; the reader is codec/decoder/container/patch_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include "format/ranged_patches.hpp"

#include <cmath>
#include <optional>

namespace facemorph::file_layout {

using format::ByteWriter;

namespace {

// The coarsest step 2^e (kMinPatchStepExponent ≤ e ≤ kMaxPatchStepExponent) of which every
// displacement component is a whole multiple, with every code within the range coder's 2^34.
std::optional<int> patch_step_exponent(const std::vector<FramePatch>& patches) {
  for (int e = kMaxPatchStepExponent; e >= kMinPatchStepExponent; --e) {
    bool exact = true;
    for (const FramePatch& f : patches) {
      for (const Vec3& d : f.displacements) {
        for (int c = 0; c < 3 && exact; ++c) {
          const double code = std::ldexp(d[c], -e);
          exact = code == std::nearbyint(code) && std::abs(code) <= kMaxRangedPatchCode;
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
                                                 " with codes within 2^34");
  }
  format::PatchStreamWriter stream;
  int64_t previous = 0;
  for (size_t p = 0; p < patches.size(); ++p) {
    const FramePatch& f = patches[p];
    format::CodedPatch coded;
    const std::optional<int64_t> change = item_time_change(f.time, o, previous);
    if (!change) fail(p, "its time is not a 64th of a frame period after the previous one's (residual_time)");
    coded.time_change = *change;
    coded.lattice = f.lattice;
    coded.nodes = f.nodes;
    coded.codes.reserve(f.displacements.size());
    for (const Vec3& d : f.displacements) {
      coded.codes.push_back({static_cast<int64_t>(std::ldexp(d[0], -*e)), static_cast<int64_t>(std::ldexp(d[1], -*e)),
                             static_cast<int64_t>(std::ldexp(d[2], -*e))});
    }
    stream.add(coded);
  }
  const std::vector<uint8_t> bytes = stream.finish();
  ByteWriter w;
  write_varint(w, static_cast<int64_t>(patches.size()));
  w.write(static_cast<int8_t>(*e));
  write_varint(w, static_cast<int64_t>(bytes.size()));
  w.bytes(bytes);
  return w.take();
}

}  // namespace facemorph::file_layout
