// A capture: the encoder's input (spec/capture.md). A folder with capture.json, one mesh per frame
// (OBJ with MTL + texture, or PLY) and landmarks.csv; or a plain folder of meshes plus fps and a
// landmarks file.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace facemorph {

struct CaptureFrame {
  std::filesystem::path mesh;  // absolute or relative to Capture::root
  double time = 0;             // seconds from the first frame
};

struct Capture {
  std::filesystem::path root;
  std::string description;
  double fps = 0;
  std::string units = "m";  // "m", "cm" or "mm"
  std::vector<CaptureFrame> frames;

  // Landmark names, and per frame one 3D point per name (NaN where a frame lacks the landmark).
  std::vector<std::string> landmark_names;
  std::vector<std::vector<Vec3>> landmarks;

  // Free-form provenance ("generator" in capture.json), e.g. fmsynth's settings, as key/value text.
  std::vector<std::pair<std::string, std::string>> generator;

  std::filesystem::path mesh_path(size_t frame) const { return root / frames[frame].mesh; }
  double duration() const { return frames.empty() ? 0.0 : frames.back().time - frames.front().time; }
  // Index of a landmark name, or -1.
  int landmark_index(const std::string& name) const;
  std::string generator_value(const std::string& key) const;  // "" when absent
};

// Metres per unit for "m", "cm", "mm"; throws kInvalidArgument otherwise.
double metres_per_unit(const std::string& units);

// Reads `path` = a capture folder (with capture.json) or the capture.json file itself. Checks that
// fps and times are finite and increasing, that every frame's mesh file exists, and the landmarks.
// Throws facemorph::Error naming the file and the defect.
Capture read_capture(const std::filesystem::path& path);

// A plain folder of .obj/.ply files (natural name order), frame i at time i / fps; landmarks from a
// CSV `frame,name,x,y,z` file (empty path: none).
Capture scan_capture_folder(const std::filesystem::path& folder, double fps, const std::filesystem::path& landmarks_csv);

// What the tools accept as a capture: a folder with capture.json (or that file), read by
// read_capture; otherwise a plain folder of meshes at `fps`, with landmarks from `landmarks_csv`.
// Throws kInvalidArgument for a plain folder without a frame rate.
Capture open_capture(const std::filesystem::path& path, double fps, const std::filesystem::path& landmarks_csv);

// Writes capture.json and landmarks.csv into capture.root (atomically, each file).
void write_capture_manifest(const Capture& capture);

// How large a capture's landmark table may grow: every frame holds a point per name, given or
// not, so a short file naming many landmarks for many frames could otherwise ask for any amount of
// memory. The defaults: 4096 names, and frames × names at most 2^24 points (384 MiB as points, up
// to twice that while names are added and each frame's vector grows by doubling; 2 hours of 74
// landmarks at 30 fps).
struct LandmarkLimits {
  size_t names = 4096;
  size_t points = size_t{1} << 24;
};

// Parses landmarks CSV text into `capture` (its frames must be set). `source` names the file.
// Throws kParse naming the row for a bad row, and for the row whose new name passes `limits`.
// read_capture and open_capture read a landmarks file a block at a time, with the default limits.
void parse_landmarks_csv(std::string_view text, const std::string& source, Capture& capture, const LandmarkLimits& limits = {});

}  // namespace facemorph
