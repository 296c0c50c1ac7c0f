// What the AVIF decoding and encoding share of libavif (the decoder's image_decode.cpp, and the
// writer's image_encode.cpp, whose avif_colour_round_trip converts back as the decoder does):
// handles freed on every path, and the conversion of a decoded frame to RGB. Private to the image
// codecs: its own library, facemorph_avif_image (codec/core/CMakeLists.txt), so that core itself
// links no image codec and the writer need not link the decoder for it.
#pragma once

#include "codec/core/image/image.hpp"

#include <avif/avif.h>

#include <cstring>
#include <string>

namespace facemorph {

// libavif's objects, freed on every path.
struct AvifImageFree {
  void operator()(avifImage* image) const { avifImageDestroy(image); }
};
struct AvifDecoderFree {
  void operator()(avifDecoder* decoder) const { avifDecoderDestroy(decoder); }
};
struct AvifRgb {
  avifRGBImage rgb;
  AvifRgb() { std::memset(&rgb, 0, sizeof rgb); }
  ~AvifRgb() { avifRGBImageFreePixels(&rgb); }
};

// An 8-bit decoded frame as RGB (`channels` 3) or opaque RGBA (4); kCorrupt naming `source` when
// libavif cannot convert it.
Image rgb_of(const avifImage* decoded, int channels, const std::string& source);

}  // namespace facemorph
