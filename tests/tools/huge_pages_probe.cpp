// What tools::start_with_huge_pages leaves a process with (tests/tools/huge_pages_test.sh): it is
// called first, as fmenc calls it; then 64 MiB are allocated and written, and the process prints its
// GLIBC_TUNABLES and the anonymous memory the kernel backs with huge pages (/proc/self/smaps_rollup's
// AnonHugePages, kB): glibc's setting took where that memory is in huge pages.
#include "tools/tool_support.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

int main(int, char** argv) {
  facemorph::tools::start_with_huge_pages(argv);
  constexpr size_t kBytes = size_t{64} << 20;
  auto* block = static_cast<char*>(std::malloc(kBytes));
  if (block == nullptr) return 1;
  std::memset(block, 1, kBytes);
  long huge_kb = -1;
  std::ifstream rollup("/proc/self/smaps_rollup");
  for (std::string line; std::getline(rollup, line);) {
    if (line.rfind("AnonHugePages:", 0) == 0) huge_kb = std::atol(line.c_str() + std::strlen("AnonHugePages:"));
  }
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  std::printf("%s %ld %d\n", tunables != nullptr ? tunables : "-", huge_kb, block[kBytes - 1]);
  std::free(block);
  return 0;
}
