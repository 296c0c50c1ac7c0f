#include "codec/core/util/parallel.hpp"
#include "format/error.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace facemorph {
namespace {

TEST(ParallelFor, RunsEveryItemExactlyOnceAndReportsProgress) {
  std::vector<std::atomic<int>> hits(1000);
  int last_done = 0, calls = 0;
  parallel_for(
      1000, 4, [&](int i) { ++hits[static_cast<size_t>(i)]; },
      [&](int done, int total) {
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
  // Items take a millisecond, so when item 17 fails (after ~6 ms on 3 threads) most of the 200
  // have not been handed out yet; with instant items the others could finish them all first.
  EXPECT_THROW(parallel_for(200, 3,
                            [&](int i) {
                              ++ran;
                              std::this_thread::sleep_for(std::chrono::milliseconds(1));
                              if (i == 17) throw Error(ErrorCode::kIo, "frame 17 failed");
                            }),
               Error);
  EXPECT_LT(ran.load(), 100);  // the hand-out stopped early
  parallel_for(0, 2, [](int) { FAIL(); });
}

}  // namespace
}  // namespace facemorph
