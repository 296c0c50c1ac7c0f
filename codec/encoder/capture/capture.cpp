// capture.json + landmarks.csv reading and writing.
#include "facemorph/encoder/capture.hpp"
#include "facemorph/error.hpp"

#include "codec/meshkit/mesh/text_scan.hpp"
#include "format/file_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace facemorph {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr uint64_t kMaxManifestBytes = uint64_t{1} << 28;

[[noreturn]] void fail(ErrorCode code, const std::string& source, const std::string& why) {
  throw Error(code, source + ": " + why);
}

void check_frames(const Capture& capture, const std::string& source) {
  if (capture.frames.empty()) fail(ErrorCode::kParse, source, "the capture has no frames");
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    const double t = capture.frames[i].time;
    if (!std::isfinite(t)) fail(ErrorCode::kParse, source, "frame " + std::to_string(i) + " has a non-finite time");
    if (i > 0 && !(t > capture.frames[i - 1].time)) {
      fail(ErrorCode::kParse, source, "frame " + std::to_string(i) + " (" + capture.frames[i].mesh.string() +
                                          ") has time " + std::to_string(t) + ", not after the previous frame");
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

void parse_landmarks_csv(std::string_view text_data, const std::string& source, Capture& capture) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  text::LineScanner lines(text_data);
  std::string_view line;
  if (!lines.next(line) || text::trim(line) != "frame,name,x,y,z") {
    fail(ErrorCode::kParse, source, "the first line must be the header 'frame,name,x,y,z'");
  }
  std::map<std::string, int> index;
  for (size_t i = 0; i < capture.landmark_names.size(); ++i) index[capture.landmark_names[i]] = static_cast<int>(i);
  std::vector<std::vector<uint8_t>> seen;
  while (lines.next(line)) {
    line = text::trim(line);
    if (line.empty()) continue;
    std::string_view fields[5];
    size_t count = 0;
    for (size_t start = 0; count < 5;) {
      const size_t comma = line.find(',', start);
      fields[count++] = text::trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
      if (count == 5) fail(ErrorCode::kParse, source + ":" + std::to_string(lines.line_number()), "more than 5 fields");
    }
    const std::string where = source + ":" + std::to_string(lines.line_number());
    if (count != 5) fail(ErrorCode::kParse, where, "expected 5 fields frame,name,x,y,z");
    const auto frame = text::parse_int(fields[0]);
    if (!frame || *frame < 0 || *frame >= static_cast<int64_t>(capture.frames.size())) {
      fail(ErrorCode::kParse, where, "frame '" + std::string(fields[0]) + "' is not a frame of the capture (0.." +
                                         std::to_string(capture.frames.size() - 1) + ")");
    }
    if (fields[1].empty()) fail(ErrorCode::kParse, where, "empty landmark name");
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      const auto value = text::parse_double(fields[2 + k]);
      if (!value || !std::isfinite(*value)) fail(ErrorCode::kParse, where, "coordinate '" + std::string(fields[2 + k]) + "' is not a finite number");
      p[k] = *value;
    }
    const std::string name(fields[1]);
    auto [it, inserted] = index.emplace(name, static_cast<int>(capture.landmark_names.size()));
    if (inserted) {
      capture.landmark_names.push_back(name);
      for (auto& frame_points : capture.landmarks) frame_points.push_back(Vec3::Constant(nan));
      for (auto& flags : seen) flags.push_back(0);
    }
    if (capture.landmarks.size() != capture.frames.size()) {
      capture.landmarks.assign(capture.frames.size(), std::vector<Vec3>(capture.landmark_names.size(), Vec3::Constant(nan)));
      seen.assign(capture.frames.size(), std::vector<uint8_t>(capture.landmark_names.size(), 0));
    }
    auto& flag = seen[static_cast<size_t>(*frame)][static_cast<size_t>(it->second)];
    if (flag) fail(ErrorCode::kParse, where, "landmark '" + name + "' given twice for frame " + std::to_string(*frame));
    flag = 1;
    capture.landmarks[static_cast<size_t>(*frame)][static_cast<size_t>(it->second)] = p;
  }
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
      f.time = frame.contains("time") && frame["time"].is_number() ? frame["time"].get<double>()
                                                                    : static_cast<double>(i) / capture.fps;
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
      const fs::path csv_path = capture.root / csv;
      const auto csv_bytes = format::read_file(csv_path, kMaxManifestBytes);
      parse_landmarks_csv(std::string_view(reinterpret_cast<const char*>(csv_bytes.data()), csv_bytes.size()),
                          csv_path.string(), capture);
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
    const auto bytes = format::read_file(landmarks_csv, kMaxManifestBytes);
    parse_landmarks_csv(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                        landmarks_csv.string(), capture);
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
      csv += std::to_string(f) + "," + capture.landmark_names[l] + "," + text::format_number(p.x()) + "," +
             text::format_number(p.y()) + "," + text::format_number(p.z()) + "\n";
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
    throw Error(ErrorCode::kInvalidArgument, path.string() + ": no capture.json here; give --fps (and --landmarks) to read it as a plain folder of meshes");
  }
  return scan_capture_folder(path, fps, landmarks_csv);
}

}  // namespace facemorph
