#include "tools/tool_support.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "format/file_io.hpp"

#include <malloc.h>
#include <unistd.h>

namespace facemorph::tools {

Progress::Progress(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && ::isatty(STDERR_FILENO)), start_(std::chrono::steady_clock::now()), last_draw_(start_) {}

void Progress::update(int done, int total) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (done < total && now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  const double elapsed = seconds_since(start_);
  const double rate = elapsed > 0 ? done / elapsed : 0.0;
  const double left = rate > 0 ? (total - done) / rate : 0.0;
  std::fprintf(stderr, "\r%s %d/%d frames  %.1f frames/s  %.0f s left   ", label_.c_str(), done, total, rate, left);
  std::fflush(stderr);
  drawn_ = true;
}

void write_json(const std::string& path, const nlohmann::json& doc) {
  const std::string text = doc.dump(1) + "\n";
  if (path == "-") {
    std::fwrite(text.data(), 1, text.size(), stdout);
  } else {
    format::write_file_atomically(path, std::string_view(text));
  }
}

void Progress::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

std::string hex64(uint64_t value) {
  char text[19];
  std::snprintf(text, sizeof text, "0x%016llx", static_cast<unsigned long long>(value));
  return text;
}

double parse_fraction(const std::string& text, const char* what) {
  try {
    size_t used = 0;
    double value = std::stod(text, &used);
    const std::string rest = text.substr(used);
    if (rest == "%") {
      value /= 100;
    } else if (!rest.empty()) {
      throw std::invalid_argument(text);
    }
    if (!(value > 0) || value > 1) throw std::out_of_range(text);
    return value;
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, std::string(what) + " '" + text + "' is not a fraction in (0, 1] (e.g. 10% or 0.1)");
  }
}

int parse_whole_number(const std::string& text, const char* what, long low, long high) {
  try {
    // Digits alone, as written: std::stol would also skip leading blanks and take a '+'.
    if (text.empty() || !(std::isdigit(static_cast<unsigned char>(text[0])) || text[0] == '-')) throw std::invalid_argument(text);
    size_t used = 0;
    const long value = std::stol(text, &used, 10);
    if (used != text.size() || value < low || value > high) throw std::out_of_range(text);
    return static_cast<int>(value);
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, std::string(what) + " '" + text + "' is neither auto nor a whole number from " +
                                                 std::to_string(low) + " to " + std::to_string(high));
  }
}

void add_limit_options(CLI::App& app, DecoderLimits& limits, std::string& max_memory) {
  app.add_option("--max-memory", max_memory, "Refuse files that would need more memory than this (bytes, or 512M, 2G)")
      ->default_str("256M");
  app.add_option("--max-grid", limits.max_grid_n, "Refuse files whose grid N is larger")->capture_default_str();
  app.add_option("--max-keyframes", limits.max_keyframes, "Refuse files with more keyframes")->capture_default_str();
  app.add_option("--max-texture", limits.max_texture_size, "Refuse files whose texture has more texels per side")->capture_default_str();
  app.add_option(
         "--max-work", limits.max_work,
         "Stop a frame whose decode would do more work than this, in work units (about a second on one core at the default; 0: no bound)")
      ->capture_default_str();
}

DecoderLimits parsed_limits(DecoderLimits limits, const std::string& max_memory) {
  if (!max_memory.empty()) {
    const auto bad = [&] {
      return Error(ErrorCode::kInvalidArgument, "--max-memory '" + max_memory + "' is not a size (bytes, or 512M, 2G)");
    };
    size_t used = 0;
    unsigned long long value = 0;
    try {
      if (max_memory.find_first_not_of("0123456789KMGkmg") != std::string::npos) throw bad();
      value = std::stoull(max_memory, &used);
    } catch (const std::logic_error&) {
      throw bad();
    }
    const std::string suffix = max_memory.substr(used);
    int shift = 0;
    if (suffix == "K" || suffix == "k")
      shift = 10;
    else if (suffix == "M" || suffix == "m")
      shift = 20;
    else if (suffix == "G" || suffix == "g")
      shift = 30;
    else if (!suffix.empty())
      throw bad();
    if (value == 0 || value > (~0ull >> shift)) throw bad();
    limits.max_memory_bytes = static_cast<uint64_t>(value) << shift;
  }
  check_decoder_limits(limits, "--max-grid/--max-keyframes/--max-texture/--max-memory");
  return limits;
}

int frame_count(double begin, double end, double fps, double slack) {
  constexpr double kMaxFrames = 1e8;
  if (!(fps > 0) || !std::isfinite(fps)) throw Error(ErrorCode::kInvalidArgument, "--fps must be a finite positive number");
  if (!std::isfinite(begin) || !std::isfinite(end) || !(end >= begin))
    throw Error(ErrorCode::kInvalidArgument, "the time range is not a finite interval");
  const double frames = std::floor((end - begin) * fps + slack);  // inf - inf and overflow give no number below the bound
  if (!(frames >= 0 && frames < kMaxFrames)) {
    char text[160];
    std::snprintf(text, sizeof text, "%.4g s at %.4g fps is more than 10^8 frames", end - begin, fps);
    throw Error(ErrorCode::kInvalidArgument, text);
  }
  return static_cast<int>(frames) + 1;
}

void reuse_freed_memory() {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 32 << 20);   // glibc's largest; the dynamic threshold stops with it
  mallopt(M_TRIM_THRESHOLD, 128 << 20);
#endif
}

void start_with_huge_pages(char** argv) {
#if defined(__linux__) && defined(__GLIBC__)
  constexpr const char* kSetting = "glibc.malloc.hugetlb";
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (tunables != nullptr && std::strstr(tunables, kSetting) != nullptr) return;
  const char* choice = std::getenv("FACEMORPH_HUGE_PAGES");
  if (choice != nullptr && std::strcmp(choice, "0") == 0) return;
  std::string modes;
  {
    std::ifstream policy("/sys/kernel/mm/transparent_hugepage/enabled");  // closed before the exec
    if (!std::getline(policy, modes)) return;
  }
  if (modes.find("[madvise]") == std::string::npos) return;
  // Started through the dynamic loader (ld-linux-x86-64.so.2 ./fmenc ...), /proc/self/exe is the
  // loader, which would take the first argument for the program: not started again.
  char exe[4096];
  const ssize_t length = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (length <= 0) return;
  exe[length] = '\0';
  const char* slash = std::strrchr(exe, '/');
  if (std::strncmp(slash != nullptr ? slash + 1 : exe, "ld-", 3) == 0) return;
  const std::string previous = tunables != nullptr ? tunables : "";
  const std::string value = (previous.empty() ? "" : previous + ":") + kSetting + "=1";
  if (::setenv("GLIBC_TUNABLES", value.c_str(), 1) != 0) return;
  ::execv("/proc/self/exe", argv);
  // Not started again: go on as started, the environment as it was.
  if (tunables != nullptr) {
    ::setenv("GLIBC_TUNABLES", previous.c_str(), 1);
  } else {
    ::unsetenv("GLIBC_TUNABLES");
  }
#else
  (void)argv;
#endif
}

}  // namespace facemorph::tools
