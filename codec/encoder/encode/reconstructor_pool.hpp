// Reconstructors on one G shared by the threads of a field-precision search (field_precision.cpp):
// each item of a run takes a free one, decodes with it, and gives it back.
#pragma once

#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/util/parallel.hpp"

#include <memory>
#include <mutex>
#include <vector>

namespace facemorph {

// One reconstructor per thread, on one G. Each decode here starts from a surface of its own (the
// harmonic one for an exact decode, the exact surface for a rounded one), never from a warm start,
// so which reconstructor takes a keyframe changes nothing.
class ReconstructorPool {
 public:
  ReconstructorPool(int grid_n, int threads) : geometry_(shared_grid_geometry(grid_n)) {
    const int count = resolved_threads(threads);
    // Made side by side (each builds its multigrid): one after another they were a serial stretch
    // of every candidate's rounding in the choice by bytes.
    free_.resize(static_cast<size_t>(count));
    parallel_for(count, count, [&](int t) { free_[static_cast<size_t>(t)] = std::make_unique<Reconstructor>(geometry_); });
    size_ = free_.size();
  }
  size_t size() const { return size_; }
  const DiskGrid& grid() const { return geometry_->grid(); }

  // body(reconstructor, i) for every i in [0, count), on up to size() threads.
  template <typename Body>
  void run(size_t count, const Body& body) {
    parallel_for(static_cast<int>(count), static_cast<int>(size_), [&](int i) {
      std::unique_ptr<Reconstructor> mine = take();
      try {
        body(*mine, static_cast<size_t>(i));
      } catch (...) {
        give_back(std::move(mine));
        throw;
      }
      give_back(std::move(mine));
    });
  }

 private:
  std::unique_ptr<Reconstructor> take() {
    std::lock_guard lock(mutex_);
    std::unique_ptr<Reconstructor> r = std::move(free_.back());
    free_.pop_back();
    return r;
  }
  void give_back(std::unique_ptr<Reconstructor> r) {
    std::lock_guard lock(mutex_);
    free_.push_back(std::move(r));
  }

  std::shared_ptr<const GridGeometry> geometry_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<Reconstructor>> free_;
  size_t size_ = 0;
};

}  // namespace facemorph
