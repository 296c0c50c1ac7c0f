// The part file (spec/part-file.md): writing, reading, and checking what is read.
#include "codec/encoder/encode/part_file.hpp"

#include "codec/encoder/encode/registration_store.hpp"
#include "format/error.hpp"

#include "codec/encoder/encode/json_fields.hpp"
#include "codec/encoder/encode/spill_bytes.hpp"
#include "format/checksum.hpp"
#include "format/container.hpp"
#include "format/file_io.hpp"

#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

namespace facemorph {

namespace {

// The records are the encoder's byte forms (spill_bytes.hpp: numbers as their bytes), which the
// spec fixes as little-endian IEEE 754.
static_assert(std::endian::native == std::endian::little, "part files are little-endian");

constexpr format::ContainerKind kPartContainer{
    {0x89, 'F', 'M', 'S', '\r', '\n', 0x1A, '\n'}, kPartMajorVersion, kPartMinorVersion, "facemorph part file"};
constexpr std::string_view kPartHeaderChunk = "PHDR", kPartFrameChunk = "PFRM";
constexpr int kRecordZstdLevel = 3;         // a map's doubles gain little from more
constexpr size_t kMaxLandmarkNames = 4096;  // spec/capture.md §4
constexpr size_t kMaxTextBytes = 4096;      // a frame's name, path, a warning, a reason

using spill::Reader;
using spill::Writer;

// ---- The frame's record ----

enum RecordFlags : uint8_t { kMapped = 1, kKept = 2, kWithoutInterior = 4 };

void write_orientation(Writer& w, const FaceOrientation& o) {
  for (const Vec3& v : {o.nose_tip, o.up, o.facing, o.vertical}) w.value(v);
  for (double v : {o.facing_share, o.mirror_error, o.up_evidence}) w.value(v);
  w.value<uint8_t>(o.up_from_hint ? 1 : 0);
  w.value<uint8_t>(static_cast<uint8_t>(o.method));  // how it was found, and how sure (version 3)
  w.value(o.confidence);
}

FaceOrientation read_orientation(Reader& r) {
  FaceOrientation o;
  for (Vec3* v : {&o.nose_tip, &o.up, &o.facing, &o.vertical}) *v = r.value<Vec3>();
  for (double* v : {&o.facing_share, &o.mirror_error, &o.up_evidence}) *v = r.value<double>();
  o.up_from_hint = r.value<uint8_t>() != 0;
  const uint8_t method = r.value<uint8_t>();
  if (method > static_cast<uint8_t>(FaceFindingMethod::kFaceRegion))
    throw Error(ErrorCode::kCorrupt, "a found orientation's method " + std::to_string(method) + " is unknown");
  o.method = static_cast<FaceFindingMethod>(method);
  o.confidence = r.value<double>();
  if (!(o.confidence >= 0 && o.confidence <= 1)) throw Error(ErrorCode::kCorrupt, "a found orientation's confidence is outside [0, 1]");
  return o;
}

void write_summary(Writer& w, const FrameSummary& s) {
  w.text(s.name);
  w.value<int32_t>(s.vertices);
  w.value<int32_t>(s.holes_filled);
  w.text(s.repair);
  w.value<int32_t>(s.repair_totals.faces_changed);
  w.value<int32_t>(s.repair_totals.vertices_changed);
  w.value(s.repair_totals.largest_move);
  w.value(s.repair_totals.diagonal);
  w.value<int32_t>(static_cast<int32_t>(s.conformal_method));
  w.text(s.conformal_fallback_reason);
  w.value<uint8_t>(s.has_uvs ? 1 : 0);
  w.value<uint8_t>(s.has_colours ? 1 : 0);
  w.value<uint8_t>(s.found ? 1 : 0);
  if (s.found) write_orientation(w, *s.found);
  w.array(s.found_rim);
}

FrameSummary read_summary(Reader& r) {
  FrameSummary s;
  s.name = r.text();
  s.vertices = r.value<int32_t>();
  s.holes_filled = r.value<int32_t>();
  s.repair = r.text();
  s.repair_totals.faces_changed = r.value<int32_t>();
  s.repair_totals.vertices_changed = r.value<int32_t>();
  s.repair_totals.largest_move = r.value<double>();
  s.repair_totals.diagonal = r.value<double>();
  s.conformal_method = static_cast<ConformalMethod>(r.value<int32_t>());
  s.conformal_fallback_reason = r.text();
  s.has_uvs = r.value<uint8_t>() != 0;
  s.has_colours = r.value<uint8_t>() != 0;
  if (r.value<uint8_t>() != 0) s.found = read_orientation(r);
  s.found_rim = r.array<Vec3>();
  return s;
}

std::vector<char> record_bytes(const SampledFrame& f) {
  Writer w;
  w.value<int32_t>(f.index);
  w.text(f.name);
  w.value(f.time);
  w.value<uint64_t>(f.warnings.size());
  for (const std::string& warning : f.warnings) w.text(warning);
  const bool kept = f.dropped.empty();
  w.value<uint8_t>(
      static_cast<uint8_t>((f.mapped ? kMapped : 0) | (kept ? kKept : 0) | (f.without_interior_landmarks ? kWithoutInterior : 0)));
  w.text(f.dropped);
  if (f.mapped) write_summary(w, f.summary);
  if (!kept) return w.take();
  w.text(f.texture.string());
  w.array(f.landmarks);
  w.array(f.map);
  w.array(f.registration);
  w.value(f.selection.time);
  w.value(f.selection.pose.rotation);
  w.value(f.selection.pose.translation);
  w.value(f.selection.diagonal);
  w.array(f.selection.local);
  w.array(f.selection.normal);
  return w.take();
}

SampledFrame read_record(const char* bytes, size_t size) {
  Reader r(bytes, size, "the record");
  SampledFrame f;
  f.index = r.value<int32_t>();
  f.name = r.text();
  f.time = r.value<double>();
  // A warning is about one of the capture's landmarks (at most kMaxLandmarkNames).
  const auto warnings = r.value<uint64_t>();
  if (warnings > kMaxLandmarkNames) throw Error(ErrorCode::kCorrupt, "it holds more warnings than a frame has landmarks");
  for (uint64_t k = 0; k < warnings; ++k) f.warnings.push_back(r.text());
  const auto flags = r.value<uint8_t>();
  if ((flags & ~(kMapped | kKept | kWithoutInterior)) != 0) throw Error(ErrorCode::kCorrupt, "it sets unknown flags");
  f.mapped = (flags & kMapped) != 0;
  f.without_interior_landmarks = (flags & kWithoutInterior) != 0;
  const bool kept = (flags & kKept) != 0;
  f.dropped = r.text();
  if (kept != f.dropped.empty()) throw Error(ErrorCode::kCorrupt, "it is kept and dropped at once, or neither");
  if (kept && !f.mapped) throw Error(ErrorCode::kCorrupt, "it is kept but was never mapped");
  if (f.mapped) f.summary = read_summary(r);
  if (kept) {
    f.texture = r.text();
    f.landmarks = r.array<Vec3>();
    f.map = r.array<char>();
    f.registration = r.array<char>();
    f.selection.time = r.value<double>();
    f.selection.pose.rotation = r.value<Eigen::Matrix3d>();
    f.selection.pose.translation = r.value<Vec3>();
    f.selection.diagonal = r.value<double>();
    f.selection.local = r.array<Eigen::Vector3f>();
    f.selection.normal = r.array<Eigen::Vector3f>();
  }
  if (!r.done()) throw Error(ErrorCode::kCorrupt, "it has bytes left over");
  return f;
}

// ---- What a record is checked for ----

// What a coordinate of a record may be, in the capture's units: a mesh ten thousand kilometres
// across in metres. Beyond it, squares and sums overflow to infinity downstream.
constexpr double kMaxCoordinate = 1e9;

template <typename V>
bool within(const std::vector<V>& values, double bound) {
  return std::all_of(values.begin(), values.end(), [&](const V& v) { return v.allFinite() && v.cwiseAbs().maxCoeff() <= bound; });
}

bool indices_within(const std::vector<int>& indices, size_t size) {
  return std::all_of(indices.begin(), indices.end(), [&](int i) { return i >= 0 && static_cast<size_t>(i) < size; });
}

bool faces_within(const std::vector<Face>& faces, size_t size) {
  return std::all_of(faces.begin(), faces.end(), [&](const Face& f) {
    return f[0] >= 0 && f[1] >= 0 && f[2] >= 0 && static_cast<size_t>(f[0]) < size && static_cast<size_t>(f[1]) < size &&
           static_cast<size_t>(f[2]) < size;
  });
}

// What the assemble stage reads of a map: the surface and its disk (the inverse map, the fit's
// samples), its UVs or colours (textures), its holes' outlines (hole levels), its rim.
void check_map(const MappedFrame& m) {
  const TriangleMesh& s = m.map.surface;
  const size_t vertices = s.positions.size();
  if (vertices < 3 || s.faces.empty()) json_fields::bad("its map has no surface");
  if (!spill::all_finite(s.positions) || !faces_within(s.faces, vertices))
    json_fields::bad("its map's surface has a coordinate not finite or a face outside its vertices");
  if (!within(s.positions, kMaxCoordinate)) json_fields::bad("its map's surface has a coordinate past " + std::to_string(kMaxCoordinate));
  if (m.map.disk.size() != vertices || !spill::all_finite(m.map.disk)) json_fields::bad("its map's disk does not fit its surface");
  for (const Vec2& w : m.map.disk) {
    if (w.squaredNorm() > 1 + 1e-9) json_fields::bad("its map's disk has a point outside the unit disk");
  }
  if (m.map.rim.size() < 3 || !indices_within(m.map.rim, vertices)) json_fields::bad("its map's rim is not a loop of its vertices");
  for (int v : m.map.rim) {
    if (std::abs(m.map.disk[static_cast<size_t>(v)].norm() - 1) > 1e-6) json_fields::bad("its map's rim does not lie on the unit circle");
  }
  // The disk's triangles cover the unit disk once (a map may leave a few flipped, which subtract):
  // their signed areas add up to the rim polygon's area, a little under π. A disk collapsed to a
  // point or a line, or folded over itself, does not.
  double area = 0;
  for (const Face& f : s.faces) {
    const Vec2 &a = m.map.disk[static_cast<size_t>(f[0])], &b = m.map.disk[static_cast<size_t>(f[1])],
               &c = m.map.disk[static_cast<size_t>(f[2])];
    area += 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
  }
  if (!(area > 0.5 * std::numbers::pi && area < 1.01 * std::numbers::pi))
    json_fields::bad("its map's disk does not cover the unit disk once");
  if (!s.uvs.empty() && (s.uv_faces.size() != s.faces.size() || !faces_within(s.uv_faces, s.uvs.size()) || !spill::all_finite(s.uvs))) {
    json_fields::bad("its map's texture coordinates do not fit its faces");
  }
  if (s.uvs.empty() && !s.uv_faces.empty()) json_fields::bad("its map has texture faces without texture coordinates");
  if (!s.colours.empty() && (s.colours.size() != vertices || !within(s.colours, kMaxCoordinate)))
    json_fields::bad("its map's colours do not fit its vertices");
  for (const FilledHole& hole : m.prepared.report.holes) {
    if (!indices_within(hole.loop, vertices)) json_fields::bad("a hole's outline lies outside its map's vertices");
  }
}

void check_record(const SampledFrame& f, const PartHeader& header, int expected_index, size_t selection_nodes) {
  if (f.index != expected_index)
    json_fields::bad("it is frame " + std::to_string(f.index) + ", where frame " + std::to_string(expected_index) + " was due");
  if (!(f.time >= header.capture.first_time && f.time <= header.capture.last_time)) json_fields::bad("its time is outside the capture's");
  for (const std::string& warning : f.warnings) {
    if (warning.size() > kMaxTextBytes) json_fields::bad("a warning is longer than " + std::to_string(kMaxTextBytes) + " bytes");
  }
  if (f.name.size() > kMaxTextBytes || f.dropped.size() > kMaxTextBytes || f.texture.string().size() > kMaxTextBytes)
    json_fields::bad("a name is too long");
  if (f.mapped) {
    const FrameSummary& s = f.summary;
    const auto method = static_cast<int>(s.conformal_method);
    if (s.vertices < 0 || s.holes_filled < 0 || method < 0 || method > static_cast<int>(ConformalMethod::kTutte))
      json_fields::bad("its summary is out of range");
    const RepairTotals& t = s.repair_totals;
    if (t.faces_changed < 0 || t.vertices_changed < 0 || !(t.largest_move >= 0 && t.largest_move <= kMaxCoordinate) ||
        !(t.diagonal >= 0 && t.diagonal <= kMaxCoordinate)) {
      json_fields::bad("its repair totals are out of range");
    }
  }
  if (!f.dropped.empty()) return;
  if (f.landmarks.size() != header.capture.landmark_names.size())
    json_fields::bad("it holds " + std::to_string(f.landmarks.size()) + " landmarks for the part's " +
                     std::to_string(header.capture.landmark_names.size()) + " names");
  for (const Vec3& p : f.landmarks) {
    // NaN where the frame lacks the landmark; else a point.
    if (!p.hasNaN() && !(p.allFinite() && p.cwiseAbs().maxCoeff() <= kMaxCoordinate))
      json_fields::bad("a landmark is neither a point nor missing");
  }
  const SelectionFrame& s = f.selection;
  if (s.local.size() != selection_nodes || s.normal.size() != selection_nodes)
    json_fields::bad("its selection samples are not the selection grid's");
  if (s.time != f.time || !s.pose.rotation.allFinite() || !s.pose.translation.allFinite() ||
      !(s.diagonal > 1e-12 && s.diagonal <= kMaxCoordinate) || !spill::all_finite(s.local) || !spill::all_finite(s.normal)) {
    json_fields::bad("its selection samples have a number not finite");
  }
  if (!(s.pose.rotation.transpose() * s.pose.rotation - Eigen::Matrix3d::Identity()).isZero(1e-6) || !(s.pose.rotation.determinant() > 0) ||
      !(s.pose.translation.cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
    json_fields::bad("its head pose is not a rigid motion");
  }
  for (const Eigen::Vector3f& v : s.local) {
    if (!(v.cwiseAbs().maxCoeff() <= kMaxCoordinate))
      json_fields::bad("its selection samples have a coordinate past " + std::to_string(kMaxCoordinate));
  }
  if (!f.texture.empty()) {
    // Read by the assemble stage: a file, never a pipe or a device that would block or not end.
    if (!f.texture.is_absolute()) json_fields::bad("its texture's path is not absolute");
    std::error_code error;
    if (std::filesystem::status(f.texture, error).type() != std::filesystem::file_type::regular)
      json_fields::bad("its texture " + f.texture.string() + " is not a file");
  }
}

// ---- The header ----

nlohmann::json header_json(const PartHeader& h) {
  const SampledCapture& c = h.capture;
  return {{"capture", h.capture_id},
          {"root", c.root.string()},
          {"frames", c.frame_count},
          {"first", h.range.first},
          {"end", h.range.end},
          {"fps", c.fps},
          {"units", c.units},
          {"first_time", c.first_time},
          {"last_time", c.last_time},
          {"landmark_names", c.landmark_names},
          {"given_landmark_names", c.given_landmark_names},
          {"given_reference", c.given_reference},
          {"reference", c.reference},
          {"settings", nlohmann::json::parse(h.settings)},
          {"encoder", h.encoder},
          {"seconds", {{"mapping", h.seconds_mapping}, {"registration", h.seconds_registration}, {"selection", h.seconds_selection}}}};
}

template <typename T>
T field(const nlohmann::json& doc, const char* name) {
  return json_fields::field<T>(doc, name, "its header");
}
int integer_field(const nlohmann::json& doc, const char* name) { return json_fields::integer_field(doc, name, "its header"); }

// How deep the header's JSON may nest: the settings are two levels; a reader (and dump) recurses.
constexpr int kMaxHeaderDepth = 8;

PartHeader parse_header(const std::vector<uint8_t>& bytes) {
  const nlohmann::json doc = json_fields::parse_object(bytes, kMaxHeaderDepth, "its header");
  PartHeader h;
  SampledCapture& c = h.capture;
  h.capture_id = field<std::string>(doc, "capture");
  c.root = field<std::string>(doc, "root");
  c.frame_count = integer_field(doc, "frames");
  h.range = {integer_field(doc, "first"), integer_field(doc, "end")};
  c.fps = field<double>(doc, "fps");
  c.units = field<std::string>(doc, "units");
  c.first_time = field<double>(doc, "first_time");
  c.last_time = field<double>(doc, "last_time");
  c.landmark_names = field<std::vector<std::string>>(doc, "landmark_names");
  c.given_landmark_names = field<std::vector<std::string>>(doc, "given_landmark_names");
  c.given_reference = integer_field(doc, "given_reference");
  c.reference = integer_field(doc, "reference");
  if (!doc.contains("settings") || !doc["settings"].is_object()) json_fields::bad("its header lacks its settings");
  h.settings = doc["settings"].dump();
  h.encoder = field<std::string>(doc, "encoder");
  const nlohmann::json seconds = field<nlohmann::json>(doc, "seconds");
  if (!seconds.is_object()) json_fields::bad("its header's \"seconds\" is not an object");
  h.seconds_mapping = field<double>(seconds, "mapping");
  h.seconds_registration = field<double>(seconds, "registration");
  h.seconds_selection = field<double>(seconds, "selection");
  if (c.frame_count < 1 || c.frame_count > kMaxPartCaptureFrames) {
    throw Error(ErrorCode::kLimit,
                "its capture has " + std::to_string(c.frame_count) + " frames, outside 1.." + std::to_string(kMaxPartCaptureFrames));
  }
  if (h.range.first < 0 || h.range.end > c.frame_count || h.range.first >= h.range.end)
    json_fields::bad("its frames are not a range of its capture's");
  if (c.reference < 0 || c.reference >= c.frame_count || c.given_reference < 0 || c.given_reference >= c.frame_count)
    json_fields::bad("its reference frame is not one of its capture's");
  if (!(c.fps > 0) || !std::isfinite(c.fps) || !std::isfinite(c.first_time) || !std::isfinite(c.last_time))
    json_fields::bad("its capture's frame rate or times are not finite");
  if (c.landmark_names.size() > kMaxLandmarkNames)
    json_fields::bad("it names more than " + std::to_string(kMaxLandmarkNames) + " landmarks");
  if (c.given_landmark_names.size() > c.landmark_names.size() ||
      !std::equal(c.given_landmark_names.begin(), c.given_landmark_names.end(), c.landmark_names.begin())) {
    json_fields::bad("its landmark names do not begin with the capture's own");
  }
  if (!c.root.is_absolute()) json_fields::bad("its capture's folder is not an absolute path");
  return h;
}

}  // namespace

std::string capture_fingerprint(const Capture& capture) {
  using format::fnv1a;
  uint64_t h = format::kFnv1aStart;
  const auto text = [&](const std::string& s) {
    const uint64_t size = s.size();
    h = fnv1a(h, &size, sizeof size);
    h = fnv1a(h, s.data(), s.size());
  };
  const uint64_t frames = capture.frames.size();
  h = fnv1a(h, &frames, sizeof frames);
  for (const CaptureFrame& f : capture.frames) {
    text(f.mesh.string());
    h = fnv1a(h, &f.time, sizeof f.time);
  }
  h = fnv1a(h, &capture.fps, sizeof capture.fps);
  text(capture.units);
  for (const std::string& name : capture.landmark_names) text(name);
  for (const std::vector<Vec3>& points : capture.landmarks) {
    if (!points.empty()) h = fnv1a(h, points.data(), points.size() * sizeof(Vec3));
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

// ---- Writing ----

PartWriter::PartWriter(std::filesystem::path path, const PartHeader& header)
    : path_(std::move(path)), temporary_(format::temporary_sibling(path_)), header_(header) {
  out_.open(temporary_, std::ios::binary | std::ios::trunc);
  if (!out_) throw Error(ErrorCode::kIo, path_.string() + ": cannot write (" + temporary_.filename().string() + ")");
  writer_ = std::make_unique<format::ContainerWriter>(out_, kPartContainer);
  const std::string text = header_json(header_).dump();
  writer_->add(format::prepare_chunk(kPartHeaderChunk, std::vector<uint8_t>(text.begin(), text.end()), true, kRecordZstdLevel));
  next_ = header_.range.first;
}

PartWriter::~PartWriter() {
  if (finished_) return;
  out_.close();
  std::error_code ignored;
  std::filesystem::remove(temporary_, ignored);
}

void PartWriter::add(const SampledFrame& frame) {
  if (frame.index != next_ || next_ >= header_.range.end) {
    throw Error(ErrorCode::kInternal,
                path_.string() + ": frame " + std::to_string(frame.index) + " given where frame " + std::to_string(next_) + " was due");
  }
  const std::vector<char> bytes = record_bytes(frame);
  if (bytes.size() > kMaxPartRecordBytes) {
    throw Error(ErrorCode::kLimit, path_.string() + ": " + frame.name + ": its record is " + std::to_string(bytes.size() >> 20) +
                                       " MiB, over the part's " + std::to_string(kMaxPartRecordBytes >> 20) + " MiB");
  }
  try {
    writer_->add(format::prepare_chunk(kPartFrameChunk, std::vector<uint8_t>(bytes.begin(), bytes.end()), true, kRecordZstdLevel));
  } catch (const Error& e) {
    throw Error(e.code(), path_.string() + ": " + e.what());
  }
  ++next_;
}

void PartWriter::finish() {
  if (next_ != header_.range.end)
    throw Error(ErrorCode::kInternal,
                path_.string() + ": finished at frame " + std::to_string(next_) + " of " + std::to_string(header_.range.end));
  writer_->finish();
  out_.flush();
  out_.close();
  if (!out_) throw Error(ErrorCode::kIo, path_.string() + ": cannot write (a full disk?)");
  format::commit_temporary(temporary_, path_);
  finished_ = true;
}

// ---- Reading ----

PartReader::PartReader(const std::filesystem::path& path) : source_(path.string()) {
  selection_nodes_ = static_cast<size_t>(make_disk_grid(SelectionSamples::kGrid).interior_count);
  file_ = std::make_unique<format::MappedFile>(path);
  reader_ =
      std::make_unique<format::ContainerReader>(file_->bytes(), source_, static_cast<uint64_t>(kMaxPartCaptureFrames) + 2, kPartContainer);
  const std::vector<format::ChunkView>& chunks = reader_->chunks();
  try {
    if (chunks.empty() || chunks.front().type != kPartHeaderChunk) json_fields::bad("it does not begin with its header");
    header_ = parse_header(reader_->payload(chunks.front(), kMaxPartHeaderBytes));
    header_.minor_version = reader_->minor_version();
    for (size_t k = 1; k < chunks.size(); ++k) {
      if (chunks[k].type == kPartFrameChunk) {
        records_.push_back(k);
      } else if (chunks[k].critical()) {
        throw Error(ErrorCode::kUnsupported, "it holds a critical chunk " + chunks[k].type + " this reader does not know");
      }
    }
    if (records_.size() != static_cast<size_t>(header_.range.size())) {
      json_fields::bad("it holds " + std::to_string(records_.size()) + " frames' records for the " + std::to_string(header_.range.size()) +
                       " frames its header names");
    }
  } catch (const Error& e) {
    if (std::string(e.what()).rfind(source_, 0) == 0) throw;
    throw Error(e.code(), source_ + ": " + e.what());
  }
}

PartReader::~PartReader() = default;

uint64_t PartReader::file_bytes() const { return file_->bytes().size(); }

SampledFrame PartReader::frame(size_t k) const {
  const int index = header_.range.first + static_cast<int>(k);
  if (k >= records_.size()) throw Error(ErrorCode::kInternal, source_ + ": no record " + std::to_string(k));
  try {
    const std::vector<uint8_t> bytes = payload(k);
    SampledFrame f;
    try {
      f = read_record(reinterpret_cast<const char*>(bytes.data()), bytes.size());
    } catch (const Error& e) {
      json_fields::bad(e.what());  // the byte form's own errors (cut short) are the file's
    }
    check_record(f, header_, index, selection_nodes_);
    if (f.dropped.empty()) {
      MappedFrame map;
      DiskRegistration registration;
      try {
        map = FrameStore::deserialize(f.map.data(), f.map.size());
      } catch (const Error& e) {
        json_fields::bad(std::string("its map: ") + e.what());
      }
      check_map(map);
      try {
        // A registration through a partition is checked against it when the assembling encoder
        // reads it (the partition is the reference's); here, its numbers.
        registration = RegistrationStore::deserialize(f.registration.data(), f.registration.size(), nullptr, true);
      } catch (const Error& e) {
        json_fields::bad(std::string("its registration: ") + e.what());
      }
      RegistrationStore::check(registration);
    }
    return f;
  } catch (const Error& e) {
    throw Error(e.code(), source_ + ": frame " + std::to_string(index) + ": " + e.what());
  }
}

std::function<std::vector<char>()> PartReader::map_source(size_t k) const {
  if (k >= records_.size()) throw Error(ErrorCode::kInternal, source_ + ": no record " + std::to_string(k));
  return [this, k] {
    try {
      const std::vector<uint8_t> bytes = payload(k);
      return read_record(reinterpret_cast<const char*>(bytes.data()), bytes.size()).map;
    } catch (const Error& e) {
      throw Error(e.code(), source_ + ": frame " + std::to_string(header_.range.first + static_cast<int>(k)) + ": " + e.what());
    }
  };
}

std::vector<uint8_t> PartReader::payload(size_t k) const {
  const format::ChunkView& chunk = reader_->chunks()[records_[k]];
  std::vector<uint8_t> bytes = reader_->payload(chunk, kMaxPartRecordBytes);
  // Its pages leave the resident set once copied out: a long capture's parts are read through,
  // most records once, and would otherwise all stay mapped in (page cache, but counted as ours).
  file_->release_pages(chunk.offset, chunk.total_size());
  return bytes;
}

void PartReader::verify() const {
  for (size_t k = 0; k < records_.size(); ++k) (void)frame(k);
}

}  // namespace facemorph
