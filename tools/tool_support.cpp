#include "tools/tool_support.hpp"

#include "format/file_io.hpp"

#include <unistd.h>

namespace facemorph::tools {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

Progress::Progress(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && ::isatty(STDERR_FILENO)), start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

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

}  // namespace facemorph::tools
