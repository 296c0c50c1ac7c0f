// What every facemorph command-line tool shares: the error boundary (message on stderr naming the
// file and the reason, non-zero exit) and a progress line on terminals.
#pragma once

#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/util/elapsed.hpp"
#include "format/error.hpp"

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

// Keeps the memory a decode frees in the process for the next keyframe's (glibc: a fixed mmap
// threshold of 32 MiB and a trim threshold of 128 MiB) where glibc's defaults handed it back to the
// kernel after each and faulted it in again: fminfo --verify on the hostile e_400_keyframes_n257.fmv
// (400 keyframes at N = 257) took 555k page faults and 9.6 s of CPU, 3.8 s of it system time, on a
// virtual machine whose faults are dear; 2.8 s with this, the same peak resident memory (77 MB).
// Called by the decoding tools (fminfo, fmdec) at start; a library must not set it for its caller.
void reuse_freed_memory();

// Starts the process again, once, with glibc's transparent huge pages for what malloc maps
// (GLIBC_TUNABLES=glibc.malloc.hugetlb=1, which glibc reads only at start), where the kernel gives
// them on request (/sys/kernel/mm/transparent_hugepage/enabled is "madvise"; "always" has them
// already, "never" none). The encoder allocates and frees hundreds of MB of arrays a second, and on
// a virtual machine whose page faults are dear those faults are most of its system time: with huge
// pages, a quarter to two fifths less of it (the sample 7.2-7.9 -> 4.8-5.0 s, fast speech 0.83-0.97
// -> 0.68-0.74 s) and fast speech's CPU 10% less, the same bytes, the same peak memory
// (spec/method.md §3.3, *Huge pages*). Returns (doing nothing) where GLIBC_TUNABLES already names the
// setting (this process was started so, or the user chose), FACEMORPH_HUGE_PAGES=0 is set, the
// kernel says otherwise, or the exec fails. Called first thing by the encoding tools (fmenc,
// fmbench); a library must not start its caller again. (Under valgrind, which runs an exec'd
// process outside itself, set FACEMORPH_HUGE_PAGES=0.)
void start_with_huge_pages(char** argv);

// "0x" and 16 hex digits.
std::string hex64(uint64_t value);

// "10%" or "0.1" -> 0.1: a fraction given either way, in (0, 1]; kInvalidArgument naming `what` for
// anything else. The one parser of --keyframes, --max-error and --field-error, so fmenc and fmbench
// read them alike (the bench's own took any positive number: --keyframes 2 meant 200% there).
double parse_fraction(const std::string& text, const char* what);

// "65" -> 65: the whole text a base-10 whole number in [low, high], else kInvalidArgument naming
// `what` ("--grid '65x' is neither auto nor a whole number from 5 to 4097"): std::stoi alone reads
// "65x" as 65 and "1e3" as 1. It parses fmenc's --grid, --quality, --texture and --intra-period and
// fmbench temporal's --grid (fmbench's other counts are CLI11's own); "auto" is the caller's to test
// first.
int parse_whole_number(const std::string& text, const char* what, long low, long high);

// The one clock reading of the encoder's reports too (codec/core/util/elapsed.hpp).
using facemorph::seconds_since;

// The decoder's limits as options (--max-memory 512M, --max-grid, --max-keyframes, --max-texture):
// what a file may make the tool allocate (spec/container.md §10). parsed_limits gives them after
// parsing.
void add_limit_options(CLI::App& app, DecoderLimits& limits, std::string& max_memory);
// `limits` with --max-memory's text ("536870912", "512M", "2G": bytes or binary K/M/G) applied;
// kInvalidArgument naming the option for anything else.
DecoderLimits parsed_limits(DecoderLimits limits, const std::string& max_memory);

// Frames in [begin, end] at `fps` (plus `slack` of a frame, for rounded rates), range-checked
// before the cast: kInvalidArgument for a rate or range that is not finite and positive, or more
// than 10⁸ frames (1e300 s at 30 fps was undefined behaviour in the cast to int).
int frame_count(double begin, double end, double fps, double slack);

// Writes `doc` (indented) to `path` atomically, or to stdout when `path` is "-".
void write_json(const std::string& path, const nlohmann::json& doc);

}  // namespace facemorph::tools
