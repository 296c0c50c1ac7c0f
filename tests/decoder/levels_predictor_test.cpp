// Format 2.6's levels predictor (format/level_predictor.hpp, spec/container.md §7.2): a lattice array
// coded coarse to fine, each finer node from the rounded mean of decoded coarser ones. Its order and
// arithmetic against hand-worked values, its round trip on random and extreme codes, the writer's
// choice of it in a KGLV chunk, and what a file stamped 2.5 does with one.
#include "codec/core/container/file_layout.hpp"
#include "codec/core/container/keyframe_group_coding.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/level_predictor.hpp"
#include "format/ranged_residuals.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <random>

namespace facemorph {
namespace {

// A full w × w square lattice, row by row: its cells and index table.
struct Square {
  std::vector<std::array<int32_t, 2>> cells;
  std::vector<int32_t> index_at;
  explicit Square(int w) : index_at(static_cast<size_t>(w * w), -1) {
    for (int j = 0; j < w; ++j) {
      for (int i = 0; i < w; ++i) {
        index_at[static_cast<size_t>(j * w + i)] = static_cast<int32_t>(cells.size());
        cells.push_back({i, j});
      }
    }
  }
};

TEST(LevelsPredictor, TheCodingOrderIsCoarseFirstThenDiagonalsThenAxesAtEachSpacing) {
  const Square sq(9);
  const format::LevelOrder order = format::level_order(sq.cells, sq.index_at, 9);
  const auto at = [](int i, int j) { return j * 9 + i; };
  // Every 8th row and column, row by row; then at spacing 4 the centre (odd both ways), then the
  // four nodes odd one way, row by row; then spacing 2, …
  const std::vector<int32_t> first = {at(0, 0), at(8, 0), at(0, 8), at(8, 8), at(4, 4), at(4, 0), at(0, 4), at(8, 4), at(4, 8),
                                      at(2, 2), at(6, 2), at(2, 6), at(6, 6)};
  ASSERT_EQ(order.size(), 81u);
  EXPECT_EQ(std::vector<int32_t>(order.element.begin(), order.element.begin() + 13), first);
  EXPECT_EQ(order.from[4], (std::array<int32_t, 4>{at(0, 0), at(8, 0), at(0, 8), at(8, 8)}));  // diagonals
  EXPECT_EQ(order.from[5], (std::array<int32_t, 4>{at(0, 0), at(8, 0), -1, at(4, 4)}));        // axes; none above row 0
  // The context: the same class at its spacing (coarse: 8; spacing s: 2s), in coding positions.
  EXPECT_EQ(order.context.left[1], 0);
  EXPECT_EQ(order.context.up[2], 0);
  EXPECT_EQ(order.context.left[7], 6);   // (8, 4)'s left at 8 is (0, 4), position 6
  EXPECT_EQ(order.context.up[8], 5);     // (4, 8)'s up at 8 is (4, 0), position 5
  EXPECT_EQ(order.context.left[10], 9);  // (6, 2) after (2, 2)
  EXPECT_EQ(order.context.up[4], -1);
  std::vector<int> seen(81, 0);
  for (int32_t e : order.element) ++seen[static_cast<size_t>(e)];
  EXPECT_EQ(seen, std::vector<int>(81, 1));
}

// d(i, j) = i² on a full 17 × 17 lattice, worked by hand: the mean of the four diagonals at ±s is
// i² + s², of the four axis neighbours i² + s²/2 (rounded half up: i² + 1 at s = 1), so a node with
// all four has residual −s² or −⌈s²/2⌉; the coarse lattice's gradient is exact on it; node (8, 0)
// has only its left neighbour (0, 0): 64 − 0; node (4, 0) has three axis neighbours, 0, 64 and
// (4, 4)'s 16: ⌊(2 · 80 + 3) / 6⌋ = 27, residual 16 − 27 = −11.
TEST(LevelsPredictor, ASquaredRampLeavesTheHandWorkedResiduals) {
  const int w = 17;
  const Square sq(w);
  const format::LevelOrder order = format::level_order(sq.cells, sq.index_at, w);
  std::vector<int32_t> codes;
  for (const auto& c : sq.cells) codes.push_back(c[0] * c[0]);
  const std::vector<int64_t> r = format::level_residuals(codes, order);
  std::vector<int64_t> by_element(codes.size());
  for (size_t k = 0; k < r.size(); ++k) by_element[static_cast<size_t>(order.element[k])] = r[k];
  const auto residual = [&](int i, int j) { return by_element[static_cast<size_t>(j * w + i)]; };
  EXPECT_EQ(residual(0, 0), 0);
  EXPECT_EQ(residual(8, 0), 64);
  EXPECT_EQ(residual(16, 0), 16 * 16 - 8 * 8);
  EXPECT_EQ(residual(8, 8), 0);
  EXPECT_EQ(residual(16, 16), 0);
  EXPECT_EQ(residual(4, 0), -11);
  size_t checked = 0;
  for (int s : {4, 2, 1}) {
    for (int j = s; j + s < w; j += s) {
      for (int i = s; i + s < w; i += s) {
        if (i % (2 * s) == 0 && j % (2 * s) == 0) continue;  // a coarser node
        const bool odd_i = (i / s) % 2 != 0, odd_j = (j / s) % 2 != 0;
        const int64_t expected = odd_i && odd_j ? -s * s : -((s * s + 1) / 2);
        ASSERT_EQ(residual(i, j), expected) << i << " " << j << " at spacing " << s;
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 200u);
  EXPECT_EQ(format::codes_from_level_residuals(r, order, "t"), codes);
}

// The mean rounds half up, negative sums floored, not truncated towards 0: the centre of a 9 × 9
// lattice from its four coarse corners.
TEST(LevelsPredictor, TheMeanRoundsHalfUpForNegativeSumsToo) {
  const Square sq(9);
  const format::LevelOrder order = format::level_order(sq.cells, sq.index_at, 9);
  std::vector<int32_t> codes(81, 0);
  codes[0] = -1;   // (0, 0)
  codes[8] = -2;   // (8, 0)
  codes[72] = 0;   // (0, 8)
  codes[80] = -3;  // (8, 8): sum −6, mean −1.5, half up −1
  codes[40] = 5;   // (4, 4)
  const std::vector<int64_t> r = format::level_residuals(codes, order);
  EXPECT_EQ(r[4], 5 - (-1));
  codes[80] = -5;  // sum −8 − 0: mean −2 exactly
  EXPECT_EQ(format::level_residuals(codes, order)[4], 5 - (-2));
  codes[80] = -4;  // sum −7: −1.75 rounds to −2 (truncating −7/4 would give −1)
  EXPECT_EQ(format::level_residuals(codes, order)[4], 5 - (-2));
}

// Property: random codes on G's interior lattice within ±100, ±(2^30 − 1) (a code's bound) and
// ±(2^31 − 2) (a change's), and neighbours alternating between the extremes, round-trip exactly with
// every residual within §7.3's 2^34.
TEST(LevelsPredictor, RandomAndExtremeCodesOnGsLatticeRoundTripExactly) {
  std::mt19937 rng(44);
  for (int n : {5, 17, 33, 65}) {
    const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(n);
    const format::LevelOrder& order = grid->interior_levels;
    ASSERT_EQ(order.size(), grid->interior.size());
    for (int trial = 0; trial < 12; ++trial) {
      std::vector<int32_t> codes(order.size());
      const int32_t bound = trial < 4 ? 100 : trial < 8 ? (1 << 30) - 1 : std::numeric_limits<int32_t>::max() - 1;
      std::uniform_int_distribution<int32_t> any(-bound, bound);
      for (size_t e = 0; e < codes.size(); ++e) codes[e] = any(rng);
      if (trial % 4 == 3) {
        for (size_t e = 0; e < codes.size(); ++e) codes[e] = e % 2 ? bound : -bound;  // the widest swing between neighbours
      }
      const std::vector<int64_t> r = format::level_residuals(codes, order);
      for (int64_t v : r) ASSERT_LE(std::abs(v), format::kMaxRangedResidual);
      ASSERT_EQ(format::codes_from_level_residuals(r, order, "t"), codes) << n << " " << trial;
    }
  }
}

// A residual that takes a code past 32 bits is the file's fault, named, never wrapped.
TEST(LevelsPredictor, AResidualPast32BitsIsCorruptNamingTheElement) {
  const Square sq(9);
  const format::LevelOrder order = format::level_order(sq.cells, sq.index_at, 9);
  std::vector<int64_t> r(81, 0);
  r[0] = std::numeric_limits<int32_t>::max();
  r[1] = 1;  // (8, 0) from (0, 0): 2^31
  testing::expect_error(ErrorCode::kCorrupt, "t: a field code outside 32 bits (levels predictor, element 8)",
                        [&] { format::codes_from_level_residuals(r, order, "t"); });
  r[1] = 0;
  r[4] = -(int64_t{1} << 34);  // the centre's mean (2^31 − 1) − 2^34
  testing::expect_error(ErrorCode::kCorrupt, "element 40", [&] { format::codes_from_level_residuals(r, order, "t"); });
}

TEST(LevelsPredictor, AnIndexTableThatDisagreesWithTheCellsIsRefused) {
  Square sq(9);
  sq.index_at[3] = 5;
  testing::expect_error(ErrorCode::kInvalidArgument, "a lattice cell its index table does not name",
                        [&] { format::level_order(sq.cells, sq.index_at, 9); });
}

// An xyz sequence on G at N = 129, a smooth warped surface whose codes (steps of 10⁻³, about 16 a
// node) carry their rounding noise, as a capture's do: the writer's choice for its positions is the
// levels predictor, in a KGLV chunk (at N = 33 and 65 it is not: too few nodes between the coarse ones).
Sequence warped_xyz_sequence(int n) {
  const GridGeometry geometry(make_disk_grid(n));
  Sequence s = crafted::small_sequence(n, 8);
  s.representation = Representation::kXYZ;
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    std::vector<Vec3> positions;
    for (const Vec2& w : geometry.grid().nodes)
      positions.push_back(Vec3(w.x() + 0.1 * std::sin(3 * w.y()), w.y() + 0.1 * std::cos(2 * w.x()), 0.3 * (w.x() * w.x() - 0.5 * w.y() * w.y())));
    s.keyframes[k].fields = compute_fields(geometry, positions, Representation::kXYZ);
  }
  return s;
}

SequenceFileMetadata xyz_metadata() {
  SequenceFileMetadata m = crafted::predicted_metadata();
  for (size_t a = 7; a <= 9; ++a) m.field_coding.steps[a] = 1e-3;
  return m;
}

TEST(LevelsPredictor, TheWriterChoosesItForWarpedPositionsAndTheFileRoundTripsExactly) {
  const Sequence s = warped_xyz_sequence(129);
  const SequenceFileMetadata m = xyz_metadata();
  const std::vector<uint8_t> bytes = encode_sequence_file(s, m);
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(bytes, "levels.fmv", &info);
  EXPECT_EQ(info.minor_version, 6);
  EXPECT_EQ(testing::chunk_count(info, "KGLV"), 2);  // both groups (intra period 2, three keyframes)
  EXPECT_EQ(testing::chunk_count(info, "KGOP"), 0);
  ASSERT_EQ(back.keyframes.size(), s.keyframes.size());
  for (size_t k = 0; k < s.keyframes.size(); ++k) {
    const std::vector<std::vector<double>> written = file_layout::keyframe_arrays(s.keyframes[k]);
    const std::vector<std::vector<double>> read = file_layout::keyframe_arrays(back.keyframes[k]);
    for (size_t a = 0; a < written.size(); ++a) {
      ASSERT_EQ(read[a].size(), written[a].size());
      for (size_t i = 0; i < read[a].size(); ++i) {
        const double step = m.field_coding.steps[a];
        ASSERT_EQ(read[a][i], step * file_layout::field_code(written[a][i], step)) << k << " " << a << " " << i;
      }
    }
  }
  // The same keyframes without the levels predictor (what a 2.5 writer writes): more bytes.
  const std::vector<uint8_t> older = crafted::with_minor_version(bytes, 5);
  EXPECT_LT(bytes.size(), older.size());
  SequenceFileInfo older_info;
  const Sequence same = decode_sequence_file(older, "older.fmv", &older_info);
  EXPECT_EQ(testing::chunk_count(older_info, "KGLV"), 0);
  for (size_t k = 0; k < s.keyframes.size(); ++k)
    EXPECT_EQ(file_layout::keyframe_arrays(same.keyframes[k]), file_layout::keyframe_arrays(back.keyframes[k])) << k;
}

// A 2.5 decoder refuses a KGLV chunk as critical and unknown (unsupported, by name); a 2.6 decoder
// refuses one in a file stamped 2.5 as corrupt, by name, before decoding anything from it.
TEST(LevelsPredictor, AKglvChunkInAFileStamped25IsCorruptByName) {
  const std::vector<uint8_t> bytes = encode_sequence_file(warped_xyz_sequence(129), xyz_metadata());
  testing::expect_error(ErrorCode::kCorrupt, "KGLV", [&] { decode_sequence_file(crafted::restamped(bytes, 5), "old.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "in a file stamped 2.5 (the levels predictor's group chunk is 2.6's)",
                        [&] { decode_sequence_file(crafted::restamped(bytes, 5), "old.fmv"); });
}

// A group written by hand: the positions' x under id 3 and the levels decision, its residuals those
// of codes d (the file's own plus a ripple of (i² + 3j) mod 5) by the predictor, in the coding
// order. The decoder must give exactly d: one that read the levels in another order, or from other
// neighbours, or took id 3 for median, decodes other codes.
TEST(LevelsPredictor, AHandWrittenKglvGroupDecodesToTheCodesItsResidualsSay) {
  constexpr size_t kX = 7;
  const Sequence s = warped_xyz_sequence(33);
  const std::vector<uint8_t> bytes = encode_sequence_file(s, xyz_metadata());
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(33);
  const DiskGrid g = make_disk_grid(33);
  std::vector<int32_t> d;
  const std::vector<double> written_x = file_layout::keyframe_arrays(s.keyframes[0])[kX];
  for (int e = 0; e < g.interior_count; ++e) {
    const auto [i, j] = g.cell[static_cast<size_t>(e)];
    d.push_back(file_layout::field_code(written_x[static_cast<size_t>(e)], 1e-3) + (i * i + 3 * j) % 5);
  }
  const auto hand = [&](uint8_t id, bool levels_chunk) {
    return crafted::with_first_group_by_hand(
        bytes, false,
        [&](crafted::HandCodedKeyframe& key) {
          key.ids[kX] = id;
          key.levels[kX] = levels_chunk ? 1 : 0;
          const std::vector<int64_t> r = format::level_residuals(d, grid->interior_levels);
          key.residuals[kX].assign(r.begin(), r.end());
        },
        levels_chunk);
  };
  const FieldCoding coding = xyz_metadata().field_coding;
  const auto x_codes = [&](const Keyframe& key) {
    const std::vector<std::vector<double>> arrays = file_layout::keyframe_arrays(key);
    std::vector<int32_t> out;
    for (double v : arrays[kX]) out.push_back(static_cast<int32_t>(std::llround(v / coding.steps[kX])));
    return out;
  };
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(hand(3, true), "hand.fmv", &info);
  EXPECT_EQ(testing::chunk_count(info, "KGLV"), 1);
  for (size_t k = 0; k < 2; ++k) EXPECT_EQ(x_codes(back.keyframes[k]), d) << k;
  // The same residuals under median (id 3 in a KGOP chunk, no levels decision) decode to other codes.
  const Sequence median = decode_sequence_file(hand(3, false), "median.fmv");
  EXPECT_NE(x_codes(median.keyframes[0]), d);
}


// The lattice's edge and its holes (review, helper-rev65): a neighbour off the table or missing is
// absent, never another row's node; a coarse node without its up-left neighbour is predicted by L,
// one without L by U; a node with none of its neighbours by the node coded just before it.
TEST(LevelsPredictor, TheEdgeAndHolesLeaveOnlyTheNeighboursThatExist) {
  const Square sq(9);
  const format::LevelOrder order = format::level_order(sq.cells, sq.index_at, 9);
  const auto at = [](int i, int j) { return j * 9 + i; };
  EXPECT_EQ(order.from[7], (std::array<int32_t, 4>{at(4, 4), -1, at(8, 0), at(8, 8)}));  // (8, 4): nothing right of column 8
  EXPECT_EQ(order.from[8], (std::array<int32_t, 4>{at(0, 8), at(8, 8), at(4, 4), -1}));  // (4, 8): nothing below row 8
  // A sparse lattice of width 9: (8, 0), (0, 8), (8, 8) coarse; (3, 3) fine with no diagonal neighbour.
  std::vector<std::array<int32_t, 2>> cells = {{8, 0}, {0, 8}, {3, 3}, {8, 8}};
  std::vector<int32_t> index_at(81, -1);
  for (size_t e = 0; e < cells.size(); ++e) index_at[static_cast<size_t>(cells[e][1] * 9 + cells[e][0])] = static_cast<int32_t>(e);
  const format::LevelOrder sparse = format::level_order(cells, index_at, 9);
  EXPECT_EQ(sparse.element, (std::vector<int32_t>{0, 1, 3, 2}));  // the coarse ones in array order, then (3, 3)
  const std::vector<int32_t> codes = {5, -7, 11, 40};
  // (8, 0): nothing coded before it: 0. (0, 8): no L, no U: the node before it, (8, 0). (8, 8): L and
  // U but no UL: L = (0, 8). (3, 3): no diagonal: the node before it in the coding order, (8, 8).
  EXPECT_EQ(format::level_residuals(codes, sparse), (std::vector<int64_t>{5, -7 - 5, 40 - (-7), 11 - 40}));
  EXPECT_EQ(format::codes_from_level_residuals(format::level_residuals(codes, sparse), sparse, "t"), codes);
  EXPECT_EQ(sparse.context.left[2], 1);  // (8, 8)'s left at 8 is (0, 8)
  EXPECT_EQ(sparse.context.up[2], 0);    // its up at 8 is (8, 0)
  EXPECT_EQ(sparse.context.left[3], -1);
}

// On G at N = 17 (its disk's edge: nodes with 1-3 of their four neighbours), a code at every coding
// position reaches int32's bounds exactly and is refused one past them, naming that element: the
// check is neither off by one nor skipped for any class of node.
TEST(LevelsPredictor, EveryCodingPositionIsRefusedOnePast32BitsAndNotBefore) {
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(17);
  const format::LevelOrder& order = grid->interior_levels;
  constexpr int64_t kTop = std::numeric_limits<int32_t>::max(), kBottom = std::numeric_limits<int32_t>::min();
  for (size_t k = 0; k < order.size(); ++k) {
    std::vector<int64_t> r(order.size(), 0);
    for (const int64_t edge : {kTop, kBottom}) {
      r[k] = edge;
      const std::vector<int32_t> codes = format::codes_from_level_residuals(r, order, "t");
      ASSERT_EQ(codes[static_cast<size_t>(order.element[k])], edge) << k;
      r[k] = edge + (edge > 0 ? 1 : -1);
      testing::expect_error(ErrorCode::kCorrupt, "(levels predictor, element " + std::to_string(order.element[k]) + ")",
                            [&] { format::codes_from_level_residuals(r, order, "t"); });
    }
  }
}


// `bytes` with `extra` appended after its last chunk (the index's offsets stay right), stamped 2.`minor`.
std::vector<uint8_t> with_chunk_appended(const std::vector<uint8_t>& bytes, const format::PreparedChunk& extra, uint16_t minor) {
  const format::ContainerReader reader(bytes, "in");
  format::ContainerWriter writer;
  for (const format::ChunkView& c : reader.chunks()) {
    writer.add(format::prepare_chunk(c.type, reader.payload(c), c.critical(), c.compressed() ? 19 : 0,
                                     c.against_dictionary() ? format::Dictionary::kHeader : format::Dictionary::kNone));
  }
  writer.add(extra);
  return crafted::restamped(writer.finish(), minor);
}

// A KGLV in a file stamped 2.5 is corrupt at open wherever it lies (spec/container.md §7), also one
// no index entry names: a 2.5 decoder refuses that file (critical, unknown), so a 2.6 decoder must
// not take it as a valid 2.5 file.
TEST(LevelsPredictor, AKglvChunkNoIndexEntryNamesInAFileStamped25IsCorrupt) {
  const std::vector<uint8_t> levels = encode_sequence_file(warped_xyz_sequence(129), xyz_metadata());
  const std::vector<uint8_t> older = crafted::with_minor_version(levels, 5);
  SequenceFileInfo info;
  decode_sequence_file(older, "older.fmv", &info);
  ASSERT_EQ(testing::chunk_count(info, "KGLV"), 0);
  const format::PreparedChunk stray = format::prepare_chunk("KGLV", crafted::chunk_payload(levels, "KGLV"), true);
  testing::expect_error(ErrorCode::kCorrupt, "in a file stamped 2.5 (the levels predictor's group chunk is 2.6's)",
                        [&] { decode_sequence_file(with_chunk_appended(older, stray, 5), "stray.fmv"); });
  // The same chunk in a file stamped 2.6 is no fault of the version (a chunk the index does not name, as a stray KGOP is).
  EXPECT_NO_THROW(decode_sequence_file(with_chunk_appended(older, stray, 6), "stray.fmv"));
}

// A KGLV's stream one byte short or one byte long, and a levels decision written after id 3 on the
// hole level (an array of G's nodes where the format has no such decision): corrupt, naming the
// chunk and the keyframe, never a crash or a decoded frame.
TEST(LevelsPredictor, ATruncatedOrOverlongKglvOrADecisionWhereNoneIsIsCorrupt) {
  const std::vector<uint8_t> bytes = encode_sequence_file(warped_xyz_sequence(129), xyz_metadata());
  for (const int change : {-1, 1}) {
    const std::vector<uint8_t> edited = crafted::with_chunk_payload(bytes, "KGLV", [&](std::vector<uint8_t>& payload) {
      if (change < 0) payload.pop_back();
      else payload.push_back(0);
    });
    testing::expect_error(ErrorCode::kCorrupt, "KGLV", [&] { decode_sequence_file(edited, "cut.fmv"); });
  }
  // small_sequence has holes: array 13, the hole level on every node, may have id 3 (median).
  const std::vector<uint8_t> holes = encode_sequence_file(crafted::small_sequence(17), crafted::predicted_metadata());
  const auto hand = [&](bool everywhere) {
    return crafted::with_first_group_by_hand(
        holes, false,
        [&](crafted::HandCodedKeyframe& key) {
          ASSERT_FALSE(key.residuals[kScalarArrayCount].empty());
          key.ids[kScalarArrayCount] = 3;  // median; `everywhere`: followed by a decision 0
          key.ids[0] = 3;
          key.levels[0] = 1;
          key.residuals[0] = format::level_residuals(std::vector<int32_t>(key.residuals[0].begin(), key.residuals[0].end()),
                                                     file_layout::grid_facts(17)->interior_levels);
        },
        true, everywhere);
  };
  EXPECT_NO_THROW(decode_sequence_file(hand(false), "levels_on_h.fmv"));
  testing::expect_error(ErrorCode::kCorrupt, "KGLV", [&] { decode_sequence_file(hand(true), "decision_on_hole_level.fmv"); });
}

}  // namespace
}  // namespace facemorph
