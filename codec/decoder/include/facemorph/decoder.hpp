// facemorph/decoder.hpp: the C++ player API, a header-only wrapper over the C API (facemorph.h),
// as libjxl's decode_cxx.h is over decode.h. It adds only what C++ gives: handles closed by their
// destructors, exceptions for statuses, frames into std::vectors. It includes facemorph.h and the
// standard library only, compiles as C++17 or later, and covers API 1.4 (spec/api.md; 1.1's
// borrowed open and texture weights, 1.3's double-precision arrays, hole levels and tolerance, 1.4's
// representation, spline and fixed nodes in File::info's fm_info included): every function is
// inline, so its ABI is the C API's.
//
//   fm::File file = fm::File::open("face.fmv");                  // throws fm::Error
//   fm::Decoder decoder(file);
//   fm::Frame frame;
//   decoder.decode(1.45, frame);                                  // positions, normals, UVs, indices, texture
//   draw(frame.positions.data(), frame.vertex_count, frame.indices.data(), frame.triangle_count);
//
// Namespace fm (the C API's prefix): the library's internal C++ lives in namespace facemorph, and a
// program linking the static library has both.
//
// Errors: every call that fails throws fm::Error, whose status() is the C API's fm_status and whose
// what() is "name: message" (fm_status_name, fm_last_error_message).
// Threads: as the C API. A File is immutable once opened: decoders on it may be created and used on
// several threads; a Decoder is used by one thread at a time. A File may be destroyed while its
// decoders live.
// Conventions (units, UV, winding, texture rows): facemorph.h.
#ifndef FACEMORPH_DECODER_HPP
#define FACEMORPH_DECODER_HPP

#if !defined(__cplusplus) || __cplusplus < 201703L
#error "facemorph/decoder.hpp needs C++17 or later (-std=c++17); C programs include facemorph.h"
#endif

#include "facemorph.h"

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace fm {

class Error : public std::runtime_error {
 public:
  Error(fm_status status, const std::string& message)
      : std::runtime_error(std::string(fm_status_name(status)) + ": " + message), status_(status) {}
  fm_status status() const noexcept { return status_; }

 private:
  fm_status status_;
};

// Throws fm::Error for any status but FM_OK, with the calling thread's last message.
inline void check(fm_status status) {
  if (status != FM_OK) throw Error(status, fm_last_error_message());
}

// The decoder's limits for a file it did not write (facemorph.h fm_decoder_options), at their
// defaults: change the fields you want, pass to File::open.
inline fm_decoder_options default_options() noexcept {
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  return options;
}

// Decode flags (facemorph.h FM_DECODE_*), or-ed.
enum DecodeFlags : uint32_t {
  kClamp = FM_DECODE_CLAMP,
  kKeepHolesFilled = FM_DECODE_KEEP_HOLES_FILLED,
  kFlipV = FM_DECODE_FLIP_V,
};

// Which arrays Decoder::decode fills, or-ed.
enum Outputs : uint32_t {
  kPositions = 1,
  kNormals = 2,
  kUvs = 4,
  kIndices = 8,
  kTexture = 16,
  kAllOutputs = 31,  // the five above, as in API 1.0 (not the 1.3 arrays below)
  // API 1.3: positions and UVs in double precision, and the hole levels (facemorph.h fm_frame).
  kPositionsF64 = 32,
  kUvsF64 = 64,
  kHoleLevels = 128,
};

// An opened .fmv file (fm_file). Move-only; the destructor closes it.
class File {
 public:
  // fm_file_open_with_options: throws fm::Error (FM_ERROR_IO, _TRUNCATED, _CORRUPT, _UNSUPPORTED,
  // _LIMIT, _OUT_OF_MEMORY, _INVALID_ARGUMENT for bad options).
  static File open(const std::string& path, const fm_decoder_options& options = default_options()) {
    fm_file* file = nullptr;
    check(fm_file_open_with_options(path.c_str(), &options, &file));
    return File(file);
  }
  // fm_file_open_memory_with_options: the bytes are copied; free them at once if you like.
  static File open_memory(const void* data, std::size_t size, const fm_decoder_options& options = default_options()) {
    fm_file* file = nullptr;
    check(fm_file_open_memory_with_options(data, size, &options, &file));
    return File(file);
  }
  // fm_file_open_memory_borrowed (API 1.1): the bytes are read where they lie, so they must stay
  // there, unchanged, until this File and every Decoder on it are gone. A group's chunk is read when
  // a frame first needs it: a streaming player may fill it in before then (facemorph.h).
  static File open_memory_borrowed(const void* data, std::size_t size, const fm_decoder_options& options = default_options()) {
    fm_file* file = nullptr;
    check(fm_file_open_memory_borrowed(data, size, &options, &file));
    return File(file);
  }

  File(File&& other) noexcept : file_(std::exchange(other.file_, nullptr)) {}
  File& operator=(File&& other) noexcept {
    if (this != &other) {
      fm_file_close(file_);
      file_ = std::exchange(other.file_, nullptr);
    }
    return *this;
  }
  File(const File&) = delete;
  File& operator=(const File&) = delete;
  ~File() { fm_file_close(file_); }

  // What the file holds (fm_file_get_info; API 1.4 adds its representation, spline and fixed nodes).
  fm_info info() const {
    fm_info info{};
    info.struct_size = sizeof info;
    check(fm_file_get_info(file_, &info));
    return info;
  }
  // The keyframes' times, seconds, increasing (fm_file_get_keyframe_times: count, then copy).
  std::vector<double> keyframe_times() const {
    std::size_t count = 0;
    check(fm_file_get_keyframe_times(file_, nullptr, 0, &count));
    std::vector<double> times(count);
    check(fm_file_get_keyframe_times(file_, times.data(), times.size(), &count));
    return times;
  }
  // The C handle, for the C API; still owned by this File.
  const fm_file* get() const noexcept { return file_; }

 private:
  explicit File(fm_file* file) noexcept : file_(file) {}
  fm_file* file_ = nullptr;
};

// A decoded frame in arrays the decoder resizes (and reuses: decoding into the same Frame again
// allocates only when a frame needs more than the last). Sizes are in elements: 3 floats per vertex
// for positions and normals, 2 for UVs, 3 indices per triangle, 4 bytes per texel.
struct Frame {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<float> uvs;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> texture;
  double time = 0;  // the time decoded (t, or t clamped), seconds
  uint32_t vertex_count = 0;
  uint32_t triangle_count = 0;
  uint32_t texture_size = 0;  // M (0: no texture)
  uint32_t iterations = 0;    // reconstruction steps
  bool fell_back = false;     // the reconstruction did not converge: the keyframes' spline
  // API 1.3 (kPositionsF64, kUvsF64, kHoleLevels): 3 and 2 doubles per vertex, and one level per
  // node of the disk grid in a file with holes (hole_level_count of them, negative inside a hole).
  std::vector<double> positions_f64;
  std::vector<double> uvs_f64;
  std::vector<double> hole_levels;
  uint32_t hole_level_count = 0;
};

// The state that decodes one file's frames (fm_decoder). Move-only; the destructor destroys it.
class Decoder {
 public:
  // fm_decoder_create: throws fm::Error (FM_ERROR_LIMIT, _OUT_OF_MEMORY, _CLOSED_HANDLE, ...).
  explicit Decoder(const File& file) { check(fm_decoder_create(file.get(), &decoder_)); }
  Decoder(Decoder&& other) noexcept : decoder_(std::exchange(other.decoder_, nullptr)) {}
  Decoder& operator=(Decoder&& other) noexcept {
    if (this != &other) {
      fm_decoder_destroy(decoder_);
      decoder_ = std::exchange(other.decoder_, nullptr);
    }
    return *this;
  }
  Decoder(const Decoder&) = delete;
  Decoder& operator=(const Decoder&) = delete;
  ~Decoder() { fm_decoder_destroy(decoder_); }

  // Decodes the frame at t (seconds) into `frame`: the arrays `outputs` names are resized to the
  // frame's counts and filled, the others emptied. Throws fm::Error with the statuses of
  // fm_decoder_decode (FM_ERROR_OUT_OF_RANGE without kClamp, FM_ERROR_CORRUPT, ...); `frame` is then
  // unspecified. Asks the sizes first (a decode that is kept), then copies.
  void decode(double t, Frame& frame, uint32_t outputs = kAllOutputs, uint32_t flags = 0) {
    fm_frame out = {};
    out.struct_size = sizeof out;
    check(fm_decoder_decode(decoder_, t, flags, &out));
    const std::size_t vertices = out.vertex_count, triangles = out.triangle_count,
                      texels = std::size_t{out.texture_size} * out.texture_size;
    wire(outputs & kPositions, frame.positions, 3 * vertices, out.positions, out.positions_bytes);
    wire(outputs & kNormals, frame.normals, 3 * vertices, out.normals, out.normals_bytes);
    wire(outputs & kUvs, frame.uvs, 2 * vertices, out.uvs, out.uvs_bytes);
    wire(outputs & kIndices, frame.indices, 3 * triangles, out.indices, out.indices_bytes);
    wire(outputs & kTexture, frame.texture, 4 * texels, out.texture, out.texture_bytes);
    wire(outputs & kPositionsF64, frame.positions_f64, 3 * vertices, out.positions_f64, out.positions_f64_bytes);
    wire(outputs & kUvsF64, frame.uvs_f64, 2 * vertices, out.uvs_f64, out.uvs_f64_bytes);
    wire(outputs & kHoleLevels, frame.hole_levels, std::size_t{out.hole_level_count}, out.hole_levels, out.hole_levels_bytes);
    check(fm_decoder_decode(decoder_, t, flags, &out));
    frame.time = out.time;
    frame.vertex_count = out.vertex_count;
    frame.triangle_count = out.triangle_count;
    frame.texture_size = out.texture_size;
    frame.iterations = out.iterations;
    frame.fell_back = out.fell_back != 0;
    frame.hole_level_count = out.hole_level_count;
  }
  // The C API's own call, for buffers the caller manages (a mapped GPU buffer): throws fm::Error
  // for every status but FM_OK (FM_ERROR_BUFFER_TOO_SMALL too: frame's counts then say what is
  // needed). frame.struct_size must be set (sizeof(fm_frame)).
  void decode_into(double t, fm_frame& frame, uint32_t flags = 0) { check(fm_decoder_decode(decoder_, t, flags, &frame)); }

  // The frame at t's texture blend without the texture (fm_decoder_get_texture_weights, API 1.1):
  // the keyframes whose images it sums and the weight of each, for a player that decodes the
  // keyframes' images itself. Count first, then copy.
  struct TextureWeights {
    std::vector<uint32_t> keyframes;
    std::vector<double> weights;
  };
  TextureWeights texture_weights(double t, uint32_t flags = 0) {
    std::size_t count = 0;
    check(fm_decoder_get_texture_weights(decoder_, t, flags, nullptr, nullptr, 0, &count));
    TextureWeights blend{std::vector<uint32_t>(count), std::vector<double>(count)};
    check(fm_decoder_get_texture_weights(decoder_, t, flags, blend.keyframes.data(), blend.weights.data(), count, &count));
    return blend;
  }

  // fm_decoder_set_tolerance (API 1.3): the reconstruction's stopping rule for the frames decoded
  // after it, a fraction of the rim's diameter in (0, 0.01] (FM_DEFAULT_TOLERANCE by default).
  void set_tolerance(double tolerance) { check(fm_decoder_set_tolerance(decoder_, tolerance)); }

  // The C handle, for the C API; still owned by this Decoder.
  fm_decoder* get() const noexcept { return decoder_; }

 private:
  template <typename T>
  static void wire(uint32_t wanted, std::vector<T>& array, std::size_t size, T*& pointer, std::size_t& bytes) {
    if (wanted == 0 || size == 0) {
      array.clear();
      return;
    }
    array.resize(size);
    pointer = array.data();
    bytes = size * sizeof(T);
  }

  fm_decoder* decoder_ = nullptr;
};

}  // namespace fm

#endif  // FACEMORPH_DECODER_HPP
