// Image files (PNG, JPEG, WebP to write; whatever OpenCV's imgcodecs reads) through OpenCV,
// loaded on first use (opencv_codecs.hpp). In the encoder so the decoder core never depends on OpenCV.
#pragma once

#include "codec/core/image/image.hpp"

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

namespace facemorph {

// Decodes an image file to RGB. Throws kMissingTexture naming the file when it is absent or
// cannot be decoded.
Image read_image(const std::filesystem::path& path);
Image decode_image(std::span<const uint8_t> bytes, const std::string& source);

// Encodes by the file extension (.png, .jpg/.jpeg, .webp); `quality` 1..100 for lossy formats.
std::vector<uint8_t> encode_image(const Image& image, const std::string& extension, int quality = 90);
// Writes atomically (temporary name, then rename). Throws kIo / kInvalidArgument.
void write_image(const std::filesystem::path& path, const Image& image, int quality = 90);

}  // namespace facemorph
