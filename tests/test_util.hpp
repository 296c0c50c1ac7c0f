// Shared helpers for the facemorph tests: temporary folders, shared-data lookup, shape builders.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"
#include "format/error.hpp"
#include "format/spatial_predictor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace facemorph::testing {

// Built under AddressSanitizer: it keeps freed memory in quarantine (256 MB by default), so the
// resident size says nothing about what the code keeps; and code runs 10-15x slower.
#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

// A fresh folder under the system temp directory, removed with its contents at scope exit.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() / ("facemorph-test-" + std::to_string(rd()) + "-" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// An environment variable set for a scope (TMPDIR naming a folder that does not exist, say) and put
// back as it was, or unset, at scope exit, whatever fails between.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) saved_ = old;
    setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (saved_) {
      setenv(name_, saved_->c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> saved_;
};

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// ../shared/data when the checkout sits beside it; empty when absent (tests then skip).
constexpr double kPi = std::numbers::pi;

// The golden files (tests/data, one per format version), by the name every test uses.
inline const std::string kGoldenV2_0 = std::string(FACEMORPH_TEST_DATA) + "/golden_v2_0.fmv";
inline const std::string kGoldenV2_1 = std::string(FACEMORPH_TEST_DATA) + "/golden_v2_1.fmv";

// Peak signal-to-noise ratio of `b` against `a` (8-bit samples), in dB; 99 where they are equal.
inline double psnr(const Image& a, const Image& b) {
  double squared = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) squared += std::pow(double(a.pixels[i]) - double(b.pixels[i]), 2);
  return squared == 0 ? 99.0 : 10 * std::log10(255.0 * 255.0 * static_cast<double>(a.pixels.size()) / squared);
}

// How many chunks of `type` (a four-letter tag) a file's walk found.
inline int chunk_count(const SequenceFileInfo& info, const std::string& type) {
  int count = 0;
  for (const auto& c : info.chunks) count += c.type == type ? c.count : 0;
  return count;
}

// A surface given on the disk (a function of w), sampled at every node of a grid (rim nodes included).
template <typename Grid, typename Surface>
std::vector<Vec3> sample_nodes(const Grid& grid, Surface&& surface) {
  std::vector<Vec3> out;
  for (const Vec2& w : grid.nodes) out.push_back(surface(w));
  return out;
}

inline std::filesystem::path shared_data() {
  const std::filesystem::path path = FACEMORPH_SHARED_DATA;
  std::error_code ec;
  return std::filesystem::is_directory(path, ec) ? path : std::filesystem::path();
}

// A stretch of ICT speech as a capture folder, made by the data's own script (make_capture.py:
// START_SECONDS, SECONDS long, at FPS). The test run's fixture (tests/tools/ict_captures.py) makes
// the stretches the tests ask for in one process, under FACEMORPH_ICT_CAPTURES; a stretch it did not
// make (or a test run outside ctest) is made here, into `scratch`. Empty where ../shared/data or
// python3 is absent, or the script failed: the test then skips.
inline std::filesystem::path ict_speech_capture(const std::string& start_seconds, const std::string& seconds, const std::string& fps,
                                                const std::filesystem::path& scratch) {
  const std::filesystem::path data = shared_data();
  if (data.empty()) return {};
  const std::filesystem::path made = std::filesystem::path(FACEMORPH_ICT_CAPTURES) / ("ict_" + start_seconds + "_" + seconds + "_" + fps);
  if (std::filesystem::is_regular_file(made / "capture.json")) return made;
  const std::string command = "python3 '" + (data / "ict-facekit/tools/make_capture.py").string() + "' '" + scratch.string() +
                              "' --start-seconds " + start_seconds + " --seconds " + seconds + " --fps " + fps + " > /dev/null 2>&1";
  return std::system(command.c_str()) == 0 ? scratch : std::filesystem::path();
}

// Runs `body` and checks that it throws facemorph::Error with `code` and a message containing
// `fragment` (so errors name the file / defect).
template <typename Body>
void expect_error(ErrorCode code, const std::string& fragment, Body&& body) {
  try {
    body();
    ADD_FAILURE() << "expected facemorph::Error(" << error_code_name(code) << ")";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << "message '" << e.what() << "' lacks '" << fragment << "'";
  }
}

// Regular grid triangulation of [0,1]² mapped through `surface(u, v)`; (n+1)² vertices.
template <typename Surface>
TriangleMesh grid_mesh(int n, Surface&& surface) {
  TriangleMesh mesh;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) mesh.positions.push_back(surface(double(i) / n, double(j) / n));
  }
  auto id = [n](int i, int j) { return static_cast<int32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      // Alternate diagonals so the mesh has no directional bias.
      if ((i + j) % 2 == 0) {
        mesh.faces.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        mesh.faces.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      } else {
        mesh.faces.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
        mesh.faces.push_back({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  }
  return mesh;
}

// A polar-grid disk: a centre and `rings` rings of `sectors` vertices, odd rings rotated half a
// sector, each unit-disk point w mapped through `lift(w)` (z = 0 for a flat disk); faces
// counter-clockwise seen from +z.
template <typename Lift>
TriangleMesh polar_disk(int rings, int sectors, Lift&& lift) {
  TriangleMesh m;
  m.positions.push_back(lift(Vec2(0, 0)));
  for (int r = 1; r <= rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      const double radius = static_cast<double>(r) / rings, angle = 2 * 3.14159265358979323846 * (s + 0.5 * (r % 2)) / sectors;
      m.positions.push_back(lift(Vec2(radius * std::cos(angle), radius * std::sin(angle))));
    }
  }
  auto id = [sectors](int r, int s) { return r == 0 ? 0 : 1 + (r - 1) * sectors + ((s % sectors) + sectors) % sectors; };
  for (int s = 0; s < sectors; ++s) m.faces.push_back({id(0, 0), id(1, s), id(1, s + 1)});
  for (int r = 1; r < rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      const int shift = r % 2 == 1 ? 1 : 0;  // pair each vertex with the nearest of the next ring
      m.faces.push_back({id(r, s), id(r + 1, s + shift), id(r, s + 1)});
      m.faces.push_back({id(r, s), id(r + 1, s - 1 + shift), id(r + 1, s + shift)});
    }
  }
  return m;
}

// The first promise a mesh parser broke in `mesh`, empty when it kept them all: positions and uvs
// finite, every face index in [0, vertex count), uv_faces empty or one per face with every index in
// [0, uvs.size()). Parse lambdas of survive_mutations check it, so a dropped range check fails.
inline std::string broken_mesh_invariant(const TriangleMesh& mesh) {
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    if (!mesh.positions[i].allFinite()) return "position " + std::to_string(i) + " is not finite";
  }
  for (size_t i = 0; i < mesh.uvs.size(); ++i) {
    if (!mesh.uvs[i].allFinite()) return "uv " + std::to_string(i) + " is not finite";
  }
  if (!mesh.colours.empty() && mesh.colours.size() != mesh.positions.size()) {
    return std::to_string(mesh.colours.size()) + " colours for " + std::to_string(mesh.positions.size()) + " vertices";
  }
  for (size_t i = 0; i < mesh.colours.size(); ++i) {
    if (!mesh.colours[i].allFinite() || mesh.colours[i].minCoeff() < 0 || mesh.colours[i].maxCoeff() > 1)
      return "colour " + std::to_string(i) + " outside [0, 1]";
  }
  if (!mesh.uv_faces.empty() && mesh.uv_faces.size() != mesh.faces.size()) {
    return std::to_string(mesh.uv_faces.size()) + " uv faces for " + std::to_string(mesh.faces.size()) + " faces";
  }
  for (const auto* faces : {&mesh.faces, &mesh.uv_faces}) {
    const size_t count = faces == &mesh.faces ? mesh.positions.size() : mesh.uvs.size();
    for (size_t f = 0; f < faces->size(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int32_t index = (*faces)[f][k];
        if (index < 0 || static_cast<size_t>(index) >= count) {
          return std::string(faces == &mesh.faces ? "face " : "uv face ") + std::to_string(f) + " index " + std::to_string(index) +
                 " out of range (" + std::to_string(count) + ")";
        }
      }
    }
  }
  return {};
}

// One random edit of `bytes` per call, up to four: a byte flipped, the input truncated, a byte
// inserted or erased, a plausible text character written, or a run of digits inserted (indices and
// counts past any range: "f 1 2 3" becomes "f 1 27380 3" or "f 1 2 -9182736455463728193").
inline std::vector<uint8_t> mutate(std::vector<uint8_t> bytes, std::mt19937& rng) {
  std::uniform_int_distribution<int> kind(0, 5), byte(0, 255);
  const int edits = 1 + static_cast<int>(rng() % 4);
  for (int e = 0; e < edits && !bytes.empty(); ++e) {
    const size_t at = rng() % bytes.size();
    switch (kind(rng)) {
      case 0: bytes[at] = static_cast<uint8_t>(byte(rng)); break;  // flip a byte
      case 1: bytes.resize(at); break;                             // truncate
      case 2: bytes.insert(bytes.begin() + static_cast<long>(at), static_cast<uint8_t>(byte(rng))); break;
      case 3: bytes.erase(bytes.begin() + static_cast<long>(at)); break;
      case 4: bytes[at] = "0123456789-.e \n/"[rng() % 16]; break;  // plausible text
      case 5: {                                                    // digit run
        std::string run(1 + rng() % 20, '0');
        for (char& c : run) c = static_cast<char>('0' + rng() % 10);
        if (rng() % 4 == 0) run.front() = '-';
        bytes.insert(bytes.begin() + static_cast<long>(at), run.begin(), run.end());
        break;
      }
    }
  }
  return bytes;
}

// A deterministic stand-in for fuzzing: `parse` runs on 1500 mutations of `seed` and must either
// throw facemorph::Error or succeed (a crash or out-of-bounds read fails, under the sanitizers).
// `parse` itself asserts the invariants of what it parsed (EXPECT_*); the first trial that breaks
// one ends the run. Some mutations must reach an error path.
template <typename Parse>
void survive_mutations(const std::vector<uint8_t>& seed, unsigned rng_seed, Parse&& parse, int trials = 1500) {
  std::mt19937 rng(rng_seed);
  int errors = 0;
  const ::testing::TestResult* result = ::testing::UnitTest::GetInstance()->current_test_info()->result();
  const int failures_before = result->total_part_count();
  for (int trial = 0; trial < trials; ++trial) {
    const std::vector<uint8_t> input = mutate(seed, rng);
    try {
      parse(input);
    } catch (const Error&) {
      ++errors;
    }
    if (result->total_part_count() > failures_before) {
      ADD_FAILURE() << "mutation " << trial << " of rng seed " << rng_seed << " (" << input.size()
                    << " bytes) was parsed into something invalid";
      return;
    }
  }
  EXPECT_GT(errors, 0);  // the mutations did reach the error paths
}

// Icosphere of radius r with `subdivisions` loop-style midpoint splits, outward-facing.
TriangleMesh icosphere(double radius, int subdivisions);

// The 5-point Laplacian of an n x n grid plus shift·I (SPD for shift > 0; semidefinite at 0): the
// sparse solvers' tests.
SparseMatrix shifted_grid_laplacian(int n, double shift);

// A w x w square lattice in row-major order, with its neighbour table (the residual coders' tests).
inline format::LatticeNeighbours square_lattice(int w) {
  format::LatticeNeighbours l;
  for (int j = 0; j < w; ++j) {
    for (int i = 0; i < w; ++i) {
      l.left.push_back(i > 0 ? j * w + i - 1 : -1);
      l.up.push_back(j > 0 ? (j - 1) * w + i : -1);
      l.up_left.push_back(i > 0 && j > 0 ? (j - 1) * w + i - 1 : -1);
    }
  }
  return l;
}

}  // namespace facemorph::testing
