#include "facemorph/error.hpp"
#include "facemorph/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <vector>

namespace facemorph {
namespace {

TEST(ParallelFor, RunsEveryItemExactlyOnceAndReportsProgress) {
  std::vector<std::atomic<int>> hits(1000);
  int last_done = 0, calls = 0;
  parallel_for(1000, 4, [&](int i) { ++hits[static_cast<size_t>(i)]; }, [&](int done, int total) {
    EXPECT_EQ(total, 1000);
    EXPECT_GE(done, last_done);
    last_done = done;
    ++calls;
  });
  for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
  EXPECT_EQ(last_done, 1000);
  EXPECT_GT(calls, 0);
}

TEST(ParallelFor, TheFirstFailureIsRethrownAfterAllThreadsStop) {
  std::atomic<int> ran{0};
  EXPECT_THROW(parallel_for(200, 3, [&](int i) {
                 ++ran;
                 if (i == 17) throw Error(ErrorCode::kIo, "frame 17 failed");
               }),
               Error);
  EXPECT_LT(ran.load(), 200);  // the hand-out stopped early
  parallel_for(0, 2, [](int) { FAIL(); });
}

}  // namespace
}  // namespace facemorph
