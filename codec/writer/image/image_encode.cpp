#include "codec/writer/image/image_encode.hpp"

#include "codec/core/image/avif_image.hpp"  // rgb_of: avif_colour_round_trip converts back as the decoder does
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <avif/avif.h>
#include <png.h>
#include <webp/encode.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>

namespace facemorph {

namespace {

void require_codable(const Image& image, bool grey_allowed) {
  const bool channels_ok = image.channels == 3 || image.channels == 4 || (grey_allowed && image.channels == 1);
  if (image.empty() || !channels_ok || image.pixels.size() != static_cast<size_t>(image.width) * image.height * image.channels) {
    throw Error(ErrorCode::kInvalidArgument, "cannot encode an image of " + std::to_string(image.width) + " x " +
                                                 std::to_string(image.height) + " pixels and " + std::to_string(image.channels) +
                                                 " channels");
  }
}

}  // namespace

std::vector<uint8_t> encode_webp(const Image& image, int quality) {
  require_codable(image, false);
  WebPConfig config;
  WebPPicture picture;
  if (!WebPConfigInit(&config) || !WebPPictureInit(&picture)) throw Error(ErrorCode::kUnsupported, "libwebp version mismatch");
  config.lossless = quality > 100;
  config.quality = config.lossless ? 100.0f : static_cast<float>(quality < 0 ? 0 : quality);
  config.exact = 1;  // keep colours under transparent pixels: a lossless image comes back bit-exact
  picture.use_argb = config.lossless;
  picture.width = image.width;
  picture.height = image.height;
  const int stride = image.width * image.channels;
  const int imported = image.channels == 3 ? WebPPictureImportRGB(&picture, image.pixels.data(), stride)
                                           : WebPPictureImportRGBA(&picture, image.pixels.data(), stride);
  WebPMemoryWriter writer;
  WebPMemoryWriterInit(&writer);
  picture.writer = WebPMemoryWrite;
  picture.custom_ptr = &writer;
  const bool ok = imported && WebPEncode(&config, &picture);
  const int error = picture.error_code;
  WebPPictureFree(&picture);
  std::vector<uint8_t> bytes(writer.mem, writer.mem + writer.size);
  WebPMemoryWriterClear(&writer);
  if (!ok) {
    throw Error(ErrorCode::kInvalidArgument, "WebP encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed (libwebp error " + std::to_string(error) + "; at most 16383 per side)");
  }
  return bytes;
}

namespace {

struct AvifEncoderFree {
  void operator()(avifEncoder* encoder) const { avifEncoderDestroy(encoder); }
};
struct AvifBytes {
  avifRWData data = AVIF_DATA_EMPTY;
  ~AvifBytes() { avifRWDataFree(&data); }
};

// An image as 8-bit YUV 4:4:4, full-range BT.601 (the matrix WebP and JPEG use; every decoder
// converts back with the matrix the file signals): what the stills and the sequences code.
std::unique_ptr<avifImage, AvifImageFree> yuv_of(const Image& image) {
  require_codable(image, false);
  std::unique_ptr<avifImage, AvifImageFree> yuv(
      avifImageCreate(static_cast<uint32_t>(image.width), static_cast<uint32_t>(image.height), 8, AVIF_PIXEL_FORMAT_YUV444));
  if (!yuv) throw Error(ErrorCode::kInvalidArgument, "AVIF encoding: out of memory");
  yuv->yuvRange = AVIF_RANGE_FULL;
  yuv->matrixCoefficients = AVIF_MATRIX_COEFFICIENTS_BT601;
  avifRGBImage rgb;
  avifRGBImageSetDefaults(&rgb, yuv.get());
  rgb.format = image.channels == 4 ? AVIF_RGB_FORMAT_RGBA : AVIF_RGB_FORMAT_RGB;
  rgb.ignoreAlpha = AVIF_TRUE;                             // textures are opaque
  rgb.pixels = const_cast<uint8_t*>(image.pixels.data());  // read only: libavif's API is not const
  rgb.rowBytes = static_cast<uint32_t>(image.width * image.channels);
  const avifResult result = avifImageRGBToYUV(yuv.get(), &rgb);
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kInvalidArgument, "AVIF encoding of " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                                 " pixels failed: " + avifResultToString(result));
  }
  return yuv;
}

// The encoder the stills and the sequences share, at the AV1 quantiser of `quality`.
std::unique_ptr<avifEncoder, AvifEncoderFree> avif_encoder(int quality) {
  if (avifCodecName(AVIF_CODEC_CHOICE_AOM, AVIF_CODEC_FLAG_CAN_ENCODE) == nullptr) {
    throw Error(ErrorCode::kUnsupported, "AVIF encoding needs libavif built with libaom");
  }
  std::unique_ptr<avifEncoder, AvifEncoderFree> encoder(avifEncoderCreate());
  if (!encoder) throw Error(ErrorCode::kInvalidArgument, "AVIF encoding: out of memory");
  encoder->minQuantizer = encoder->maxQuantizer = avif_quantizer(quality);
  encoder->speed = 6;       // avifenc's default, 0.06 s for a 448² texture
  encoder->maxThreads = 1;  // the same bytes on every run (with one libaom version)
  // libaom: it codes 4:4:4 (SVT-AV1 does not), and a fixed encoder keeps the bytes reproducible.
  encoder->codecChoice = AVIF_CODEC_CHOICE_AOM;
  return encoder;
}

}  // namespace

namespace {

// The still encode of an image already converted (yuv_of).
std::vector<uint8_t> encode_avif_yuv(const avifImage* yuv, int quality) {
  const auto encoder = avif_encoder(quality);
  AvifBytes bytes;
  const avifResult result = avifEncoderWrite(encoder.get(), yuv, &bytes.data);
  if (result != AVIF_RESULT_OK) {
    throw Error(ErrorCode::kInvalidArgument, "AVIF encoding of " + std::to_string(yuv->width) + " x " + std::to_string(yuv->height) +
                                                 " pixels failed: " + avifResultToString(result));
  }
  return std::vector<uint8_t>(bytes.data.data, bytes.data.data + bytes.data.size);
}

}  // namespace

std::vector<uint8_t> encode_avif(const Image& image, int quality) { return encode_avif_yuv(yuv_of(image).get(), quality); }

namespace {

// libavif stamps an image sequence's movie, track and media headers (mvhd, tkhd, mdhd) with the
// wall-clock time of the encode: set to 0 ("unknown" in ISO BMFF), so the same frames give the same
// bytes (spec/container.md §11). Walks the boxes of `bytes` (the encoder's own output) within
// [begin, end), descending into moov, trak and mdia.
void clear_creation_times(std::vector<uint8_t>& bytes, size_t begin, size_t end) {
  const auto u32 = [&](size_t at) {
    return (uint32_t{bytes[at]} << 24) | (uint32_t{bytes[at + 1]} << 16) | (uint32_t{bytes[at + 2]} << 8) | bytes[at + 3];
  };
  size_t at = begin;
  while (at + 8 <= end) {
    uint64_t size = u32(at);
    size_t header = 8;
    if (size == 1 && at + 16 <= end) {
      size = (uint64_t{u32(at + 8)} << 32) | u32(at + 12);
      header = 16;
    } else if (size == 0) {
      size = end - at;
    }
    if (size < header || size > end - at) return;  // not a box we wrote: leave the rest alone
    const std::string type(bytes.begin() + static_cast<ptrdiff_t>(at + 4), bytes.begin() + static_cast<ptrdiff_t>(at + 8));
    const size_t body = at + header, box_end = at + static_cast<size_t>(size);
    if (type == "moov" || type == "trak" || type == "mdia") clear_creation_times(bytes, body, box_end);
    if ((type == "mvhd" || type == "tkhd" || type == "mdhd") && body + 4 <= box_end) {
      const size_t times = bytes[body] == 1 ? 16 : 8;  // version 1: two u64, else two u32
      if (body + 4 + times <= box_end)
        std::fill(bytes.begin() + static_cast<ptrdiff_t>(body + 4), bytes.begin() + static_cast<ptrdiff_t>(body + 4 + times), 0);
    }
    at = box_end;
  }
}

}  // namespace

struct AvifSequenceWriter::State {
  std::unique_ptr<avifEncoder, AvifEncoderFree> encoder;
  int width = 0, height = 0;
  bool finished = false;
};

AvifSequenceWriter::AvifSequenceWriter(int quality) : state_(std::make_unique<State>()) {
  state_->encoder = avif_encoder(quality);
  state_->encoder->timescale = 30;        // informative: a frame a tick (the file's times are the container's)
  state_->encoder->keyframeInterval = 0;  // frame 0 intra, every later one predicted from those before it
}

AvifSequenceWriter::~AvifSequenceWriter() = default;

void AvifSequenceWriter::add(const Image& frame) {
  State& s = *state_;
  if (s.finished) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence given a frame after it was finished");
  if (s.width == 0) {
    s.width = frame.width;
    s.height = frame.height;
  } else if (frame.width != s.width || frame.height != s.height) {
    throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of frames of different sizes");
  }
  const auto yuv = yuv_of(frame);
  const avifResult result = avifEncoderAddImage(s.encoder.get(), yuv.get(), 1, AVIF_ADD_IMAGE_FLAG_NONE);
  if (result != AVIF_RESULT_OK)
    throw Error(ErrorCode::kInvalidArgument, std::string("AVIF sequence encoding failed: ") + avifResultToString(result));
}

std::vector<uint8_t> AvifSequenceWriter::finish() {
  State& s = *state_;
  if (s.width == 0) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of no frames");
  if (s.finished) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence finished twice");
  s.finished = true;
  AvifBytes bytes;
  const avifResult result = avifEncoderFinish(s.encoder.get(), &bytes.data);
  if (result != AVIF_RESULT_OK)
    throw Error(ErrorCode::kInvalidArgument, std::string("AVIF sequence encoding failed: ") + avifResultToString(result));
  std::vector<uint8_t> out(bytes.data.data, bytes.data.data + bytes.data.size);
  clear_creation_times(out, 0, out.size());
  return out;
}

std::vector<uint8_t> encode_avif_sequence(std::span<const Image* const> frames, int quality) {
  if (frames.empty()) throw Error(ErrorCode::kInvalidArgument, "an AVIF image sequence of no frames");
  AvifSequenceWriter writer(quality);
  for (const Image* frame : frames) writer.add(*frame);
  return writer.finish();
}

Image avif_colour_round_trip(const Image& image) { return TextureStill(TextureCodec::kAvif, image).colour_round_trip(); }

std::vector<uint8_t> encode_png(const Image& image) {
  require_codable(image, true);
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = image.channels == 4 ? PNG_FORMAT_RGBA : image.channels == 3 ? PNG_FORMAT_RGB : PNG_FORMAT_GRAY;
  png_alloc_size_t size = 0;
  const int stride = image.width * image.channels;
  if (!png_image_write_to_memory(&png, nullptr, &size, 0, image.pixels.data(), stride, nullptr)) {
    throw Error(ErrorCode::kInvalidArgument, std::string("PNG encoding failed: ") + png.message);
  }
  std::vector<uint8_t> bytes(size);
  if (!png_image_write_to_memory(&png, bytes.data(), &size, 0, image.pixels.data(), stride, nullptr)) {
    throw Error(ErrorCode::kInvalidArgument, std::string("PNG encoding failed: ") + png.message);
  }
  bytes.resize(size);
  return bytes;
}

int avif_quantizer(int quality) { return static_cast<int>(std::lround((100 - std::clamp(quality, 0, 100)) * 63 / 100.0)); }

std::vector<uint8_t> encode_texture(TextureCodec codec, const Image& image, int quality) { return TextureStill(codec, image).encode(quality); }

struct TextureStill::Yuv {
  std::unique_ptr<avifImage, AvifImageFree> image;
};

TextureStill::TextureStill(TextureCodec codec, const Image& image) : codec_(codec), image_(image) {}
TextureStill::~TextureStill() = default;

const TextureStill::Yuv& TextureStill::yuv() const {
  if (!yuv_) yuv_ = std::make_unique<Yuv>(Yuv{yuv_of(image_)});
  return *yuv_;
}

std::vector<uint8_t> TextureStill::encode(int quality) const {
  if (stored_texture_codec(codec_, quality) != TextureCodec::kAvif) return encode_webp(image_, quality);
  return encode_avif_yuv(yuv().image.get(), quality);
}

Image TextureStill::colour_round_trip() const { return rgb_of(yuv().image.get(), 3, "avif_colour_round_trip"); }

void write_png(const std::filesystem::path& path, const Image& image) { format::write_file_atomically(path, encode_png(image)); }

}  // namespace facemorph
