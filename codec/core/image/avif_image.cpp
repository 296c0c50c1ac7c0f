// A decoded AVIF frame as RGB, as the decoder shows it and the writer's colour round trip predicts it.
#include "codec/core/image/avif_image.hpp"

#include "format/error.hpp"

namespace facemorph {

Image rgb_of(const avifImage* decoded, int channels, const std::string& source) {
  Image image(static_cast<int>(decoded->width), static_cast<int>(decoded->height), channels);
  AvifRgb rgb;
  avifRGBImageSetDefaults(&rgb.rgb, decoded);
  rgb.rgb.format = channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.rgb.depth = 8;
  rgb.rgb.pixels = image.pixels.data();
  rgb.rgb.rowBytes = static_cast<uint32_t>(image.width * channels);
  const avifResult result = avifImageYUVToRGB(decoded, &rgb.rgb);
  rgb.rgb.pixels = nullptr;  // ours, not libavif's to free
  if (channels == 4 && decoded->alphaPlane == nullptr) {
    for (size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;  // no alpha stored: opaque
  }
  if (result != AVIF_RESULT_OK)
    throw Error(ErrorCode::kCorrupt, source + ": the AVIF image cannot be converted to RGB (" + avifResultToString(result) + ")");
  return image;
}

}  // namespace facemorph
