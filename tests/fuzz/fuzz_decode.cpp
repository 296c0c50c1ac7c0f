// libFuzzer target: the whole decode path a player runs on a file it did not write. Opens the bytes
// (checksums mended, see mend_checksums.hpp) under the fuzzing limits and decodes several times —
// the keyframes, between them, past the ends with and without clamping, the same t twice — through
// the C API, as a player does. A named status is the right answer to a bad file; a crash, a
// sanitizer report, a time or memory beyond the limits (libFuzzer's -timeout and -rss_limit_mb,
// set by the test to match them), or FM_OK with a number that is not finite is a bug.
#include "facemorph.h"
#include "tests/fuzz/mend_checksums.hpp"

#include <cmath>
#include <cstdlib>
#include <vector>

namespace {

// The fuzzing limits: small enough that every accepted file decodes in well under the test's
// -timeout, and within its -rss_limit_mb with the sanitizers' overhead (spec/container.md §10.3).
fm_decoder_options fuzz_options() {
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  options.max_grid_n = 65;
  options.max_keyframes = 64;
  options.max_texture_size = 256;
  options.max_memory_bytes = uint64_t{128} << 20;
  // The work of one call (§10.3), an eighth of the default: about 0.15 s natively, so that a call
  // stays far under -timeout with the sanitizers' 3-10x; an input the limit stops is a named
  // FM_ERROR_LIMIT like any other refusal, and one that takes longer anyway is a finding.
  options.max_work = FM_DEFAULT_MAX_WORK / 8;
  return options;
}

void check_finite(const std::vector<float>& values, uint32_t count) {
  for (uint32_t i = 0; i < count && i < values.size(); ++i) {
    if (!std::isfinite(values[i])) std::abort();  // FM_OK with a non-finite number
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  facemorph::fuzz::mend_checksums(bytes);
  const fm_decoder_options options = fuzz_options();
  fm_file* file = nullptr;
  const fm_status opened = fm_file_open_memory_with_options(bytes.data(), bytes.size(), &options, &file);
  if (opened == FM_ERROR_INVALID_ARGUMENT || opened == FM_ERROR_INTERNAL) std::abort();  // a file's fault blamed on the caller, or a bug
  if (opened != FM_OK) return 0;
  fm_info info;
  fm_info_init(&info);
  fm_decoder* decoder = nullptr;
  if (fm_file_get_info(file, &info) != FM_OK || fm_decoder_create(file, &decoder) != FM_OK) std::abort();  // an opened file has both
  fm_file_close(file);                                                                                     // the decoder keeps it
  std::vector<double> times(info.keyframe_count);
  size_t count = 0;
  if (fm_file_get_keyframe_times(file, times.data(), times.size(), &count) != FM_ERROR_CLOSED_HANDLE) std::abort();
  std::vector<float> positions(3 * static_cast<size_t>(info.max_vertex_count)), normals(positions.size()),
      uvs(2 * static_cast<size_t>(info.max_vertex_count));
  std::vector<uint32_t> indices(3 * static_cast<size_t>(info.max_triangle_count));
  std::vector<uint8_t> texture(4 * static_cast<size_t>(info.texture_size) * info.texture_size);
  const double span = info.last_time - info.first_time;
  const double ts[] = {info.first_time, info.first_time + 0.37 * span, info.first_time + 0.37 * span,
                       info.last_time,  info.last_time + span + 1,     info.first_time - 1};
  for (size_t i = 0; i < sizeof ts / sizeof ts[0]; ++i) {
    fm_frame frame;
    fm_frame_init(&frame);
    frame.positions = positions.data(), frame.positions_bytes = sizeof(float) * positions.size();
    frame.normals = normals.data(), frame.normals_bytes = sizeof(float) * normals.size();
    frame.uvs = uvs.data(), frame.uvs_bytes = sizeof(float) * uvs.size();
    frame.indices = indices.data(), frame.indices_bytes = sizeof(uint32_t) * indices.size();
    frame.texture = texture.empty() ? nullptr : texture.data(), frame.texture_bytes = texture.size();
    const uint32_t flags = i >= 4 ? FM_DECODE_CLAMP : 0;
    const fm_status status = fm_decoder_decode(decoder, ts[i], flags, &frame);
    if (status == FM_ERROR_INVALID_ARGUMENT || status == FM_ERROR_INTERNAL || status == FM_ERROR_BUFFER_TOO_SMALL)
      std::abort();  // never the file's fault
    if (status != FM_OK) continue;
    if (frame.vertex_count > info.max_vertex_count || frame.triangle_count > info.max_triangle_count) std::abort();
    check_finite(positions, 3 * frame.vertex_count);
    check_finite(normals, 3 * frame.vertex_count);
    check_finite(uvs, 2 * frame.vertex_count);
    for (uint32_t f = 0; f < 3 * frame.triangle_count; ++f) {
      if (indices[f] >= frame.vertex_count) std::abort();
    }
  }
  if (fm_decoder_release(decoder) != FM_OK || fm_decoder_release(decoder) != FM_ERROR_CLOSED_HANDLE) std::abort();
  return 0;
}
