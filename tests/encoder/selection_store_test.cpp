// The selection's samples spilled and read back through a bounded cache: the same floats, at most
// the cache's frames held, and a selection on them that is the one made in memory. The sample
// stage's state around them (SelectionSamples): each frame's noise, kept for the keyframes when
// the samples are released.
#include "codec/encoder/encode/selection_store.hpp"
#include "codec/encoder/encode/selection_samples.hpp"

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

// The sample stage's state for 6 frames 1/30 s apart whose every node moves in a straight line
// (the cubic through a frame's four neighbours predicts it exactly), but frame 2, which stands
// `bump` off that line along z. The reference, frame 0, keeps its local vectors in its outline.
void fill_line_with_bump(SelectionSamples& samples, float bump) {
  samples.start(6, SpillMode::kMemory);
  const size_t nodes = samples.weights().size();
  for (size_t k = 0; k < 6; ++k) {
    SelectionFrame& outline = samples.outline(k);
    outline.time = static_cast<double>(k) / 30;
    outline.diagonal = 1;
    std::vector<Eigen::Vector3f> local(nodes), normal(nodes, Eigen::Vector3f(0, 0, 1));
    for (size_t v = 0; v < nodes; ++v)
      local[v] = Eigen::Vector3f(0.001f * static_cast<float>(v % 7), 0.01f * static_cast<float>(k), k == 2 ? bump : 0.0f);
    if (k == 0) outline.local = local;
    samples.put(k, std::move(local), std::move(normal));
  }
}

TEST(SelectionSamples, TheNoiseIsWhatTheNeighboursCubicLeavesAndTheKeyframesKeepIt) {
  SelectionSamples samples;
  const float bump = 0.003f;
  fill_line_with_bump(samples, bump);
  ASSERT_EQ(samples.weights().size(), static_cast<size_t>(make_disk_grid(SelectionSamples::kGrid).interior_count));
  // Frame 2 against the cubic through frames 0, 1, 3, 4 (Lagrange weights -1/6, 2/3, 2/3, -1/6):
  // the bump over the stencil's noise gain √(1 + Σw²) = √(35/18). Frame 5 against the cubic through
  // 1 to 4 (weights -1, 4, -6, 4): frame 2's bump seen 4 times over, over √70.
  EXPECT_NEAR(samples.noise_at(2), bump / std::sqrt(35.0 / 18), 1e-6);
  EXPECT_NEAR(samples.noise_at(5), 4 * bump / std::sqrt(70.0), 1e-6);
  EXPECT_NEAR(samples.centre(0).y(), 0.0, 1e-12);  // the reference's centroid, from its outline
  const double before = samples.noise_at(2);
  const std::optional<SelectionSamples::StoreFigures> figures = samples.release({0, 2, 5});
  ASSERT_TRUE(figures.has_value());
  EXPECT_GE(figures->peak_held, 1);
  EXPECT_EQ(figures->spilled_bytes, 0u);  // kMemory
  // Released: the keyframes' noise as it was, the outlines and the reference's centre still there,
  // the samples and any other frame's noise a named internal error.
  EXPECT_FALSE(samples.sampled());
  EXPECT_DOUBLE_EQ(samples.noise_at(2), before);
  EXPECT_EQ(samples.frames().size(), 6u);
  EXPECT_NEAR(samples.centre(0).y(), 0.0, 1e-12);
  try {
    samples.noise_at(3);
    ADD_FAILURE() << "frame 3's noise after release";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInternal);
    EXPECT_NE(std::string(e.what()).find("frame 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(samples.samples(), Error);
  EXPECT_THROW(samples.frame(0), Error);
  EXPECT_FALSE(samples.release({}).has_value());  // nothing left to free
  // Sampled again: every frame's noise from the new samples.
  fill_line_with_bump(samples, 0);
  EXPECT_NEAR(samples.noise_at(3), 0.0, 1e-6);
}

}  // namespace
}  // namespace facemorph
