// facemorph._decoder: the player C API (facemorph.h) for Python and numpy. Frames are decoded by
// fm_decoder_decode straight into numpy arrays allocated for the call (so Python owns them), with
// the GIL released; every status other than FM_OK raises the facemorph.Error subclass of its name
// with fm_last_error_message. What the C API does not give (the header's settings, landmark names,
// encoder, format version; the keyframes' own textures) comes from the library's reader of the same
// file under the same limits (spec/python.md §2). The Python layer (facemorph/__init__.py) wraps
// this module; its documentation is the public one.
#include "codec/core/image/image.hpp"
#include "codec/core/image/texture_codec.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "facemorph.h"

#include "python/src/status.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace facemorph::python {
namespace {

// The decoder's limits as Python gives them (fm_decoder_options' fields; None keeps a default).
struct Limits {
  std::optional<uint32_t> max_grid_n, max_keyframes, max_texture_size;
  std::optional<uint64_t> max_memory, max_work;

  fm_decoder_options options() const {
    fm_decoder_options o;
    fm_decoder_options_init(&o);
    if (max_grid_n) o.max_grid_n = *max_grid_n;
    if (max_keyframes) o.max_keyframes = *max_keyframes;
    if (max_texture_size) o.max_texture_size = *max_texture_size;
    if (max_memory) o.max_memory_bytes = *max_memory;
    if (max_work) o.max_work = *max_work;
    return o;
  }
  // The same for the library's reader, as the C API maps them (c_api.cpp limits_of: the grid and
  // texture clamped to what the format allows). Only used once the C API has accepted them.
  DecoderLimits decoder_limits() const {
    const fm_decoder_options o = options();
    DecoderLimits limits;
    limits.max_grid_n = static_cast<int>(std::min<uint32_t>(o.max_grid_n, kMaxGridSize));
    limits.max_keyframes = o.max_keyframes;
    limits.max_texture_size = static_cast<int>(std::min<uint32_t>(o.max_texture_size, 1u << 20));
    limits.max_memory_bytes = o.max_memory_bytes;
    limits.max_work = o.max_work;
    return limits;
  }
};

// Throws StatusError for a status other than FM_OK; call on the thread that made the call (the
// message is the thread's), with or without the GIL.
void check(fm_status status) {
  if (status != FM_OK) throw StatusError(static_cast<int>(status), fm_last_error_message());
}

// One decoded frame: numpy arrays Python owns, and the C API's description of the frame.
struct Frame {
  double time = 0;
  uint32_t vertex_count = 0, triangle_count = 0, texture_size = 0, iterations = 0;
  bool fell_back = false;
  py::object positions = py::none(), normals = py::none(), uv = py::none(), faces = py::none(), texture = py::none();
};

// What Python asks decode for.
enum Output : unsigned { kPositions = 1, kNormals = 2, kUv = 4, kFaces = 8, kTexture = 16, kAll = 31 };

class File {
 public:
  // Opens `path` under `limits` (fm_file_open_with_options), or `data` (kept, read where it lies:
  // fm_file_open_memory_borrowed).
  static std::unique_ptr<File> open_path(const std::string& path, const Limits& limits) {
    auto file = std::unique_ptr<File>(new File(limits));
    file->path_ = path;
    const fm_decoder_options options = limits.options();
    {
      py::gil_scoped_release release;
      check(fm_file_open_with_options(path.c_str(), &options, &file->file_));
      file->start();
    }
    return file;
  }
  static std::unique_ptr<File> open_bytes(py::bytes data, const Limits& limits) {
    auto file = std::unique_ptr<File>(new File(limits));
    file->data_ = data;
    char* buffer = nullptr;
    Py_ssize_t size = 0;
    if (PyBytes_AsStringAndSize(data.ptr(), &buffer, &size) != 0) throw py::error_already_set();
    file->bytes_ = {reinterpret_cast<const uint8_t*>(buffer), static_cast<size_t>(size)};
    const fm_decoder_options options = limits.options();
    {
      py::gil_scoped_release release;
      check(fm_file_open_memory_borrowed(file->bytes_.data(), file->bytes_.size(), &options, &file->file_));
      file->start();
    }
    return file;
  }

  File(const File&) = delete;
  File& operator=(const File&) = delete;
  ~File() { release(); }

  // Closes the decoder and the file; later calls raise ClosedHandleError. Waits for a decode in
  // progress on another thread.
  void close() {
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(mutex_);
    this->release();
  }
  bool closed() const { return file_ == nullptr; }

  // fm_file_get_info and the keyframe times, with what the file's header says besides (the reader's
  // SequenceFileInfo): a dict the Python layer completes (the settings' JSON parsed).
  py::dict info() const {
    py::dict d;
    d["fps"] = info_.fps;
    d["first_time"] = info_.first_time;
    d["last_time"] = info_.last_time;
    d["duration"] = info_.duration;
    d["range"] = py::make_tuple(info_.range_begin, info_.range_end);
    d["keyframe_count"] = info_.keyframe_count;
    d["keyframe_times"] = keyframe_times_;
    d["grid_n"] = info_.grid_n;
    d["max_vertex_count"] = info_.max_vertex_count;
    d["max_triangle_count"] = info_.max_triangle_count;
    d["grid_vertex_count"] = info_.grid_vertex_count;
    d["grid_triangle_count"] = info_.grid_triangle_count;
    d["has_holes"] = info_.has_holes != 0;
    d["texture_size"] = info_.texture_size;
    d["units"] = std::string(info_.units);
    d["format_version"] = std::to_string(header_.major_version) + "." + std::to_string(header_.minor_version);
    d["file_bytes"] = header_.file_bytes;
    d["encoder"] = header_.metadata.encoder;
    d["settings_text"] = py::reinterpret_steal<py::object>(
        PyUnicode_DecodeUTF8(header_.metadata.settings.data(), static_cast<Py_ssize_t>(header_.metadata.settings.size()), "replace"));
    d["landmark_names"] = header_.metadata.landmark_names;
    d["texture_codec"] =
        info_.texture_size > 0 ? py::object(py::str(texture_codec_name(header_.metadata.texture_codec))) : py::object(py::none());
    d["distinct_textures"] = header_.distinct_textures;
    return d;
  }

  // fm_decoder_decode at t into new arrays: positions n×3, normals n×3, uv n×2 (float32), faces
  // m×3 (int32), texture M×M×3 (uint8; None without texture), those `outputs` asks for.
  Frame decode(double t, uint32_t flags, unsigned outputs) {
    const size_t n = info_.max_vertex_count, m = info_.max_triangle_count,
                 texels = static_cast<size_t>(info_.texture_size) * info_.texture_size;
    py::array_t<float> positions, normals, uv;
    py::array_t<int32_t> faces;
    py::array_t<uint8_t> texture;
    fm_frame frame;
    fm_frame_init(&frame);
    if (outputs & kPositions) {
      positions = py::array_t<float>({n, size_t{3}});
      frame.positions = positions.mutable_data();
      frame.positions_bytes = 3 * sizeof(float) * n;
    }
    if (outputs & kNormals) {
      normals = py::array_t<float>({n, size_t{3}});
      frame.normals = normals.mutable_data();
      frame.normals_bytes = 3 * sizeof(float) * n;
    }
    if (outputs & kUv) {
      uv = py::array_t<float>({n, size_t{2}});
      frame.uvs = uv.mutable_data();
      frame.uvs_bytes = 2 * sizeof(float) * n;
    }
    if (outputs & kFaces) {
      faces = py::array_t<int32_t>({m, size_t{3}});
      frame.indices = reinterpret_cast<uint32_t*>(faces.mutable_data());  // indices < 2^31: max_vertex_count is a uint32 the grid bounds
      frame.indices_bytes = 3 * sizeof(uint32_t) * m;
    }
    const bool want_texture = (outputs & kTexture) && texels > 0;
    if (want_texture) {
      texture = py::array_t<uint8_t>({static_cast<size_t>(info_.texture_size), static_cast<size_t>(info_.texture_size), size_t{3}});
      // The C API's texture is RGBA; Python's is RGB (alpha is always 255): decoded into a buffer of
      // the file's, then packed into the array.
      rgba_.resize(4 * texels);
      frame.texture = rgba_.data();
      frame.texture_bytes = rgba_.size();
    }
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      require_open();
      check(fm_decoder_decode(decoder_, t, flags, &frame));
      if (want_texture) {
        const uint8_t* from = rgba_.data();
        uint8_t* to = texture.mutable_data();
        for (size_t i = 0; i < texels; ++i, from += 4, to += 3) std::memcpy(to, from, 3);
      }
    }
    Frame out;
    out.time = frame.time;
    out.vertex_count = frame.vertex_count;
    out.triangle_count = frame.triangle_count;
    out.texture_size = frame.texture_size;
    out.iterations = frame.iterations;
    out.fell_back = frame.fell_back != 0;
    // A file with holes cuts a frame's own counts out of the largest buffers: those rows, copied.
    const auto rows = [](const py::array& array, size_t count, size_t capacity) -> py::object {
      if (count == capacity) return array;
      return array[py::slice(0, static_cast<py::ssize_t>(count), 1)].attr("copy")();
    };
    if (outputs & kPositions) out.positions = rows(positions, frame.vertex_count, n);
    if (outputs & kNormals) out.normals = rows(normals, frame.vertex_count, n);
    if (outputs & kUv) out.uv = rows(uv, frame.vertex_count, n);
    if (outputs & kFaces) out.faces = rows(faces, frame.triangle_count, m);
    if (want_texture) out.texture = texture;
    return out;
  }

  // fm_decoder_get_texture_weights: the keyframes (uint32) whose textures blend at t, and their
  // weights (float64).
  py::tuple texture_weights(double t, uint32_t flags) {
    std::vector<uint32_t> keyframes;
    std::vector<double> weights;
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      require_open();
      size_t count = 0;
      check(fm_decoder_get_texture_weights(decoder_, t, flags, nullptr, nullptr, 0, &count));
      keyframes.resize(count);
      weights.resize(count);
      check(fm_decoder_get_texture_weights(decoder_, t, flags, keyframes.data(), weights.data(), count, &count));
    }
    py::array_t<int64_t> k(static_cast<py::ssize_t>(keyframes.size()));
    std::copy(keyframes.begin(), keyframes.end(), k.mutable_data());
    py::array_t<double> w(static_cast<py::ssize_t>(weights.size()));
    std::copy(weights.begin(), weights.end(), w.mutable_data());
    return py::make_tuple(k, w);
  }

  // Keyframe k's texture as stored, M×M×3 uint8 (row 0 at the top, as decode's): through the
  // library's reader of the file, opened on first use under the same limits.
  py::array_t<uint8_t> keyframe_texture(int64_t k) {
    if (info_.texture_size == 0) throw StatusError(FM_ERROR_INVALID_ARGUMENT, name() + ": the file has no texture");
    if (k < 0 || k >= static_cast<int64_t>(info_.keyframe_count)) {
      throw StatusError(FM_ERROR_INVALID_ARGUMENT,
                        name() + ": keyframe " + std::to_string(k) + " outside 0.." + std::to_string(info_.keyframe_count - 1));
    }
    std::shared_ptr<const Image> image;
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      require_open();
      image = source()->texture(static_cast<size_t>(k));
    }
    if (image->channels != 3)
      throw StatusError(FM_ERROR_INTERNAL, name() + ": keyframe texture of " + std::to_string(image->channels) + " channels");
    py::array_t<uint8_t> out({static_cast<size_t>(image->height), static_cast<size_t>(image->width), size_t{3}});
    std::memcpy(out.mutable_data(), image->pixels.data(), image->pixels.size());
    return out;
  }

  std::string name() const { return data_ ? std::string("memory") : path_; }

 private:
  explicit File(const Limits& limits) : limits_(limits) {}

  // After the open: the info, the keyframe times, the decoder, and the header's description (the
  // library's reader, dropped once read; the C API has read and checked the same header). Without
  // the GIL.
  void start() {
    try {
      fm_info_init(&info_);
      check(fm_file_get_info(file_, &info_));
      size_t count = 0;
      check(fm_file_get_keyframe_times(file_, nullptr, 0, &count));
      keyframe_times_.resize(count);
      check(fm_file_get_keyframe_times(file_, keyframe_times_.data(), count, &count));
      check(fm_decoder_create(file_, &decoder_));
      if (data_) {
        open_sequence_source(bytes_, "memory", limits_.decoder_limits(), &header_);
      } else {
        open_sequence_source(path_, limits_.decoder_limits(), &header_);
      }
    } catch (...) {
      release();
      throw;
    }
  }

  std::shared_ptr<const KeyframeSource> source() {
    std::call_once(source_once_, [&] {
      source_ = data_ ? open_borrowed_sequence_source(bytes_, "memory", limits_.decoder_limits())
                      : open_sequence_source(path_, limits_.decoder_limits());
    });
    return source_;
  }

  void require_open() const {
    if (file_ == nullptr) throw StatusError(FM_ERROR_CLOSED_HANDLE, name() + ": the file is closed");
  }

  void release() {
    fm_decoder_destroy(decoder_);
    fm_file_close(file_);
    decoder_ = nullptr;
    file_ = nullptr;
    source_.reset();
    rgba_ = {};
  }

  Limits limits_;
  std::string path_;
  std::optional<py::bytes> data_;   // the bytes of a file opened from memory: the C API reads them where they lie...
  std::span<const uint8_t> bytes_;  // ...here (read without the GIL: a bytes object never changes)
  fm_file* file_ = nullptr;
  fm_decoder* decoder_ = nullptr;
  fm_info info_{};
  std::vector<double> keyframe_times_;
  SequenceFileInfo header_;
  std::once_flag source_once_;
  std::shared_ptr<const KeyframeSource> source_;
  std::vector<uint8_t> rgba_;
  // One call on the decoder at a time (an fm_decoder is used by one thread at a time), and close()
  // never while one runs. Taken only without the GIL, and released before the GIL is taken back, so
  // a thread holding it never waits for the GIL.
  std::mutex mutex_;
};

}  // namespace
}  // namespace facemorph::python

PYBIND11_MODULE(_decoder, m) {
  namespace py = pybind11;
  using namespace facemorph::python;
  m.doc() = "facemorph's player C API for numpy (internal: use the facemorph package).";
  register_status_errors();

  py::class_<Frame>(m, "Frame", "One decoded frame (facemorph.Frame).")
      .def_readonly("time", &Frame::time)
      .def_readonly("vertex_count", &Frame::vertex_count)
      .def_readonly("triangle_count", &Frame::triangle_count)
      .def_readonly("texture_size", &Frame::texture_size)
      .def_readonly("iterations", &Frame::iterations)
      .def_readonly("fell_back", &Frame::fell_back)
      .def_readonly("positions", &Frame::positions)
      .def_readonly("normals", &Frame::normals)
      .def_readonly("uv", &Frame::uv)
      .def_readonly("faces", &Frame::faces)
      .def_readonly("texture", &Frame::texture)
      .def("__repr__", [](const Frame& f) {
        char text[160];
        std::snprintf(text, sizeof text, "<facemorph.Frame t = %.4f s: %u vertices, %u triangles, texture %u, %u iterations%s>", f.time,
                      f.vertex_count, f.triangle_count, f.texture_size, f.iterations, f.fell_back ? ", fell back" : "");
        return std::string(text);
      });

  py::class_<File>(m, "File", "An opened .fmv file and its decoder (facemorph.File).")
      .def_static("open_path", &File::open_path, py::arg("path"), py::arg("limits"))
      .def_static("open_bytes", &File::open_bytes, py::arg("data"), py::arg("limits"))
      .def("close", &File::close)
      .def_property_readonly("closed", &File::closed)
      .def_property_readonly("name", &File::name)
      .def("info", &File::info)
      .def("decode", &File::decode, py::arg("t"), py::arg("flags"), py::arg("outputs"))
      .def("texture_weights", &File::texture_weights, py::arg("t"), py::arg("flags"))
      .def("keyframe_texture", &File::keyframe_texture, py::arg("k"));

  py::class_<Limits>(m, "Limits")
      .def(py::init([](std::optional<uint64_t> max_memory, std::optional<uint64_t> max_work, std::optional<uint32_t> max_grid_n,
                       std::optional<uint32_t> max_keyframes, std::optional<uint32_t> max_texture_size) {
             return Limits{max_grid_n, max_keyframes, max_texture_size, max_memory, max_work};
           }),
           py::arg("max_memory") = py::none(), py::arg("max_work") = py::none(), py::arg("max_grid_n") = py::none(),
           py::arg("max_keyframes") = py::none(), py::arg("max_texture_size") = py::none());

  m.attr("DECODE_CLAMP") = FM_DECODE_CLAMP;
  m.attr("DECODE_KEEP_HOLES_FILLED") = FM_DECODE_KEEP_HOLES_FILLED;
  m.attr("DECODE_FLIP_V") = FM_DECODE_FLIP_V;
  m.attr("OUTPUT_POSITIONS") = static_cast<unsigned>(kPositions);
  m.attr("OUTPUT_NORMALS") = static_cast<unsigned>(kNormals);
  m.attr("OUTPUT_UV") = static_cast<unsigned>(kUv);
  m.attr("OUTPUT_FACES") = static_cast<unsigned>(kFaces);
  m.attr("OUTPUT_TEXTURE") = static_cast<unsigned>(kTexture);
  m.attr("DEFAULT_MAX_MEMORY") = FM_DEFAULT_MAX_MEMORY_BYTES;
  m.attr("DEFAULT_MAX_WORK") = FM_DEFAULT_MAX_WORK;
  m.attr("DEFAULT_MAX_GRID_N") = FM_DEFAULT_MAX_GRID_N;
  m.attr("DEFAULT_MAX_KEYFRAMES") = FM_DEFAULT_MAX_KEYFRAMES;
  m.attr("DEFAULT_MAX_TEXTURE_SIZE") = FM_DEFAULT_MAX_TEXTURE_SIZE;
  m.def("version", [] { return std::string(fm_version()); });
  m.def("status_name", [](int status) { return std::string(fm_status_name(static_cast<fm_status>(status))); });
}
