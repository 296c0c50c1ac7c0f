// fmdec --extract-fields: each keyframe's stored quantities as files any viewer opens. The fields
// over G as an OpenEXR image (one pixel per grid point, alpha 0 outside the disk), the boundary
// curve and the boundary-frame vectors as CSV, the texture as PNG.
#pragma once

#include "codec/core/sequence/sequence.hpp"

#include <filesystem>
#include <vector>

namespace facemorph::tools {

// Writes keyframe_KKK.exr (+ _rim.csv, _fixed.csv, _texture.png) per keyframe into `folder`
// (created). Returns the files written. Throws kIo naming a file that cannot be written.
std::vector<std::filesystem::path> export_keyframe_fields(const Sequence& sequence, const std::filesystem::path& folder);

}  // namespace facemorph::tools
