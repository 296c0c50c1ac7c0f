// Hostile.LibraryHoldsOnEveryFile (issue 46): hostile_corpus's files through the library in one
// process, as a player embeds it, so that the sanitizer build (which builds no tools) runs the
// whole hostile set too: for each file of the manifest, fminfo's description (describe_sequence_file:
// header, index and checksums) and check (inspect_sequence_file, fminfo --verify: every keyframe
// decoded once, every checksum verified), then the player C API at its defaults
// (fm_file_open_with_options, fm_file_get_info, fm_decoder_create, and fm_decoder_decode at each of
// the manifest's times into buffers for every output: positions, normals, uvs, indices, texture).
// Each step must succeed with finite numbers, or fail with an error naming the file (the C API's
// message, or the exception's), saying what the manifest says where every run must refuse the
// file. A sanitizer's report aborts the process, which fails the test. Prints each file's time and
// the process's peak resident memory; bounds on those are the tools' test's
// (tests/tools/hostile_files_test.sh, one process a run), not this one's: the sanitizers cost a
// multiple of both.
//   hostile_check DIR   (DIR: hostile_corpus's output, with its manifest.tsv)
#include "codec/decoder/container/sequence_file.hpp"
#include "facemorph.h"
#include "format/error.hpp"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

struct ManifestEntry {
  std::string name;
  std::vector<double> times;
  std::string refused;  // what every step's error must say ("": the file may open and decode)
};

std::vector<ManifestEntry> read_manifest(const fs::path& dir) {
  std::ifstream in(dir / "manifest.tsv");
  if (!in) throw std::runtime_error((dir / "manifest.tsv").string() + ": cannot read");
  std::vector<ManifestEntry> entries;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> columns;
    std::stringstream fields(line);
    std::string column;
    while (std::getline(fields, column, '\t')) columns.push_back(column);
    if (columns.size() < 3) throw std::runtime_error("manifest line without its columns: " + line);
    ManifestEntry e{columns[0], {}, columns.size() > 3 ? columns[3] : ""};
    std::stringstream times(columns[1]);
    std::string t;
    while (std::getline(times, t, ',')) e.times.push_back(std::stod(t));
    entries.push_back(std::move(e));
  }
  return entries;
}

// Failures of one file, said on stderr; the count decides the exit status.
class Verdict {
 public:
  explicit Verdict(std::string name) : name_(std::move(name)) {}

  void fail(const std::string& why) {
    std::fprintf(stderr, "FAIL: %s: %s\n", name_.c_str(), why.c_str());
    ++failures_;
  }
  // An error from `step`: it must name the file, and say `refused` where the manifest gives it.
  void refused_by(const std::string& step, const std::string& message, const std::string& refused) {
    if (message.find(name_) == std::string::npos) fail(step + ": an error that does not name the file: " + message);
    if (!refused.empty() && message.find(refused) == std::string::npos) fail(step + ": not refused with '" + refused + "': " + message);
  }
  // A step that succeeded where every step must refuse the file.
  void succeeded(const std::string& step, const std::string& refused) {
    if (!refused.empty()) fail(step + ": succeeded; every step must refuse the file with '" + refused + "'");
  }
  int failures() const { return failures_; }

 private:
  std::string name_;
  int failures_ = 0;
};

bool all_finite(const std::vector<float>& values) {
  for (float v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

// fm_decoder_decode at t: the count query, then every buffer.
void decode_at(fm_decoder* decoder, double t, const ManifestEntry& entry, Verdict& verdict) {
  const std::string step = "fm_decoder_decode at t = " + std::to_string(t);
  fm_frame sizes;
  fm_frame_init(&sizes);
  fm_status status = fm_decoder_decode(decoder, t, FM_DECODE_CLAMP, &sizes);
  if (status != FM_OK) {
    verdict.refused_by(step, fm_last_error_message(), entry.refused);
    return;
  }
  std::vector<float> positions(3 * size_t{sizes.vertex_count}), normals(positions.size()), uvs(2 * size_t{sizes.vertex_count});
  std::vector<uint32_t> indices(3 * size_t{sizes.triangle_count});
  std::vector<uint8_t> texture(4 * size_t{sizes.texture_size} * sizes.texture_size);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.positions = positions.data(), frame.positions_bytes = positions.size() * sizeof(float);
  frame.normals = normals.data(), frame.normals_bytes = normals.size() * sizeof(float);
  frame.uvs = uvs.data(), frame.uvs_bytes = uvs.size() * sizeof(float);
  frame.indices = indices.data(), frame.indices_bytes = indices.size() * sizeof(uint32_t);
  frame.texture = texture.empty() ? nullptr : texture.data(), frame.texture_bytes = texture.size();
  status = fm_decoder_decode(decoder, t, FM_DECODE_CLAMP, &frame);
  if (status != FM_OK) {
    verdict.refused_by(step, fm_last_error_message(), entry.refused);
    return;
  }
  verdict.succeeded(step, entry.refused);
  if (!all_finite(positions) || !all_finite(normals) || !all_finite(uvs)) verdict.fail(step + ": FM_OK with a number that is not finite");
  for (uint32_t index : indices) {
    if (index >= sizes.vertex_count) return verdict.fail(step + ": FM_OK with a triangle index past the vertices");
  }
}

void check_file(const fs::path& path, const ManifestEntry& entry, Verdict& verdict) {
  // fminfo's description decodes no keyframe, so a file refused for a keyframe's content may pass
  // it: it must describe the file or refuse it by name, whatever the manifest says.
  try {
    facemorph::describe_sequence_file(path);
  } catch (const facemorph::Error& e) {
    verdict.refused_by("describe_sequence_file", e.what(), "");
  }
  try {
    facemorph::inspect_sequence_file(path);
    verdict.succeeded("inspect_sequence_file", entry.refused);
  } catch (const facemorph::Error& e) {
    verdict.refused_by("inspect_sequence_file", e.what(), entry.refused);
  }
  fm_decoder_options options;
  fm_decoder_options_init(&options);
  fm_file* file = nullptr;
  if (fm_file_open_with_options(path.c_str(), &options, &file) != FM_OK) {
    verdict.refused_by("fm_file_open_with_options", fm_last_error_message(), entry.refused);
    return;
  }
  fm_info info;
  fm_info_init(&info);
  if (fm_file_get_info(file, &info) != FM_OK) verdict.fail(std::string("fm_file_get_info of an opened file: ") + fm_last_error_message());
  fm_decoder* decoder = nullptr;
  if (fm_decoder_create(file, &decoder) != FM_OK) {
    verdict.refused_by("fm_decoder_create", fm_last_error_message(), entry.refused);
  } else {
    for (double t : entry.times) decode_at(decoder, t, entry, verdict);
    fm_decoder_destroy(decoder);
  }
  fm_file_close(file);
}

double peak_resident_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024;  // kilobytes on Linux
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hostile_check DIR\n");
    return 2;
  }
  try {
    const fs::path dir = argv[1];
    int failures = 0;
    double worst_seconds = 0;
    std::string worst_file;
    for (const ManifestEntry& entry : read_manifest(dir)) {
      const auto start = std::chrono::steady_clock::now();
      Verdict verdict(entry.name);
      check_file(dir / entry.name, entry, verdict);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::printf("%-36s %6.2f s  peak so far %7.1f MiB  %s\n", entry.name.c_str(), seconds, peak_resident_mib(),
                  verdict.failures() ? "FAILED" : "ok");
      if (seconds > worst_seconds) worst_seconds = seconds, worst_file = entry.name;
      failures += verdict.failures();
    }
    std::printf("worst file %.2f s (%s); the process's peak %.1f MiB\n", worst_seconds, worst_file.c_str(), peak_resident_mib());
    if (failures > 0) {
      std::printf("%d failures\n", failures);
      return 1;
    }
    std::printf("every file refused by name or decoded finite through the library\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hostile_check: %s\n", e.what());
    return 1;
  }
  return 0;
}
