#include "codec/core/util/parallel.hpp"
#include "format/error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <utility>
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

// A count asked for is kept; 0 or less is one per hardware thread, never none.
TEST(ParallelFor, ResolvedThreadsKeepsACountAndMakesZeroOnePerHardwareThread) {
  EXPECT_EQ(resolved_threads(1), 1);
  EXPECT_EQ(resolved_threads(7), 7);
  const int hardware = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(resolved_threads(0), hardware);
  EXPECT_EQ(resolved_threads(-2), hardware);
}

// The runs cover [0, count) once, in order (run r ends where run r + 1 starts), none empty, at
// most `threads` of them and as many as that where the items allow; none for no items.
TEST(ParallelRuns, CutTheItemsIntoConsecutiveRunsOnePerThread) {
  for (const size_t count : {size_t{1}, size_t{2}, size_t{7}, size_t{1000}}) {
    for (const int threads : {1, 2, 3, 8}) {
      SCOPED_TRACE(::testing::Message() << count << " items, " << threads << " threads");
      std::vector<std::pair<size_t, size_t>> runs(static_cast<size_t>(threads), {0, 0});
      std::vector<std::atomic<int>> hits(count);
      std::atomic<int> called{0};
      parallel_runs(count, threads, [&](size_t run, size_t first, size_t last) {
        ++called;
        ASSERT_LT(run, runs.size());
        runs[run] = {first, last};
        for (size_t i = first; i < last; ++i) ++hits[i];
      });
      const size_t expected = std::min(count, static_cast<size_t>(threads));
      ASSERT_EQ(called.load(), static_cast<int>(expected));
      for (size_t r = 0; r < expected; ++r) {
        EXPECT_LT(runs[r].first, runs[r].second) << "run " << r << " is empty";
        EXPECT_EQ(runs[r].first, r == 0 ? 0 : runs[r - 1].second) << "run " << r;
      }
      EXPECT_EQ(runs[expected - 1].second, count);
      for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
    }
  }
  parallel_runs(0, 2, [](size_t, size_t, size_t) { FAIL(); });
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
