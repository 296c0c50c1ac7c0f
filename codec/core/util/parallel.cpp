#include "codec/core/util/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace facemorph {

int resolved_threads(int threads) {
  return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

void parallel_for(int count, int threads, const std::function<void(int)>& body, const std::function<void(int, int)>& progress) {
  if (count <= 0) return;
  threads = std::min(resolved_threads(threads), count);
  std::atomic<int> next{0}, done{0};
  // The failure of the lowest item, not the first in time: items are handed out in order, so every
  // item below a failing one was handed out before it and runs to its end, and the lowest failure
  // kept is the one a loop over the items in order would have met first, on any thread count.
  std::exception_ptr failure;
  int failed_item = count;
  std::mutex failure_mutex;
  auto run = [&](int i) {
    try {
      body(i);
    } catch (...) {
      std::lock_guard lock(failure_mutex);
      if (i < failed_item) {
        failure = std::current_exception();
        failed_item = i;
      }
      next = count;  // stop handing out work
    }
    ++done;
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) {
    pool.emplace_back([&] {
      for (int i = next++; i < count; i = next++) run(i);
    });
  }
  for (int i = next++; i < count; i = next++) {
    run(i);
    if (progress) progress(std::min(done.load(), count), count);
  }
  for (auto& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  if (progress) progress(count, count);
}

void parallel_runs(size_t count, int threads, const std::function<void(size_t, size_t, size_t)>& body) {
  if (count == 0) return;
  const size_t runs = std::min(static_cast<size_t>(resolved_threads(threads)), count);
  parallel_for(static_cast<int>(runs), static_cast<int>(runs), [&](int r) {
    const auto run = static_cast<size_t>(r);
    body(run, run * count / runs, (run + 1) * count / runs);
  });
}

}  // namespace facemorph
