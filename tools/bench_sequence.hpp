// What fmbench's whole-capture benches share (temporal, capture): the captures they make or find,
// the file round trip, and every captured frame decoded at its own time and measured against it.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace facemorph::tools {

// A fresh folder under the system's temporary one (NAME-PID), removed with all it holds on scope exit.
struct ScratchFolder {
  explicit ScratchFolder(const std::string& name);
  ~ScratchFolder();
  ScratchFolder(const ScratchFolder&) = delete;
  ScratchFolder& operator=(const ScratchFolder&) = delete;
  std::filesystem::path path;
};

// A capture to measure: a folder as given, or one the bench makes or finds: synth (fmsynth
// --frames 60 --expression mixed --remesh with `synth`'s noise and texture), synth:head30 (the
// same with --head-motion 30), medusa, ict (make_capture.py --start-seconds 56 --seconds 4, into
// `scratch`). nullopt when the data it needs (`data`, python3) is absent.
std::optional<std::filesystem::path> make_bench_capture(const std::string& input, const std::string& data,
                                                        const std::filesystem::path& scratch, const SynthOptions& synth, const char* bench,
                                                        bool quiet);

// `sequence` as fmenc writes it and fmdec reads it back: encode_sequence_file with per-keyframe
// `texture_qualities` (fmenc's come from choose_texture_qualities; empty: AVIF
// quality 90) and `coding` (empty: format 1.0's code planes; fmenc's come from
// round_fields), then decode_sequence_file. `bytes` and `info` (when given)
// describe the file.
Sequence file_round_trip(const Sequence& sequence, const std::vector<int>& texture_qualities, std::vector<uint8_t>* bytes = nullptr,
                         SequenceFileInfo* info = nullptr, const FieldCoding& coding = {});

struct FrameError {
  double rms = 0, max = 0;  // symmetric point-to-surface, relative to the captured frame's diagonal
  double p99 = 0;           // its 99th percentile (the worst region), relative to the same diagonal
  // The same percentile of each direction apart (record_distance): every decoded vertex to the
  // captured surface (the decoded frame's own error: issue 44's measure), and every captured vertex
  // to the decoded surface (what the decoded frame misses, a sheet the repair dropped included).
  double p99_decoded = 0, p99_captured = 0;
  double psnr = -1;         // decoded texture against the captured one on the disk (dB); -1 without
  bool keyframe = false;
  bool converged = true;
  double time = 0;
};

struct Evaluation {
  std::string registration, spline;
  int keyframes = 0, grid = 0;
  std::vector<FrameError> frames;
  double decode_ms = 0;  // mean per decoded frame
  int iterations = 0;    // mean reconstruction steps
};

struct Summary {
  double key_rms_mean = 0, key_rms_worst = 0, held_rms_mean = 0, held_rms_worst = 0, held_max_worst = 0, psnr_mean = -1, psnr_worst = -1;
  double p99_worst = 0;  // over every decoded frame, keyframes and held-out: design §7's worst-region target
  double p99_decoded_worst = 0, p99_captured_worst = 0;  // each direction's (FrameError)
};

// f's distances from surface_distance(captured frame, decoded mesh), over the captured frame's diagonal.
void record_distance(const SurfaceDistance& d, FrameError& f);

// Means and worsts over keyframes and held-out frames (texture PSNR over held-out frames).
Summary summarise(const Evaluation& e);

// PSNR (dB, peak 255) of RGB over the texels whose centres lie in the unit disk; the images are
// disk textures of one size.
double disk_psnr(const Image& a, const Image& b);

// Every frame of `frames_to_decode` decoded at its own time and compared with `captured` (holes and
// all); with `textures`, each held-out frame's texture against the captured one resampled onto the
// disk through the frame's map and registration. `on_decoded` (when set) sees every decoded frame.
Evaluation evaluate(const SequenceEncoder& encoder, const Sequence& sequence, const std::vector<int>& keyframes,
                    const std::vector<TriangleMesh>& captured, const std::vector<int>& frames_to_decode, bool textures,
                    const std::function<void(int, const DecodedFrame&)>& on_decoded = {});

nlohmann::json evaluation_json(const Evaluation& e);

// Error against time (% of the diagonal), keyframes marked, as a PNG.
void write_error_plot(const std::filesystem::path& path, const Evaluation& e);

}  // namespace facemorph::tools
