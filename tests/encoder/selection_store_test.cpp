// The selection's samples spilled and read back through a bounded cache: the same floats, at most
// the cache's frames held, and a selection on them that is the one made in memory.
#include "codec/encoder/encode/selection_store.hpp"

#include "format/error.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace facemorph {
namespace {

// Frames of a bump that grows and shrinks, on `nodes` nodes: something for the selection to rank.
std::vector<SelectionFrame> moving_frames(int count, int nodes) {
  std::mt19937 random(3);
  std::normal_distribution<float> noise(0, 1e-4f);
  std::vector<SelectionFrame> frames(static_cast<size_t>(count));
  for (int k = 0; k < count; ++k) {
    SelectionFrame& f = frames[static_cast<size_t>(k)];
    f.time = k / 30.0;
    f.diagonal = 2;
    for (int v = 0; v < nodes; ++v) {
      const float x = -1 + 2.0f * static_cast<float>(v) / static_cast<float>(nodes - 1);
      f.local.emplace_back(x, 0.0f, 0.1f * std::sin(0.2f * static_cast<float>(k)) * std::exp(-4 * x * x) + noise(random));
      f.normal.emplace_back(0.0f, 0.0f, 1.0f);
    }
  }
  return frames;
}

std::vector<SelectionFrame> outlines_of(const std::vector<SelectionFrame>& frames) {
  std::vector<SelectionFrame> outlines = frames;
  for (SelectionFrame& f : outlines) f.local = f.normal = {};
  return outlines;
}

TEST(SelectionStore, ReadsBackTheSameFloatsHoldingNoMoreThanItsCache) {
  const std::vector<SelectionFrame> frames = moving_frames(40, 50);
  const std::vector<SelectionFrame> outlines = outlines_of(frames);
  const uint64_t frame_bytes = 2 * (8 + 50 * 12);
  SelectionStore store(outlines, SpillMode::kSpill, 3 * frame_bytes);  // three frames' worth
  for (size_t i = 0; i < frames.size(); ++i) store.put(i, std::vector(frames[i].local), std::vector(frames[i].normal));
  EXPECT_EQ(store.spilled_bytes(), frames.size() * frame_bytes);
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = 0; i < frames.size(); ++i) {
      const std::shared_ptr<const SelectionFrame> f = store.sampled(i);
      EXPECT_EQ(f->time, frames[i].time);
      EXPECT_EQ(f->diagonal, frames[i].diagonal);
      ASSERT_EQ(f->local.size(), frames[i].local.size());
      for (size_t v = 0; v < f->local.size(); ++v) {
        EXPECT_EQ(f->local[v], frames[i].local[v]);
        EXPECT_EQ(f->normal[v], frames[i].normal[v]);
      }
    }
  }
  EXPECT_LE(store.peak_held(), 4) << "the cache's three and the one in use";
  EXPECT_EQ(store.reads(), 2 * frames.size()) << "a pass longer than the cache misses every frame";
  // A window within the cache is read once.
  const uint64_t before = store.reads();
  for (int repeat = 0; repeat < 5; ++repeat) {
    for (size_t i = 10; i < 13; ++i) store.sampled(i);
  }
  EXPECT_EQ(store.reads() - before, 3u);
  testing::expect_error(ErrorCode::kInternal, "past its size", [&] { store.put(frames.size(), {}, {}); });
  SelectionStore empty(outlines, SpillMode::kSpill, frame_bytes);
  testing::expect_error(ErrorCode::kInternal, "never stored", [&] { empty.sampled(0); });
}

TEST(SelectionStore, TheSelectionOnSpilledSamplesIsTheOneInMemory) {
  const std::vector<SelectionFrame> frames = moving_frames(90, 80);
  const std::vector<SelectionFrame> outlines = outlines_of(frames);
  const std::vector<double> weights(80, 1.0);
  for (const SpillMode mode : {SpillMode::kSpill, SpillMode::kMemory}) {
    SelectionStore store(outlines, mode, 20 * 2 * (8 + 80 * 12));
    for (size_t i = 0; i < frames.size(); ++i) store.put(i, std::vector(frames[i].local), std::vector(frames[i].normal));
    SelectionOptions options;
    options.fraction = 0.1;
    const KeyframeSelection in_memory = select_keyframes(frames, weights, options), stored = select_keyframes(store, weights, options);
    EXPECT_EQ(stored.keyframes, in_memory.keyframes);
    EXPECT_EQ(stored.predicted_error, in_memory.predicted_error);
    if (mode == SpillMode::kSpill) {
      EXPECT_LE(store.peak_held(), 21);
    } else {
      EXPECT_EQ(store.peak_held(), static_cast<int>(frames.size())) << "in memory: every frame";
    }
  }
}

}  // namespace
}  // namespace facemorph
