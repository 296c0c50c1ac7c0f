// capture.json + landmarks.csv reading and writing.
#include "codec/encoder/capture/capture.hpp"
#include "format/error.hpp"

#include "codec/meshkit/mesh/text_scan.hpp"
#include "format/file_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>

namespace facemorph {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr uint64_t kMaxManifestBytes = uint64_t{1} << 28;
constexpr size_t kMaxLandmarkLineBytes = 4096;

[[noreturn]] void fail(ErrorCode code, const std::string& source, const std::string& why) { throw Error(code, source + ": " + why); }

void check_frames(const Capture& capture, const std::string& source) {
  if (capture.frames.empty()) fail(ErrorCode::kParse, source, "the capture has no frames");
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    const double t = capture.frames[i].time;
    if (!std::isfinite(t)) fail(ErrorCode::kParse, source, "frame " + std::to_string(i) + " has a non-finite time");
    if (i > 0 && !(t > capture.frames[i - 1].time)) {
      fail(ErrorCode::kParse, source,
           "frame " + std::to_string(i) + " (" + capture.frames[i].mesh.string() + ") has time " + std::to_string(t) +
               ", not after the previous frame");
    }
    std::error_code ec;
    if (!fs::is_regular_file(capture.mesh_path(i), ec)) {
      fail(ErrorCode::kIo, capture.mesh_path(i).string(), "frame " + std::to_string(i) + " mesh file not found");
    }
  }
}

// Natural order: "frame_2" before "frame_10".
bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      std::string_view na(a.data() + i, ie - i), nb(b.data() + j, je - j);
      while (na.size() > 1 && na.front() == '0') na.remove_prefix(1);
      while (nb.size() > 1 && nb.front() == '0') nb.remove_prefix(1);
      if (na.size() != nb.size()) return na.size() < nb.size();
      if (na != nb) return na < nb;
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

}  // namespace

int Capture::landmark_index(const std::string& name) const {
  const auto it = std::find(landmark_names.begin(), landmark_names.end(), name);
  return it == landmark_names.end() ? -1 : static_cast<int>(it - landmark_names.begin());
}

std::string Capture::generator_value(const std::string& key) const {
  for (const auto& [k, v] : generator) {
    if (k == key) return v;
  }
  return {};
}

double metres_per_unit(const std::string& units) {
  if (units == "m") return 1.0;
  if (units == "cm") return 0.01;
  if (units == "mm") return 0.001;
  throw Error(ErrorCode::kInvalidArgument, "unknown units '" + units + "' (m, cm or mm)");
}

namespace {

// A landmarks file's rows into a capture, one line at a time (the file is read a block at a time:
// an hour of 74 landmarks at 30 fps is 300 MB of text, which need not be in memory at once).
class LandmarkRows {
 public:
  LandmarkRows(const std::string& source, Capture& capture, const LandmarkLimits& limits)
      : source_(source), capture_(capture), limits_(limits) {
    for (size_t i = 0; i < capture.landmark_names.size(); ++i) index_[capture.landmark_names[i]] = static_cast<int>(i);
  }

  void line(std::string_view line, size_t number) {
    if (line.size() > kMaxLandmarkLineBytes) {
      fail(ErrorCode::kParse, source_ + ":" + std::to_string(number),
           "a line longer than " + std::to_string(kMaxLandmarkLineBytes) + " bytes");
    }
    if (!header_seen_) {
      if (text::trim(line) != "frame,name,x,y,z") fail(ErrorCode::kParse, source_, "the first line must be the header 'frame,name,x,y,z'");
      header_seen_ = true;
      return;
    }
    line = text::trim(line);
    if (line.empty()) return;
    const std::string where = source_ + ":" + std::to_string(number);
    std::string_view fields[5];
    size_t count = 0;
    for (size_t start = 0; count < 5;) {
      const size_t comma = line.find(',', start);
      fields[count++] = text::trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
      if (count == 5) fail(ErrorCode::kParse, where, "more than 5 fields");
    }
    if (count != 5) fail(ErrorCode::kParse, where, "expected 5 fields frame,name,x,y,z");
    const auto frame = text::parse_int(fields[0]);
    const size_t frames = capture_.frames.size();
    if (!frame || *frame < 0 || *frame >= static_cast<int64_t>(frames)) {
      fail(ErrorCode::kParse, where,
           "frame '" + std::string(fields[0]) + "' is not a frame of the capture (0.." + std::to_string(frames - 1) + ")");
    }
    if (fields[1].empty()) fail(ErrorCode::kParse, where, "empty landmark name");
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      const auto value = text::parse_double(fields[2 + k]);
      if (!value || !std::isfinite(*value))
        fail(ErrorCode::kParse, where, "coordinate '" + std::string(fields[2 + k]) + "' is not a finite number");
      p[k] = *value;
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const std::string name(fields[1]);
    auto it = index_.find(name);
    if (it == index_.end()) {
      // Every frame holds a point per name, given or not: the names and the table are bounded
      // before they grow, so that a short file cannot ask for a table of any size.
      const size_t names = capture_.landmark_names.size() + 1;
      if (names > limits_.names) fail(ErrorCode::kParse, where, "more than " + std::to_string(limits_.names) + " landmark names");
      if (names * frames > limits_.points) {
        fail(ErrorCode::kParse, where,
             std::to_string(names) + " landmark names for " + std::to_string(frames) + " frames: more than the " +
                 std::to_string(limits_.points) + " landmark points a capture may hold");
      }
      it = index_.emplace(name, static_cast<int>(capture_.landmark_names.size())).first;
      capture_.landmark_names.push_back(name);
      for (auto& frame_points : capture_.landmarks) frame_points.push_back(Vec3::Constant(nan));
      for (auto& flags : seen_) flags.push_back(0);
    }
    if (capture_.landmarks.size() != frames) {
      capture_.landmarks.assign(frames, std::vector<Vec3>(capture_.landmark_names.size(), Vec3::Constant(nan)));
      seen_.assign(frames, std::vector<uint8_t>(capture_.landmark_names.size(), 0));
    }
    auto& flag = seen_[static_cast<size_t>(*frame)][static_cast<size_t>(it->second)];
    if (flag) fail(ErrorCode::kParse, where, "landmark '" + name + "' given twice for frame " + std::to_string(*frame));
    flag = 1;
    capture_.landmarks[static_cast<size_t>(*frame)][static_cast<size_t>(it->second)] = p;
  }

  void finish() const {
    if (!header_seen_) fail(ErrorCode::kParse, source_, "the first line must be the header 'frame,name,x,y,z'");
  }

 private:
  const std::string& source_;
  Capture& capture_;
  LandmarkLimits limits_;
  bool header_seen_ = false;
  std::map<std::string, int> index_;
  std::vector<std::vector<uint8_t>> seen_;
};

// Calls `line` with every line of the file (without its "\n" or "\r\n") and its number from 1,
// reading a block at a time. Throws kIo when the file cannot be read, kParse for a line longer than
// kMaxLandmarkLineBytes (no landmark row is, and the line is kept whole until its end is read).
template <typename OnLine>
void for_each_line(const fs::path& path, const OnLine& on_line) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) fail(ErrorCode::kIo, path.string(), "is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(ErrorCode::kIo, path.string(), "cannot be opened");
  std::vector<char> block(size_t{1} << 20);
  std::string pending;  // a line begun in an earlier block
  size_t number = 0;
  auto emit = [&](std::string_view line) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    on_line(line, ++number);
  };
  for (;;) {
    in.read(block.data(), static_cast<std::streamsize>(block.size()));
    if (in.bad()) fail(ErrorCode::kIo, path.string(), "read failed");
    const auto got = static_cast<size_t>(in.gcount());
    if (got == 0) break;
    size_t start = 0;
    for (size_t i = 0; i < got; ++i) {
      if (block[i] != '\n') continue;
      const std::string_view piece(block.data() + start, i - start);
      if (pending.empty()) {
        emit(piece);
      } else {
        pending.append(piece);
        emit(pending);
        pending.clear();
      }
      start = i + 1;
    }
    pending.append(block.data() + start, got - start);
    // One byte more than a row may hold: the "\r" of a CRLF row whose "\n" is in the next block.
    if (pending.size() > kMaxLandmarkLineBytes + 1) {
      fail(ErrorCode::kParse, path.string() + ":" + std::to_string(number + 1),
           "a line longer than " + std::to_string(kMaxLandmarkLineBytes) + " bytes");
    }
  }
  if (!pending.empty()) emit(pending);
}

void read_landmarks_csv(const fs::path& path, Capture& capture) {
  const std::string source = path.string();
  LandmarkRows rows(source, capture, {});
  for_each_line(path, [&](std::string_view line, size_t number) { rows.line(line, number); });
  rows.finish();
}

}  // namespace

void parse_landmarks_csv(std::string_view text_data, const std::string& source, Capture& capture, const LandmarkLimits& limits) {
  LandmarkRows rows(source, capture, limits);
  text::LineScanner lines(text_data);
  std::string_view line;
  while (lines.next(line)) rows.line(line, lines.line_number());
  rows.finish();
}

Capture read_capture(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    throw Error(ErrorCode::kIo, path.string() + ": not found (expected a capture folder with capture.json, or the capture.json file)");
  }
  const fs::path manifest = fs::is_directory(path, ec) ? path / "capture.json" : path;
  const std::string source = manifest.string();
  const auto bytes = format::read_file(manifest, kMaxManifestBytes);
  json doc;
  try {
    doc = json::parse(bytes.begin(), bytes.end());
  } catch (const json::exception& e) {
    fail(ErrorCode::kParse, source, std::string("not valid JSON: ") + e.what());
  }
  Capture capture;
  capture.root = manifest.parent_path();
  try {
    if (!doc.is_object()) fail(ErrorCode::kParse, source, "the manifest must be a JSON object");
    if (!doc.contains("fps") || !doc["fps"].is_number()) fail(ErrorCode::kParse, source, "missing number 'fps'");
    capture.fps = doc["fps"].get<double>();
    if (!std::isfinite(capture.fps) || capture.fps <= 0) fail(ErrorCode::kParse, source, "fps must be a positive number");
    capture.units = doc.value("units", std::string("m"));
    metres_per_unit(capture.units);
    capture.description = doc.value("description", std::string());
    if (!doc.contains("frames") || !doc["frames"].is_array()) fail(ErrorCode::kParse, source, "missing array 'frames'");
    size_t i = 0;
    for (const json& frame : doc["frames"]) {
      if (!frame.is_object() || !frame.contains("mesh") || !frame["mesh"].is_string()) {
        fail(ErrorCode::kParse, source, "frame " + std::to_string(i) + " lacks a 'mesh' file name");
      }
      CaptureFrame f;
      f.mesh = frame["mesh"].get<std::string>();
      f.time = frame.contains("time") && frame["time"].is_number() ? frame["time"].get<double>() : static_cast<double>(i) / capture.fps;
      capture.frames.push_back(std::move(f));
      ++i;
    }
    if (doc.contains("generator") && doc["generator"].is_object()) {
      for (const auto& [key, value] : doc["generator"].items()) {
        capture.generator.emplace_back(key, value.is_string() ? value.get<std::string>() : value.dump());
      }
    }
    check_frames(capture, source);
    const std::string csv = doc.value("landmarks_csv", std::string());
    if (!csv.empty()) {
      read_landmarks_csv(capture.root / csv, capture);
    }
  } catch (const json::exception& e) {
    fail(ErrorCode::kParse, source, std::string("unexpected value: ") + e.what());
  }
  return capture;
}

Capture scan_capture_folder(const fs::path& folder, double fps, const fs::path& landmarks_csv) {
  if (!std::isfinite(fps) || fps <= 0) throw Error(ErrorCode::kInvalidArgument, "--fps must be a positive number");
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw Error(ErrorCode::kIo, folder.string() + ": not a folder");
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (entry.is_regular_file() && (ext == ".obj" || ext == ".ply")) names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end(), natural_less);
  Capture capture;
  capture.root = folder;
  capture.fps = fps;
  for (size_t i = 0; i < names.size(); ++i) capture.frames.push_back({names[i], static_cast<double>(i) / fps});
  if (capture.frames.empty()) throw Error(ErrorCode::kParse, folder.string() + ": no .obj or .ply frames");
  check_frames(capture, folder.string());
  if (!landmarks_csv.empty()) {
    read_landmarks_csv(landmarks_csv, capture);
  }
  return capture;
}

void write_capture_manifest(const Capture& capture) {
  json doc;
  doc["description"] = capture.description;
  doc["fps"] = capture.fps;
  doc["units"] = capture.units;
  json frames = json::array();
  for (const CaptureFrame& f : capture.frames) frames.push_back({{"mesh", f.mesh.generic_string()}, {"time", f.time}});
  doc["frames"] = std::move(frames);
  if (!capture.landmark_names.empty()) doc["landmarks_csv"] = "landmarks.csv";
  if (!capture.generator.empty()) {
    json generator = json::object();
    for (const auto& [key, value] : capture.generator) generator[key] = value;
    doc["generator"] = std::move(generator);
  }
  format::write_file_atomically(capture.root / "capture.json", std::string_view(doc.dump(1) + "\n"));

  if (capture.landmark_names.empty()) return;
  std::string csv = "frame,name,x,y,z\n";
  for (size_t f = 0; f < capture.landmarks.size(); ++f) {
    for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
      const Vec3& p = capture.landmarks[f][l];
      if (!p.allFinite()) continue;
      csv += std::to_string(f) + "," + capture.landmark_names[l] + "," + text::format_number(p.x()) + "," + text::format_number(p.y()) +
             "," + text::format_number(p.z()) + "\n";
    }
  }
  format::write_file_atomically(capture.root / "landmarks.csv", std::string_view(csv));
}

Capture open_capture(const std::filesystem::path& path, double fps, const std::filesystem::path& landmarks_csv) {
  std::error_code ec;
  const bool manifest = std::filesystem::is_regular_file(path, ec) || std::filesystem::exists(path / "capture.json", ec);
  if (manifest) return read_capture(path);
  if (!std::filesystem::is_directory(path, ec)) throw Error(ErrorCode::kIo, path.string() + ": no such capture folder");
  if (!(fps > 0)) {
    throw Error(ErrorCode::kInvalidArgument,
                path.string() + ": no capture.json here; give --fps (and --landmarks) to read it as a plain folder of meshes");
  }
  return scan_capture_folder(path, fps, landmarks_csv);
}

}  // namespace facemorph
