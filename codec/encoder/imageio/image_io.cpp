#include "codec/encoder/imageio/image_io.hpp"

#include "codec/encoder/imageio/opencv_codecs.hpp"

#include "format/error.hpp"
#include "format/file_io.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>

namespace facemorph {
namespace fs = std::filesystem;

Image decode_image(std::span<const uint8_t> bytes, const std::string& source) {
  const OpenCvImageCodecs& codecs = opencv_image_codecs(source);
  const cv::Mat raw(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<uint8_t*>(bytes.data()));
  cv::Mat decoded;
  try {
    decoded = codecs.imdecode(raw, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    decoded.release();
  }
  if (decoded.empty()) throw Error(ErrorCode::kMissingTexture, source + ": not a decodable image");
  cv::Mat rgb;
  cv::cvtColor(decoded, rgb, cv::COLOR_BGR2RGB);
  Image image(rgb.cols, rgb.rows, 3);
  for (int y = 0; y < rgb.rows; ++y) std::copy_n(rgb.ptr<uint8_t>(y), rgb.cols * 3, image.at(0, y));
  return image;
}

Image read_image(const fs::path& path) {
  std::vector<uint8_t> bytes;
  try {
    bytes = format::read_file(path, uint64_t{1} << 30);
  } catch (const Error& e) {
    throw Error(ErrorCode::kMissingTexture, std::string("texture ") + e.what());
  }
  return decode_image(bytes, path.string());
}

std::vector<uint8_t> encode_image(const Image& image, const std::string& extension, int quality) {
  std::string ext = extension;
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".jpeg") ext = ".jpg";
  if (ext != ".png" && ext != ".jpg" && ext != ".webp") {
    throw Error(ErrorCode::kInvalidArgument, "unsupported image type '" + extension + "' (png, jpg, webp)");
  }
  if (image.empty() || (image.channels != 3 && image.channels != 4)) {
    throw Error(ErrorCode::kInvalidArgument, "cannot encode an empty image or one with " + std::to_string(image.channels) + " channels");
  }
  const OpenCvImageCodecs& codecs = opencv_image_codecs("encoding an image to " + ext);
  const cv::Mat view(image.height, image.width, image.channels == 3 ? CV_8UC3 : CV_8UC4, const_cast<uint8_t*>(image.pixels.data()));
  cv::Mat bgr;
  cv::cvtColor(view, bgr, image.channels == 3 ? cv::COLOR_RGB2BGR : cv::COLOR_RGBA2BGRA);
  std::vector<int> params;
  if (ext == ".jpg") params = {cv::IMWRITE_JPEG_QUALITY, std::clamp(quality, 1, 100)};
  if (ext == ".webp") params = {cv::IMWRITE_WEBP_QUALITY, std::clamp(quality, 1, 100)};
  std::vector<uint8_t> bytes;
  if (!codecs.imencode(ext, bgr, bytes, params)) throw Error(ErrorCode::kIo, "image encoding to " + ext + " failed");
  return bytes;
}

void write_image(const fs::path& path, const Image& image, int quality) {
  format::write_file_atomically(path, encode_image(image, path.extension().string(), quality));
}

}  // namespace facemorph
