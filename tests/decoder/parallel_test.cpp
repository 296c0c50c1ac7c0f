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

// Item 4 fails at once and item 3 a while later: the error that comes back is item 3's, as a loop
// over the items in order would throw, not the first in time (which named a different frame from
// run to run). Rethrowing the first failure in time fails here.
TEST(ParallelFor, TheLowestFailingItemsErrorIsRethrownWhicheverFailsFirst) {
  for (const int threads : {1, 2, 3, 8}) {
    SCOPED_TRACE(::testing::Message() << threads << " threads");
    try {
      parallel_for(50, threads, [&](int i) {
        if (i == 3) {
          std::this_thread::sleep_for(std::chrono::milliseconds(30));
          throw Error(ErrorCode::kIo, "frame 3 failed");
        }
        if (i == 4) throw Error(ErrorCode::kNumerical, "frame 4 failed");
      });
      ADD_FAILURE() << "nothing thrown";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kIo);
      EXPECT_STREQ(e.what(), "frame 3 failed");
    }
  }
}

}  // namespace
}  // namespace facemorph
