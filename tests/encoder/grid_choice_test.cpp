// --grid auto's two bounds beside the RMS target (spec/method.md §7.6): a grid no finer than the
// captured mesh's density asks, and a worst region (99th percentile, resampled and decoded) that
// leaves room for the 1% worst-region target; and the third term where nothing is predicted.
#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/stages/choose_grid.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <vector>

namespace facemorph {
namespace {

// A floor that falls as 1/N² from its values at N = 33, as resampling floors do (§7.6), on a capture
// whose frames all read `noise` (the RMS target then is the noise).
GridChoiceInput grid_input_falling_from(double rms_at_33, double p99_at_33, double noise, double vertex_area) {
  GridChoiceInput input;
  input.noise.assign(12, noise);
  input.vertex_disk_area = vertex_area;
  input.floor = [=](int n) {
    const double shrink = (33.0 * 33.0) / (double(n) * double(n));
    return GridFloor{.rms = rms_at_33 * shrink, .p99 = p99_at_33 * shrink};
  };
  return input;
}

// G's nodes within one vertex's area of the disk at size n.
double grid_nodes_in_vertex_area(double vertex_area, int n) {
  const double h = 2.0 / (n - 1);
  return vertex_area / (h * h);
}

TEST(GridChoice, TheWorstRegionRaisesTheGridWhereTheFloorsNinetyNinthPercentileIsHigh) {
  // The RMS target (0.1% noise) is met at N = 33 already (0.05%).
  const GridChoice calm = choose_grid_size(grid_input_falling_from(5e-4, 4e-3, 1e-3, 0));
  EXPECT_EQ(calm.n, 33);
  EXPECT_EQ(calm.term, "noise");
  // The same RMS with a 2% worst region at N = 33: within 0.75% from (33/N)² <= 3/8, N >= 54, so 57.
  const GridChoice rough = choose_grid_size(grid_input_falling_from(5e-4, 2e-2, 1e-3, 0));
  EXPECT_EQ(rough.n, 57);
  EXPECT_EQ(rough.term, "worst region");
  ASSERT_EQ(rough.floor_p99s.size(), rough.floors.size());
  EXPECT_DOUBLE_EQ(rough.worst_target, 0.0075);
  EXPECT_LE(rough.floor_p99s.back().second, 0.0075);
  for (size_t i = 0; i + 1 < rough.floor_p99s.size(); ++i) EXPECT_GT(rough.floor_p99s[i].second, 0.0075);
  // Past the density cap as well: the worst region is a bound, not a trade (vertices of π/2000 of
  // the disk cap the RMS terms at 81; a 20% worst region at 33 needs (33/N)² <= 3/80, N >= 171).
  const GridChoice capped = choose_grid_size(grid_input_falling_from(1.0, 0.2, 1e-3, std::numbers::pi / 2000));
  EXPECT_EQ(capped.density_cap, 81);
  EXPECT_EQ(capped.n, 193);
  EXPECT_EQ(capped.term, "worst region");
}

// The rungs between the old ladder's wide steps (97 → 129 → 193 → 257: 1.8-2.2x the nodes) are
// each taken where the worst region's floor meets its 0.75% share there and not at the rung below.
TEST(GridChoice, EachNewRungIsTakenWhereItsFloorMeetsTheShareAndTheNextCoarserDoesNot) {
  const std::span<const int> ladder = grid_ladder();
  for (const int rung : {113, 161, 225}) {
    SCOPED_TRACE(rung);
    const auto at = std::find(ladder.begin(), ladder.end(), rung);
    ASSERT_NE(at, ladder.end());
    ASSERT_NE(at, ladder.begin());
    const int below = *(at - 1);
    // A p99 falling as 1/N² that is 0.75% just past the geometric middle of `below` and `rung`
    // (so it misses the share at `below` and meets it at `rung`), with the RMS met at N = 33.
    const double crossing = std::sqrt(double(below) * double(rung)) + 0.5;
    const double p99_at_33 = kGridWorstTarget * crossing * crossing / (33.0 * 33.0);
    const GridChoice choice = choose_grid_size(grid_input_falling_from(5e-4, p99_at_33, 1e-3, 0));
    EXPECT_EQ(choice.n, rung);
    EXPECT_EQ(choice.term, "worst region");
    ASSERT_GE(choice.floor_p99s.size(), 2u);
    EXPECT_GT(choice.floor_p99s.end()[-2].second, kGridWorstTarget);
    EXPECT_EQ(choice.floor_p99s.end()[-2].first, below);
    EXPECT_LE(choice.floor_p99s.back().second, kGridWorstTarget);
  }
  // No step between neighbours above 1.25 in N past 65 (at most ~1.6x the nodes).
  for (size_t i = 1; i < ladder.size(); ++i) {
    if (ladder[i - 1] >= 65) {
      EXPECT_LE(double(ladder[i]) / ladder[i - 1], 1.25) << ladder[i];
    }
  }
}

TEST(GridChoice, TheWorstRegionIsReadThroughTheReconstruction) {
  // A resampling floor that meets both targets at N = 33 (RMS 0.05%, p99 0.4%), and a reference that
  // decodes far from it below N = 65 (p99 4%, as a second solution of the equations would) and
  // does not reconstruct at 49: the decoded floor sets N, 65.
  GridChoiceInput input = grid_input_falling_from(5e-4, 4e-3, 1e-3, 0);
  std::vector<int> decoded_at;
  input.decoded = [&](int n) {
    decoded_at.push_back(n);
    if (n == 49) return GridFloor{.rms = std::numeric_limits<double>::infinity(), .p99 = std::numeric_limits<double>::infinity()};
    return n < 65 ? GridFloor{.rms = 8e-3, .p99 = 4e-2} : GridFloor{.rms = 4e-4, .p99 = 3e-3};
  };
  const GridChoice choice = choose_grid_size(input);
  EXPECT_EQ(choice.n, 65);
  EXPECT_EQ(choice.term, "worst region");
  // Measured from the coarse end, stopping where it is met.
  EXPECT_EQ(decoded_at, (std::vector<int>{33, 41, 49, 57, 65}));
  ASSERT_EQ(choice.decoded.size(), 5u);
  EXPECT_EQ(choice.decoded.back().first, 65);
  EXPECT_DOUBLE_EQ(choice.decoded.back().second.p99, 3e-3);
  // The decoded floor is measured only from where the RMS terms are done: here the 0.1% noise, met
  // where 0.8% (33/N)² <= 0.1%, N >= 93.3: 97, whose resampled p99 (4% (33/97)² = 0.46%) is within
  // 0.75% and whose decoded one (0.9%) is not, nor is 113's; 129 decodes within it.
  GridChoiceInput late = grid_input_falling_from(8e-3, 4e-2, 1e-3, 0);
  decoded_at.clear();
  late.decoded = [&](int n) {
    decoded_at.push_back(n);
    return GridFloor{.rms = 1e-3, .p99 = n < 129 ? 9e-3 : 5e-3};
  };
  const GridChoice raised = choose_grid_size(late);
  EXPECT_EQ(raised.n, 129);
  EXPECT_EQ(raised.term, "worst region");
  EXPECT_EQ(decoded_at, (std::vector<int>{97, 113, 129}));
  // Decoded within the bound while the resampled p99 is not: the resampled one still holds N up
  // (a keyframe stored as positions decodes as sampled). 4% (33/N)² <= 0.75%: N >= 76.2, 81.
  GridChoiceInput sampled = grid_input_falling_from(5e-4, 4e-2, 1e-3, 0);
  sampled.decoded = [](int) { return GridFloor{.rms = 1e-4, .p99 = 1e-3}; };
  EXPECT_EQ(choose_grid_size(sampled).n, 81);
}

TEST(GridChoice, WhereNothingIsPredictedTheErrorBoundTakesThePredictionsPlace) {
  // One frame: no noise estimate (infinite), no predicted error. A floor of 0.5% at N = 33 meets
  // ½ B = 0.25% where (33/N)² <= 1/2, N >= 46.7: 49, named after the bound.
  GridChoiceInput single = grid_input_falling_from(5e-3, 1e-3, std::numeric_limits<double>::infinity(), 0);
  single.error_bound = 0.005;
  const GridChoice bounded = choose_grid_size(single);
  EXPECT_EQ(bounded.n, 49);
  EXPECT_DOUBLE_EQ(bounded.target, 0.0025);
  EXPECT_EQ(bounded.term, "error bound");
  // A predicted error replaces the bound (0.4%: a target of 0.2%, (33/N)² <= 2/5, N >= 52.2: 57).
  single.mean_predicted_error = 0.004;
  const GridChoice predicted = choose_grid_size(single);
  EXPECT_EQ(predicted.n, 57);
  EXPECT_EQ(predicted.term, "interpolation");
  // Neither (no keyframes chosen): the fixed 0.02%, (33/N)² <= 1/25, N >= 165: 193.
  single.mean_predicted_error = 0;
  single.error_bound = 0;
  const GridChoice fixed = choose_grid_size(single);
  EXPECT_EQ(fixed.n, 193);
  EXPECT_DOUBLE_EQ(fixed.target, 2e-4);
  EXPECT_EQ(fixed.term, "floor");
  // The worst region, decoded, still bounds the bound's N: a decoded p99 of 2% at 33 falling as
  // 1/N² needs N >= 54 (57), past the 49 ½ B asks.
  GridChoiceInput rough = grid_input_falling_from(5e-3, 1e-3, std::numeric_limits<double>::infinity(), 0);
  rough.error_bound = 0.005;
  rough.decoded = [](int n) { return GridFloor{.rms = 5e-3, .p99 = 2e-2 * (33.0 * 33.0) / (double(n) * double(n))}; };
  const GridChoice worst = choose_grid_size(rough);
  EXPECT_EQ(worst.n, 57);
  EXPECT_EQ(worst.term, "worst region");
}

TEST(GridChoice, TheDensityCapFollowsTheVertexArea) {
  // A capture of V vertices spread evenly over the disk: each holds π/V of it (and so does its
  // lower quartile).
  for (const int vertices : {500, 2000, 9400, 20000}) {
    const double area = std::numbers::pi / vertices;
    const int cap = density_grid_cap(area);
    SCOPED_TRACE(vertices);
    if (cap > 33) {
      EXPECT_LE(grid_nodes_in_vertex_area(area, cap), 3.0);
    }
    // The next candidate would put more than 3 nodes in a vertex's area.
    for (int n : grid_ladder()) {
      if (n > cap) {
        EXPECT_GT(grid_nodes_in_vertex_area(area, n), 3.0) << n;
        break;
      }
    }
    // A floor that never meets the RMS target stops at the cap, named as the density's.
    const GridChoice choice = choose_grid_size(grid_input_falling_from(1.0, 0.0, 1e-3, area));
    EXPECT_EQ(choice.n, cap);
    EXPECT_EQ(choice.term, "density");
    EXPECT_EQ(choice.floors.back().first, cap);
  }
  EXPECT_EQ(density_grid_cap(std::numbers::pi / 2000), 81);
  EXPECT_EQ(density_grid_cap(std::numbers::pi / 500), 41);
  EXPECT_EQ(density_grid_cap(0), 257);  // no area measured: no cap
}

TEST(GridChoice, QuartileVertexDiskAreaOfTwoTriangles) {
  // Two triangles of the unit square [0,1]²: 4 vertices; the two on the diagonal touch both
  // triangles (area 1/2 each: a third of 1), the other two one (a sixth): the lower quartile, a sixth.
  const std::vector<Vec2> disk = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  const std::vector<Face> faces = {Face{0, 1, 2}, Face{0, 2, 3}};
  EXPECT_NEAR(quartile_vertex_disk_area(disk, faces), 1.0 / 6.0, 1e-12);
  EXPECT_EQ(quartile_vertex_disk_area({}, {}), 0.0);
}

// End to end: a clean capture of ~800 vertices, too short for a noise estimate (4 frames) and no
// keyframes chosen, asks for the fixed 0.02% floor, which its own facets keep out of reach until
// N = 257; the cap holds G to the mesh's density.
TEST(GridChoice, ALowVertexCaptureGetsAGridSizedToItsMesh) {
  testing::TempDir dir;
  write_synthetic_capture(dir.path(), {.frames = 4, .vertices = 800, .remesh = true, .noise = 0, .texture_size = 64});
  const Capture capture = read_capture(dir.path());
  EncodeOptions options;
  options.texture = false;
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const int n = choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report());
  const EncodeReport& report = encoder.report();
  ASSERT_GT(report.grid_vertex_area, 0);
  EXPECT_EQ(report.grid_density_cap, density_grid_cap(report.grid_vertex_area));
  EXPECT_LE(report.grid_density_cap, 97);  // an 800-vertex face: far below the 257 the floor alone asks
  ASSERT_FALSE(report.grid_floors.empty());
  EXPECT_EQ(report.grid_term, "density");
  EXPECT_EQ(n, report.grid_density_cap);
  EXPECT_LE(grid_nodes_in_vertex_area(report.grid_vertex_area, n), 3.0);
  EXPECT_GT(report.grid_floors.back().second, report.grid_target);  // the floor alone would go on
  EXPECT_LE(report.grid_floor_p99s.back().second, report.grid_worst_target);
}

}  // namespace
}  // namespace facemorph
