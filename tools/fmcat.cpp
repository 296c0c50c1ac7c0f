// fmcat: joins the segment files of one long encode into one .fmv, without decoding them
// (fmenc --stage assemble --segment S/N writes them; spec/method.md §7.17).
#include "codec/encoder/encode/segment_join.hpp"

#include "tools/tool_support.hpp"

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

using namespace facemorph;

int main(int argc, char** argv) {
  CLI::App app(
      "Join the segment files of one encode (fmenc --stage assemble --segment S/N) into one facemorph file, without decoding them.",
      "fmcat");
  std::vector<std::string> segments;
  std::string output;
  bool quiet = false, check = false;
  app.add_option("segments", segments, "The segment files, every one of the encode's, in any order")->required();
  app.add_option("-o,--output", output, "The .fmv file to write")->required();
  app.add_flag("--check", check, "Decode every segment's keyframes and textures first, as fminfo does (the join itself decodes nothing)");
  app.add_flag("-q,--quiet", quiet, "No summary");
  return tools::guarded_main(app, argc, argv, [&] {
    const auto start = std::chrono::steady_clock::now();
    const JoinReport report = join_segment_files(std::vector<std::filesystem::path>(segments.begin(), segments.end()), output, check);
    if (!quiet) {
      std::printf("fmcat: %s: %d segments, %zu keyframes, %llu bytes, %.2f s\n", output.c_str(), report.segments, report.keyframes,
                  static_cast<unsigned long long>(report.bytes), tools::seconds_since(start));
    }
    return 0;
  });
}
