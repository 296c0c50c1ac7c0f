// Parallel work over independent items (frames), the way every facemorph stage uses it.
#pragma once

#include <functional>

namespace facemorph {

// `threads` as every facemorph option reads it: that many, or for 0 (or less) one per hardware thread.
int resolved_threads(int threads);

// Runs body(i) for every i in [0, count) on up to `threads` threads (0: one per hardware thread).
// The calling thread takes part and, between its items, calls progress(done, count). The first
// exception stops handing out items; once every thread has finished, the exception of the lowest
// item that threw is rethrown: the one a loop over the items in order would throw, on any threads.
void parallel_for(int count, int threads, const std::function<void(int)>& body, const std::function<void(int, int)>& progress = {});

// [0, count) cut into up to `threads` runs of consecutive items (0: one per hardware thread), none
// empty, run r before run r + 1, and body(r, first, last) for each run side by side: for work that
// is cheapest done in order within a run (a search that starts where the previous item's ended, a
// decoder that moves forward in time). Failures as parallel_for's (the lowest run's).
void parallel_runs(size_t count, int threads, const std::function<void(size_t, size_t, size_t)>& body);

}  // namespace facemorph
