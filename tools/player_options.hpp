// The tools' decoder limits (--max-memory, --max-grid, ... : tool_support.hpp) as the player API's
// options: what fmdec and fmplay open their file with through facemorph.h.
#pragma once

#include "facemorph.h"

#include "codec/core/limits/decoder_limits.hpp"

namespace facemorph::tools {

// `limits` as fm_decoder_options, every field the API has (its defaults where `limits` has none).
inline fm_decoder_options player_options(const DecoderLimits& limits) {
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  options.max_grid_n = static_cast<uint32_t>(limits.max_grid_n);
  options.max_keyframes = limits.max_keyframes;
  options.max_texture_size = static_cast<uint32_t>(limits.max_texture_size);
  options.max_memory_bytes = limits.max_memory_bytes;
  options.max_work = limits.max_work;
  return options;
}

}  // namespace facemorph::tools
