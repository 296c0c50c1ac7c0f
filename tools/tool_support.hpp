// What every facemorph command-line tool shares: the error boundary (message on stderr naming the
// file and the reason, non-zero exit) and a progress line on terminals.
#pragma once

#include "facemorph/error.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <exception>
#include <string>

namespace facemorph::tools {

// Runs `body` (which parses the command line into `app` and does the work) and turns every failure
// into a message on stderr and a non-zero exit status. Returns the process exit status.
template <typename Body>
int guarded_main(CLI::App& app, int argc, char** argv, Body&& body) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return body();
  } catch (const Error& e) {
    std::fprintf(stderr, "%s: error (%s): %s\n", app.get_name().c_str(), error_code_name(e.code()), e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", app.get_name().c_str(), e.what());
  }
  return 1;
}

// Frames done, rate and time left, redrawn in place on a terminal; silent otherwise or when quiet.
class Progress {
 public:
  Progress(std::string label, bool quiet);
  void update(int done, int total);
  void finish();

 private:
  std::string label_;
  bool enabled_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

// "0x" and 16 hex digits.
std::string hex64(uint64_t value);

double seconds_since(std::chrono::steady_clock::time_point start);

// Writes `doc` (indented) to `path` atomically, or to stdout when `path` is "-".
void write_json(const std::string& path, const nlohmann::json& doc);

}  // namespace facemorph::tools
