// What an encode writes into its file's header as settings (spec/container.md §5: informative JSON
// that fminfo shows): the options as given and what the encoder chose from them, the frames
// dropped, the conformal maps that fell back, and the scanner repairs. One writer for fmenc and the
// Python package, whose files must be the same bytes.
#pragma once

#include "codec/encoder/encode/sequence_encoder.hpp"

#include <cstddef>
#include <string>

namespace facemorph {

// How many repaired frames the settings list by name (the rest are counted in the totals: a long
// capture repairs every frame alike, and the header's settings stay small).
inline constexpr size_t kRepairedFramesListed = 16;

// The settings as a JSON object, keys in a fixed order.
std::string encode_settings_json(const EncodeOptions& options, const EncodeReport& report);

}  // namespace facemorph
