#include "facemorph/encoder/frame_store.hpp"

#include "facemorph/error.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>

#include <fcntl.h>
#include <unistd.h>

namespace facemorph {

namespace {

// Vectors of plain numbers are written as their bytes: the file lives only as long as the process,
// on the machine that wrote it, and a map read back must be the very same doubles (the encode's
// output must not depend on whether its frames were spilled).
static_assert(sizeof(Vec2) == 2 * sizeof(double) && sizeof(Vec3) == 3 * sizeof(double) && sizeof(Face) == 3 * sizeof(int32_t));
static_assert(sizeof(Complex) == 2 * sizeof(double));
template <typename T>
constexpr bool kPlain = std::is_trivially_copyable_v<T> || std::is_same_v<T, Vec2> || std::is_same_v<T, Vec3> || std::is_same_v<T, Complex>;

class Writer {
 public:
  template <typename T>
  void value(const T& v) {
    static_assert(kPlain<T>);
    bytes(&v, sizeof v);
  }
  void text(const std::string& s) {
    value<uint64_t>(s.size());
    bytes(s.data(), s.size());
  }
  template <typename T>
  void array(const std::vector<T>& v) {
    static_assert(kPlain<T>);
    value<uint64_t>(v.size());
    bytes(v.data(), v.size() * sizeof(T));
  }
  std::vector<char> take() { return std::move(out_); }

 private:
  void bytes(const void* data, size_t size) {
    const auto* p = static_cast<const char*>(data);
    out_.insert(out_.end(), p, p + size);
  }
  std::vector<char> out_;
};

class Reader {
 public:
  Reader(const char* data, size_t size) : p_(data), end_(data + size) {}
  template <typename T>
  T value() {
    static_assert(kPlain<T>);
    T v;
    bytes(&v, sizeof v);
    return v;
  }
  std::string text() {
    std::string s(count(1), '\0');
    bytes(s.data(), s.size());
    return s;
  }
  template <typename T>
  std::vector<T> array() {
    std::vector<T> v(count(sizeof(T)));
    bytes(v.data(), v.size() * sizeof(T));
    return v;
  }
  bool done() const { return p_ == end_; }

 private:
  size_t count(size_t item) {
    const auto n = value<uint64_t>();
    if (n > static_cast<uint64_t>(end_ - p_) / item) throw Error(ErrorCode::kInternal, "frame store: a stored frame is cut short");
    return static_cast<size_t>(n);
  }
  void bytes(void* data, size_t size) {
    if (size > static_cast<size_t>(end_ - p_)) throw Error(ErrorCode::kInternal, "frame store: a stored frame is cut short");
    if (size == 0) return;  // an empty array's data() may be null, which memcpy must not be given
    std::memcpy(data, p_, size);
    p_ += size;
  }
  const char* p_;
  const char* end_;
};

void write_mesh(Writer& w, const TriangleMesh& mesh) {
  w.array(mesh.positions);
  w.array(mesh.faces);
  w.array(mesh.uvs);
  w.array(mesh.uv_faces);
  w.text(mesh.texture.string());
  w.array(mesh.colours);
}

TriangleMesh read_mesh_bytes(Reader& r) {
  TriangleMesh mesh;
  mesh.positions = r.array<Vec3>();
  mesh.faces = r.array<Face>();
  mesh.uvs = r.array<Vec2>();
  mesh.uv_faces = r.array<Face>();
  mesh.texture = r.text();
  mesh.colours = r.array<Vec3>();
  return mesh;
}

// ConformalReport, RepairReport and FilledHole hold only numbers (and one string): written field by
// field, so a field added to them must be added here too (the round-trip test compares them all).
void write_conformal_report(Writer& w, const ConformalReport& c) {
  w.value(c.method);
  w.text(c.fallback_reason);
  for (int v : {c.iterations, c.factorizations, c.intrinsic_flips, c.split_chords, c.split_ears, c.split_obtuse_boundary, c.split_caps, c.caps_left,
                c.obtuse_boundary_left, c.flipped_triangles, c.untangled_vertices}) {
    w.value(v);
  }
  for (double v : {c.energy, c.energy_excess, c.seconds_prepare, c.seconds_initial, c.seconds_flow, c.seconds_finish}) w.value(v);
}

ConformalReport read_conformal_report(Reader& r) {
  ConformalReport c;
  c.method = r.value<ConformalMethod>();
  c.fallback_reason = r.text();
  for (int* v : {&c.iterations, &c.factorizations, &c.intrinsic_flips, &c.split_chords, &c.split_ears, &c.split_obtuse_boundary, &c.split_caps,
                 &c.caps_left, &c.obtuse_boundary_left, &c.flipped_triangles, &c.untangled_vertices}) {
    *v = r.value<int>();
  }
  for (double* v : {&c.energy, &c.energy_excess, &c.seconds_prepare, &c.seconds_initial, &c.seconds_flow, &c.seconds_finish}) *v = r.value<double>();
  return c;
}

void write_repair_report(Writer& w, const RepairReport& report) {
  for (int v : {report.merged_vertices, report.dropped_degenerate_faces, report.split_faces, report.dropped_duplicate_faces,
                report.dropped_unreferenced_vertices, report.reoriented_faces, report.dropped_components, report.dropped_component_faces}) {
    w.value(v);
  }
  w.value<uint64_t>(report.holes.size());
  for (const FilledHole& h : report.holes) {
    w.array(h.loop);
    for (int v : {h.first_vertex, h.vertex_count, h.first_face, h.face_count, h.folded_faces}) w.value(v);
    for (double v : {h.perimeter, h.area, h.min_angle_degrees, h.sharpest_hole_corner_degrees}) w.value(v);
  }
}

RepairReport read_repair_report(Reader& r) {
  RepairReport report;
  for (int* v : {&report.merged_vertices, &report.dropped_degenerate_faces, &report.split_faces, &report.dropped_duplicate_faces,
                 &report.dropped_unreferenced_vertices, &report.reoriented_faces, &report.dropped_components, &report.dropped_component_faces}) {
    *v = r.value<int>();
  }
  report.holes.resize(r.value<uint64_t>());
  for (FilledHole& h : report.holes) {
    h.loop = r.array<int>();
    for (int* v : {&h.first_vertex, &h.vertex_count, &h.first_face, &h.face_count, &h.folded_faces}) *v = r.value<int>();
    for (double* v : {&h.perimeter, &h.area, &h.min_angle_degrees, &h.sharpest_hole_corner_degrees}) *v = r.value<double>();
  }
  return report;
}

}  // namespace

std::vector<char> FrameStore::serialize(const MappedFrame& frame) {
  Writer w;
  w.text(frame.name);
  // The prepared frame without its mesh (see put).
  w.array(frame.prepared.rim);
  w.array(frame.prepared.source_vertex);
  write_repair_report(w, frame.prepared.report);
  write_mesh(w, frame.map.surface);
  w.array(frame.map.disk);
  w.array(frame.map.rim);
  w.array(frame.map.source_vertex);
  w.value(frame.map.normalization.a);
  w.value(frame.map.normalization.theta);
  write_conformal_report(w, frame.map.report);
  w.value(frame.normalized);
  w.value(frame.found.has_value());
  if (frame.found) {
    const FaceOrientation& o = *frame.found;
    for (const Vec3& v : {o.nose_tip, o.up, o.facing, o.vertical}) w.value(v);
    for (double v : {o.facing_share, o.mirror_error, o.up_evidence}) w.value(v);
    w.value(o.up_from_hint);
  }
  w.array(frame.found_rim);
  w.value(frame.seconds_prepare);
  w.value(frame.seconds_map);
  return w.take();
}

MappedFrame FrameStore::deserialize(const char* bytes, size_t size) {
  Reader r(bytes, size);
  MappedFrame frame;
  frame.name = r.text();
  frame.prepared.rim = r.array<int>();
  frame.prepared.source_vertex = r.array<int>();
  frame.prepared.report = read_repair_report(r);
  frame.map.surface = read_mesh_bytes(r);
  frame.map.disk = r.array<Vec2>();
  frame.map.rim = r.array<int>();
  frame.map.source_vertex = r.array<int>();
  frame.map.normalization.a = r.value<Complex>();
  frame.map.normalization.theta = r.value<double>();
  frame.map.report = read_conformal_report(r);
  frame.normalized = r.value<bool>();
  if (r.value<bool>()) {
    FaceOrientation o;
    for (Vec3* v : {&o.nose_tip, &o.up, &o.facing, &o.vertical}) *v = r.value<Vec3>();
    for (double* v : {&o.facing_share, &o.mirror_error, &o.up_evidence}) *v = r.value<double>();
    o.up_from_hint = r.value<bool>();
    frame.found = o;
  }
  frame.found_rim = r.array<Vec3>();
  frame.seconds_prepare = r.value<double>();
  frame.seconds_map = r.value<double>();
  if (!r.done()) throw Error(ErrorCode::kInternal, "frame store: a stored frame has bytes left over");
  return frame;
}

FrameStore::Hold::Hold(std::shared_ptr<Counter> counter) : counter_(std::move(counter)) {
  const int now = ++counter_->now;
  int peak = counter_->peak.load();
  while (now > peak && !counter_->peak.compare_exchange_weak(peak, now)) {
  }
}

FrameStore::Hold::~Hold() { --counter_->now; }

FrameStore::FrameStore(Mode mode) : mode_(mode), counter_(std::make_shared<Counter>()) {}

FrameStore::~FrameStore() {
  if (fd_ >= 0) ::close(fd_);
}

void FrameStore::open_file() {
  // Unlinked as soon as it is open: the file goes when the process ends, however it ends.
  const std::filesystem::path folder = std::filesystem::temp_directory_path();
  std::string name = (folder / "facemorph-frames-XXXXXX").string();
  fd_ = ::mkstemp(name.data());
  if (fd_ < 0) {
    throw Error(ErrorCode::kIo, "cannot create a temporary file for the frames' maps in " + folder.string() + ": " + std::strerror(errno) +
                                    " (TMPDIR names another folder)");
  }
  ::unlink(name.c_str());
}

void FrameStore::reset(size_t count) {
  std::lock_guard lock(mutex_);
  entries_.assign(count, {});
  if (fd_ >= 0 && ::ftruncate(fd_, 0) != 0) throw Error(ErrorCode::kIo, std::string("cannot empty the frames' temporary file: ") + std::strerror(errno));
  end_ = 0;
  counter_->peak = counter_->now.load();
}

namespace {

// A frame handed out counts as held until its last pointer goes.
std::shared_ptr<const MappedFrame> counted(MappedFrame&& frame, FrameStore::Hold* hold) {
  struct Held {
    MappedFrame frame;
    std::unique_ptr<FrameStore::Hold> hold;
  };
  auto held = std::make_shared<Held>(Held{std::move(frame), std::unique_ptr<FrameStore::Hold>(hold)});
  return {held, &held->frame};
}

}  // namespace

void FrameStore::put(size_t i, MappedFrame&& frame) {
  if (i >= entries_.size()) throw Error(ErrorCode::kInternal, "frame store: frame " + std::to_string(i) + " is past its size");
  if (mode_ == Mode::kMemory) {
    auto stored = counted(std::move(frame), new Hold(counter_));
    std::lock_guard lock(mutex_);
    entries_[i].frame = std::move(stored);
    entries_[i].stored = true;
    return;
  }
  const std::vector<char> bytes = serialize(frame);
  uint64_t offset = 0;
  {
    std::lock_guard lock(mutex_);
    if (fd_ < 0) open_file();
    offset = end_;
    end_ += bytes.size();
  }
  // Each frame has its own range of the file: threads write side by side.
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::pwrite(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      throw Error(ErrorCode::kIo, frame.name + ": cannot write its map to the temporary file in " + std::filesystem::temp_directory_path().string() +
                                      ": " + std::strerror(errno) + " (a full disk? TMPDIR names another folder)");
    }
    done += static_cast<size_t>(n);
  }
  std::lock_guard lock(mutex_);
  entries_[i].offset = offset;
  entries_[i].size = bytes.size();
  entries_[i].stored = true;
}

std::shared_ptr<const MappedFrame> FrameStore::get(size_t i) const {
  Entry entry;
  {
    std::lock_guard lock(mutex_);
    if (i >= entries_.size() || !entries_[i].stored) throw Error(ErrorCode::kInternal, "frame store: frame " + std::to_string(i) + " was never stored");
    entry = entries_[i];
  }
  if (entry.frame) return entry.frame;
  auto hold = std::make_unique<Hold>(counter_);  // counts from the read on: the bytes are a frame's worth too
  std::vector<char> bytes(entry.size);
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, bytes.size() - done, static_cast<off_t>(entry.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw Error(ErrorCode::kIo, "frame store: cannot read frame " + std::to_string(i) + " back: " + (n < 0 ? std::strerror(errno) : "the file is short"));
    done += static_cast<size_t>(n);
  }
  MappedFrame frame = deserialize(bytes.data(), bytes.size());
  bytes = {};
  return counted(std::move(frame), hold.release());
}

void FrameStore::keep(const std::vector<size_t>& kept) {
  std::lock_guard lock(mutex_);
  std::vector<Entry> out;
  out.reserve(kept.size());
  for (size_t i : kept) out.push_back(std::move(entries_.at(i)));
  entries_ = std::move(out);
}

}  // namespace facemorph
