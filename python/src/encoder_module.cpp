// facemorph._encoder: the encoder's C++ library for Python (links OpenCV through facemorph_encoder;
// facemorph.encode imports it, `import facemorph` does not). One path for both inputs, as fmenc's:
// a capture (open_capture), or frames given as numpy arrays, made a capture in a private temporary
// folder (the encoder reads its frames' meshes and textures from files: spec/python.md §3), then
// encode_capture_stored and write_sequence_file with fmenc's metadata, so that the same frames and
// options make the same bytes as fmenc (tests/python: cmp). The encode runs without the GIL;
// progress calls back into Python on the calling thread, where an exception (KeyboardInterrupt
// included) ends the encode and is raised.
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/encode_settings.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "python/src/status.hpp"

#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace facemorph::python {
namespace {

namespace fs = std::filesystem;

// --- Options ------------------------------------------------------------------------------------

// The options as facemorph/encode.py has checked and normalised them (fractions as numbers, "auto"
// as None), set as fmenc sets them from its command line.
struct Options {
  EncodeOptions encode;
  TextureCoding texture_coding = TextureCoding::kSequence;
};

template <typename T>
std::optional<T> get(const py::dict& d, const char* key) {
  if (!d.contains(key) || d[key].is_none()) return std::nullopt;
  return d[key].cast<T>();
}

Options options_from(const py::dict& d) {
  Options out;
  EncodeOptions& o = out.encode;
  if (const auto max_error = get<double>(d, "max_error")) {
    o.max_error = *max_error;
  } else if (const auto keyframes = get<double>(d, "keyframes")) {
    o.keyframe_fraction = *keyframes;
    // A budget given is a budget kept; the default one grows where frames are far apart or fast (fmenc).
    o.keyframe_error_bound = o.sparse_frame_interval = 0;
  }
  if (const auto grid = get<int>(d, "grid")) o.grid = *grid;
  o.texture_quality = get<int>(d, "quality").value_or(kAutoTextureQuality);
  if (o.texture_quality != kAutoTextureQuality && (o.texture_quality < 0 || o.texture_quality > 101)) {
    throw Error(ErrorCode::kInvalidArgument, "quality " + std::to_string(o.texture_quality) + " outside 0..101");
  }
  o.texture_codec = parse_texture_codec(get<std::string>(d, "texture_codec").value_or("avif"));
  out.texture_coding = parse_texture_coding(get<std::string>(d, "texture_coding").value_or("sequence"));
  o.texture = get<bool>(d, "texture").value_or(true);
  o.share_textures = get<bool>(d, "texture_sharing").value_or(true);
  o.track_landmarks = get<bool>(d, "track_landmarks").value_or(false);
  if (const auto size = get<int>(d, "texture_size")) o.texture_size = *size;
  o.registration.method = parse_registration_method(get<std::string>(d, "registration").value_or("gmf"));
  o.spline = parse_spline_kind(get<std::string>(d, "spline").value_or("catmull-rom"));
  if (const auto representation = get<std::string>(d, "representation")) o.representation = parse_representation(*representation);
  o.keep_holes_filled = get<bool>(d, "keep_holes_filled").value_or(false);
  o.largest_component = get<bool>(d, "largest_component").value_or(false);
  o.threads = get<int>(d, "threads").value_or(0);
  o.strict = get<bool>(d, "strict").value_or(false);
  o.reference_frame = get<int>(d, "reference").value_or(0);
  o.density_equalising.strength = get<double>(d, "density_equalising").value_or(EncodeOptions{}.density_equalising.strength);
  o.keyframe_fit = get<bool>(d, "keyframe_fit").value_or(true);
  // field_error: None is auto, 0 is 16-bit precision without a search, else the target (fmenc --field-error).
  const auto field_error = get<double>(d, "field_error");
  o.predicted_fields = !field_error || *field_error != 0;
  o.auto_field_error = !field_error;
  if (o.predicted_fields && !o.auto_field_error) o.field_precision.target_error = *field_error;
  o.field_precision.intra_period = get<int>(d, "intra_period").value_or(kAutoIntraPeriod);
  o.field_precision.noise_shaping = get<std::string>(d, "field_rounding").value_or("shaped") == "shaped";
  o.field_precision.inter_dead_zone = get<double>(d, "inter_dead_zone").value_or(kAutoDeadZone);
  return out;
}

// --- Progress ---------------------------------------------------------------------------------

// The encoder's progress calls into Python (GIL taken for the call). The encoder calls it between
// the items of its parallel loops, where it must not throw (facemorph::parallel_for would end with
// its threads still running), so a Python exception there (or a signal: Ctrl-C) is kept, Python is
// not called again, and the encode stops at the next point that may stop (Cancelled): before the
// file is written, or between the frames written for it. The caller raises the kept exception.
struct Cancelled {};

class ProgressBridge {
 public:
  explicit ProgressBridge(py::object callback) : callback_(std::move(callback)) {}
  ~ProgressBridge() {
    py::gil_scoped_acquire acquire;  // the kept exception and the callback are Python objects
    error_.reset();
    callback_ = py::object();
  }
  ProgressBridge(const ProgressBridge&) = delete;
  ProgressBridge& operator=(const ProgressBridge&) = delete;

  std::function<void(const std::string&, int, int)> function() {
    return [this](const std::string& stage, int done, int total) { call(stage, done, total); };
  }
  void call(const std::string& stage, int done, int total) {
    if (stopped_) return;
    py::gil_scoped_acquire acquire;
    try {
      if (!callback_.is_none()) callback_(stage, done, total);
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    } catch (py::error_already_set& e) {
      error_.emplace(std::move(e));
      stopped_ = true;
    }
  }
  // Throws Cancelled where Python asked to stop: where the encode may stop.
  void stop_point() const {
    if (stopped_) throw Cancelled{};
  }
  bool stopped() const { return stopped_; }
  // With the GIL: raises the kept exception.
  [[noreturn]] void raise() {
    py::error_already_set e = std::move(*error_);
    error_.reset();
    throw e;
  }

 private:
  py::object callback_;
  std::optional<py::error_already_set> error_;
  std::atomic<bool> stopped_{false};
};

// --- The encode ---------------------------------------------------------------------------------

// What the encode reports to Python (and the settings written, as JSON text).
struct Result {
  std::string output;
  uint64_t bytes = 0;
  size_t frames = 0;
  std::vector<double> keyframe_times;
  std::vector<int> keyframe_frames;
  int grid_n = 0;
  std::string representation;
  int texture_size = 0;
  double predicted_worst_error = 0;
  std::vector<std::tuple<int, std::string, double, std::string>> dropped;
  std::vector<std::string> warnings;
  std::string settings;
  double seconds = 0;
};

// fmenc's stage "all" on `capture` into `output` (without the GIL), unless `progress` says stop.
Result encode_capture_to(Capture capture, const fs::path& output, Options options, const ProgressBridge& progress) {
  const auto start = std::chrono::steady_clock::now();
  EncodeReport report;
  const std::vector<std::string> landmark_names = capture.landmark_names;
  const size_t frame_count = capture.frames.size();
  std::unique_ptr<StoredSequence> sequence = encode_capture_stored(std::move(capture), options.encode, &report);
  progress.stop_point();
  SequenceFileMetadata metadata;
  metadata.settings = encode_settings_json(options.encode, report);  // fmenc's own, so the files are the same bytes
  metadata.landmark_names = landmark_names;
  metadata.keyframe_texture_qualities = report.texture_qualities;
  metadata.texture_codec = options.encode.texture_codec;
  metadata.texture_coding = options.texture_coding;
  metadata.field_coding = report.field_coding;
  write_sequence_file(output, *sequence, metadata);
  Result r;
  r.output = output.string();
  r.bytes = fs::file_size(output);
  r.frames = frame_count - report.dropped.size();
  for (const Keyframe& key : sequence->shape().keyframes) r.keyframe_times.push_back(key.time);
  r.keyframe_frames = report.keyframes;
  r.grid_n = sequence->shape().grid_n;
  r.representation = representation_name(sequence->shape().representation);
  r.texture_size = sequence->outline().has_texture() ? report.texture_size : 0;
  for (const EncodedFrameReport& f : report.frames) r.predicted_worst_error = std::max(r.predicted_worst_error, f.predicted_error);
  for (const DroppedFrame& d : report.dropped) r.dropped.emplace_back(d.index, d.name, d.time, d.reason);
  r.warnings = report.warnings;
  r.settings = metadata.settings;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

py::dict result_dict(const Result& r) {
  py::dict d;
  d["output"] = r.output;
  d["bytes"] = r.bytes;
  d["frames"] = r.frames;
  d["keyframe_times"] = r.keyframe_times;
  d["keyframe_frames"] = r.keyframe_frames;
  d["grid_n"] = r.grid_n;
  d["representation"] = r.representation;
  d["texture_size"] = r.texture_size;
  d["predicted_worst_error"] = r.predicted_worst_error;
  py::list dropped;
  for (const auto& [index, name, time, reason] : r.dropped) {
    py::dict f;
    f["frame"] = index;
    f["name"] = name;
    f["time"] = time;
    f["reason"] = reason;
    dropped.append(f);
  }
  d["dropped"] = dropped;
  d["warnings"] = r.warnings;
  d["settings_text"] = r.settings;
  d["seconds"] = r.seconds;
  return d;
}

// Runs encode(bridge) without the GIL, progress through `callback`.
template <typename F>
py::dict run_encode(Options& options, py::object callback, F&& encode) {
  ProgressBridge bridge(std::move(callback));
  options.encode.progress = bridge.function();
  std::optional<Result> result;
  {
    py::gil_scoped_release release;
    try {
      result = encode(bridge);
    } catch (const Cancelled&) {}
  }
  if (bridge.stopped()) bridge.raise();
  return result_dict(*result);
}

// A private folder under TMPDIR, removed with everything in it when the encode ends, however.
class TemporaryFolder {
 public:
  TemporaryFolder() {
    std::string pattern = (fs::temp_directory_path() / "facemorph-python-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) {
      throw Error(ErrorCode::kIo,
                  pattern + ": cannot make a temporary folder for the frames (" + std::strerror(errno) + "; TMPDIR says where)");
    }
    path_ = pattern;
  }
  ~TemporaryFolder() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TemporaryFolder(const TemporaryFolder&) = delete;
  TemporaryFolder& operator=(const TemporaryFolder&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// A capture from numpy frames: facemorph/encode.py has checked every array's shape and type.
struct NumpyFrame {
  py::array_t<double, py::array::c_style> vertices;                  // n×3
  py::array_t<int32_t, py::array::c_style> faces;                    // m×3
  std::optional<py::array_t<double, py::array::c_style>> uv;         // k×2
  std::optional<py::array_t<int32_t, py::array::c_style>> uv_faces;  // m×3 (uv per vertex: the faces)
  std::optional<py::array_t<double, py::array::c_style>> colours;    // n×3 in [0, 1]
  int texture = -1;                                                  // into the textures, -1: none
};

TriangleMesh mesh_of(const NumpyFrame& f) {
  TriangleMesh mesh;
  const auto n = static_cast<size_t>(f.vertices.shape(0)), m = static_cast<size_t>(f.faces.shape(0));
  mesh.positions.resize(n);
  std::memcpy(static_cast<void*>(mesh.positions.data()), f.vertices.data(), n * 3 * sizeof(double));
  mesh.faces.resize(m);
  std::memcpy(mesh.faces.data(), f.faces.data(), m * 3 * sizeof(int32_t));
  if (f.uv) {
    const auto k = static_cast<size_t>(f.uv->shape(0));
    mesh.uvs.resize(k);
    std::memcpy(static_cast<void*>(mesh.uvs.data()), f.uv->data(), k * 2 * sizeof(double));
    mesh.uv_faces.resize(m);
    std::memcpy(mesh.uv_faces.data(), (f.uv_faces ? *f.uv_faces : f.faces).data(), m * 3 * sizeof(int32_t));
  }
  if (f.colours) {
    mesh.colours.resize(n);
    std::memcpy(static_cast<void*>(mesh.colours.data()), f.colours->data(), n * 3 * sizeof(double));
  }
  return mesh;
}

py::dict encode_frames(const std::vector<NumpyFrame>& frames, const std::vector<py::array_t<uint8_t, py::array::c_style>>& textures,
                       const std::vector<double>& times, const std::vector<std::string>& names, double fps, const std::string& units,
                       const std::vector<std::string>& landmark_names, const py::array_t<double, py::array::c_style>& landmarks,
                       const std::string& output, const py::dict& options_dict, py::object progress) {
  Options options = options_from(options_dict);
  // The frames as meshes and images, copied out of numpy with the GIL (the arrays are Python's).
  std::vector<TriangleMesh> meshes;
  for (const NumpyFrame& f : frames) meshes.push_back(mesh_of(f));
  std::vector<Image> images;
  for (const auto& t : textures) {
    Image image(static_cast<int>(t.shape(1)), static_cast<int>(t.shape(0)), 3);
    std::memcpy(image.pixels.data(), t.data(), image.pixels.size());
    images.push_back(std::move(image));
  }
  Capture capture;
  capture.fps = fps;
  capture.units = units;
  capture.landmark_names = landmark_names;
  const auto count = static_cast<size_t>(landmark_names.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    capture.frames.push_back({names[i], times[i]});
    std::vector<Vec3> points(count);
    for (size_t l = 0; l < count; ++l) points[l] = Vec3(landmarks.at(i, l, 0), landmarks.at(i, l, 1), landmarks.at(i, l, 2));
    capture.landmarks.push_back(std::move(points));
  }
  std::vector<int> texture_of;
  for (const NumpyFrame& f : frames) texture_of.push_back(f.texture);
  return run_encode(options, std::move(progress), [&](ProgressBridge& bridge) {
    // The encoder reads frames from files: each mesh written as OBJ (numbers in the shortest text
    // that reads back to the same double), each texture once as PNG (lossless), so the encoder
    // reads exactly the arrays given.
    TemporaryFolder folder;
    capture.root = folder.path();
    std::vector<fs::path> texture_paths;
    for (size_t t = 0; t < images.size(); ++t) {
      char name[48];
      std::snprintf(name, sizeof name, "texture_%05zu.png", t);
      texture_paths.push_back(folder.path() / name);
      write_png(texture_paths.back(), images[t]);
    }
    images.clear();
    for (size_t i = 0; i < meshes.size(); ++i) {
      if (texture_of[i] >= 0) meshes[i].texture = texture_paths[static_cast<size_t>(texture_of[i])];
      write_mesh(capture.mesh_path(i), meshes[i]);
      meshes[i] = {};
      bridge.call("writing", static_cast<int>(i + 1), static_cast<int>(meshes.size()));
      bridge.stop_point();
    }
    return encode_capture_to(std::move(capture), output, options, bridge);
  });
}

py::dict encode_capture(const std::string& path, double fps, const std::string& landmarks, bool auto_landmarks, const std::string& output,
                        const py::dict& options_dict, py::object progress) {
  Options options = options_from(options_dict);
  return run_encode(options, std::move(progress), [&](ProgressBridge& bridge) {
    Capture capture = open_capture(path, fps, landmarks);
    if (auto_landmarks) {  // fmenc --landmarks auto: the capture's own ignored
      capture.landmark_names.clear();
      capture.landmarks.assign(capture.frames.size(), {});
    }
    return encode_capture_to(std::move(capture), output, options, bridge);
  });
}

// A mesh file as numpy arrays (meshkit's reader: OBJ, PLY).
py::dict read_mesh_file(const std::string& path) {
  TriangleMesh mesh;
  {
    py::gil_scoped_release release;
    mesh = read_mesh(path, {.allow_missing_texture = true});
  }
  const auto n = static_cast<size_t>(mesh.positions.size()), m = static_cast<size_t>(mesh.faces.size());
  py::dict d;
  py::array_t<double> vertices({n, size_t{3}});
  std::memcpy(vertices.mutable_data(), mesh.positions.data(), n * 3 * sizeof(double));
  py::array_t<int32_t> faces({m, size_t{3}});
  std::memcpy(faces.mutable_data(), mesh.faces.data(), m * 3 * sizeof(int32_t));
  d["vertices"] = vertices;
  d["faces"] = faces;
  d["uv"] = py::none();
  d["uv_faces"] = py::none();
  d["colours"] = py::none();
  if (mesh.has_uvs()) {
    py::array_t<double> uv({mesh.uvs.size(), size_t{2}});
    std::memcpy(uv.mutable_data(), mesh.uvs.data(), mesh.uvs.size() * 2 * sizeof(double));
    py::array_t<int32_t> uv_faces({m, size_t{3}});
    std::memcpy(uv_faces.mutable_data(), mesh.uv_faces.data(), m * 3 * sizeof(int32_t));
    d["uv"] = uv;
    d["uv_faces"] = uv_faces;
  }
  if (mesh.has_colours()) {
    py::array_t<double> colours({n, size_t{3}});
    std::memcpy(colours.mutable_data(), mesh.colours.data(), n * 3 * sizeof(double));
    d["colours"] = colours;
  }
  d["texture_path"] = mesh.texture.empty() ? py::object(py::none()) : py::object(py::str(mesh.texture.string()));
  return d;
}

// An image file (PNG, JPEG, WebP: OpenCV) as H×W×3 uint8 RGB.
py::array_t<uint8_t> read_image_file(const std::string& path) {
  Image image;
  {
    py::gil_scoped_release release;
    image = read_image(path);
  }
  if (image.channels != 3) throw Error(ErrorCode::kInternal, path + ": read as " + std::to_string(image.channels) + " channels");
  py::array_t<uint8_t> out({static_cast<size_t>(image.height), static_cast<size_t>(image.width), size_t{3}});
  std::memcpy(out.mutable_data(), image.pixels.data(), image.pixels.size());
  return out;
}

}  // namespace
}  // namespace facemorph::python

PYBIND11_MODULE(_encoder, m) {
  namespace py = pybind11;
  using namespace facemorph::python;
  m.doc() = "facemorph's encoder for numpy (internal: use facemorph.encode).";
  register_status_errors();
  py::class_<NumpyFrame>(m, "NumpyFrame")
      .def(py::init([](py::array_t<double, py::array::c_style | py::array::forcecast> vertices,
                       py::array_t<int32_t, py::array::c_style | py::array::forcecast> faces,
                       std::optional<py::array_t<double, py::array::c_style | py::array::forcecast>> uv,
                       std::optional<py::array_t<int32_t, py::array::c_style | py::array::forcecast>> uv_faces,
                       std::optional<py::array_t<double, py::array::c_style | py::array::forcecast>> colours,
                       int texture) { return NumpyFrame{vertices, faces, uv, uv_faces, colours, texture}; }),
           py::arg("vertices"), py::arg("faces"), py::arg("uv"), py::arg("uv_faces"), py::arg("colours"), py::arg("texture"));
  m.def("encode_frames", &encode_frames, py::arg("frames"), py::arg("textures"), py::arg("times"), py::arg("names"), py::arg("fps"),
        py::arg("units"), py::arg("landmark_names"), py::arg("landmarks"), py::arg("output"), py::arg("options"), py::arg("progress"));
  m.def("encode_capture", &encode_capture, py::arg("path"), py::arg("fps"), py::arg("landmarks"), py::arg("auto_landmarks"),
        py::arg("output"), py::arg("options"), py::arg("progress"));
  m.def("read_mesh", &read_mesh_file, py::arg("path"));
  m.def("read_image", &read_image_file, py::arg("path"));
}
