// Frame patches (format 2.4, spec/container.md §7.5, spec/method.md §7.19): the displacement,
// analytically (bilinear on the lattice, linear in t between nodes, 0 at keyframes and past the
// ends); continuity in t; the PTCH chunk's round trip to the bit and what a decoder shows with it;
// every check of its reader; a file stamped 2.3 skips it.
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/decoder/container/chunk_readers.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <functional>

namespace facemorph {
namespace {

// Keyframes at 0, 0.5, 1 and 1.5 s; interval 0 has a patch at 0.2 (the centre node of a 3 × 3
// lattice lifted by 1) and an empty one at 0.3; interval 1 one at 0.8 (the same node by 2 along x).
struct PatchFixture {
  std::vector<double> times = {0.0, 0.5, 1.0, 1.5};
  std::vector<FramePatch> patches = {{0.2, 3, {4}, {Vec3(0, 0, 1)}}, {0.3, 3, {}, {}}, {0.8, 3, {4}, {Vec3(2, 0, 0)}}};
};

TEST(FramePatches, TheDisplacementIsBilinearOnTheLatticeAndLinearInTime) {
  const PatchFixture f;
  ASSERT_NO_THROW(validate_patches(f.times, f.patches));
  // Bilinear: the centre node's hat, 1 at the centre, 1/2 half-way to an edge, 1/4 half-way to a corner.
  const std::vector<Vec2> points = {Vec2(0, 0), Vec2(0.5, 0), Vec2(0.5, 0.5), Vec2(-1, 0), Vec2(0, -0.25)};
  const std::vector<double> hat = {1, 0.5, 0.25, 0, 0.75};
  for (size_t p = 0; p < points.size(); ++p) EXPECT_NEAR(patch_displacement(f.patches[0], points[p]).z(), hat[p], 1e-15) << p;
  // In time: (t, the share of patch 0's and patch 2's displacement expected there).
  const std::vector<std::array<double, 3>> expected = {
      {0.2, 1, 0},    {0.1, 0.5, 0},   // from keyframe 0 (0) to the patch at 0.2: u = 1/2
      {0.25, 0.5, 0},                  // from 0.2 to the empty patch at 0.3
      {0.4, 0, 0},    {0.65, 0, 0.5},  // from keyframe 1 (0.5) to 0.8: u = 1/2
      {0.8, 0, 1},    {0.9, 0, 0.5},   // from 0.8 to keyframe 2 (1.0)
  };
  for (const auto& [t, a, b] : expected) {
    SCOPED_TRACE(t);
    const std::vector<Vec3> d = frame_patch_displacements(f.times, f.patches, t, points);
    ASSERT_EQ(d.size(), points.size());
    for (size_t p = 0; p < points.size(); ++p)
      EXPECT_TRUE(d[p].isApprox(Vec3(2 * b, 0, a) * hat[p], 1e-14) || (a == 0 && b == 0 && d[p].isZero()));
  }
  // At a keyframe, in an interval without patches and past either end: none at all.
  for (double t : {0.0, 0.5, 1.0, 1.2, 1.5, -0.3, 1.9}) EXPECT_TRUE(frame_patch_displacements(f.times, f.patches, t, points).empty()) << t;
}

// The displacement moves by at most (its slope) × the step everywhere from a second before the
// first keyframe to a second after the last: no jump where a patch's reach starts or ends.
TEST(FramePatches, TheDisplacementIsContinuousInTimeAndExtrapolationIsUnchanged) {
  const PatchFixture f;
  const std::vector<Vec2> points = {Vec2(0, 0), Vec2(0.3, -0.2)};
  const auto at = [&](double t) {
    std::vector<Vec3> d = frame_patch_displacements(f.times, f.patches, t, points);
    if (d.empty()) d.assign(points.size(), Vec3::Zero());
    return d;
  };
  const double h = 1e-4;
  double worst = 0;
  std::vector<Vec3> before = at(-1.0);
  for (double t = -1.0 + h; t <= 2.5; t += h) {
    const std::vector<Vec3> now = at(t);
    for (size_t p = 0; p < points.size(); ++p) worst = std::max(worst, (now[p] - before[p]).norm());
    before = now;
  }
  // Slopes: 1 / 0.1 s from the empty patch at 0.3 … 2 / 0.3 s from 0.8 to keyframe 1.
  EXPECT_LT(worst, 11 * h);
}

TEST(FramePatches, ValidationRefusesWhatTheDecoderCannotUse) {
  const std::vector<double> times = {0.0, 0.5, 1.0};
  const auto refused = [&](std::vector<FramePatch> p, const std::string& fragment) {
    testing::expect_error(ErrorCode::kInvalidArgument, fragment, [&] { validate_patches(times, p); });
  };
  refused({{0.5, 3, {}, {}}}, "not strictly between two keyframes");
  refused({{1.2, 3, {}, {}}}, "not strictly between two keyframes");
  refused({{0.2, 3, {}, {}}, {0.1, 3, {}, {}}}, "times must increase");
  refused({{0.2, 1, {}, {}}}, "lattice 1 outside");
  refused({{0.2, 3, {9}, {Vec3::Zero()}}}, "node indices must increase");
  refused({{0.2, 3, {4, 4}, {Vec3::Zero(), Vec3::Zero()}}}, "node indices must increase");
  refused({{0.2, 3, {4}, {}}}, "one displacement per node");
  refused({{0.2, 3, {4}, {Vec3(std::nan(""), 0, 0)}}}, "not finite");
  EXPECT_NO_THROW(validate_patches(times, {}));
}

// small_sequence's keyframes at 0, 0.5 and 1 s (30 fps) with two patches on the file's lattice
// (0.25 s is 480 64ths of a frame period, 0.75 s 1440), displacements in 16ths.
Sequence with_patches() {
  Sequence s = small_sequence(9, 8);
  s.patches = {{0.25, 5, {12}, {Vec3(0.25, -0.5, 0.125)}}, {0.75, 3, {4, 5}, {Vec3(0, 0, 0.0625), Vec3(0.5, 0, 0)}}};
  return s;
}

std::vector<uint8_t> patch_file() { return encode_sequence_file(with_patches(), small_metadata()); }

// u32 count 2, i8 e = -4; 480 (zigzag 960: 0xC0 0x07), C 5, 1 node: gap 12, codes 4, -8, 2; change
// 960 (0x80 0x0F), C 3, 2 nodes: gap 4, codes 0, 0, 1; gap 0, codes 8, 0, 0 (all zigzag).
const std::vector<uint8_t> kPatchPayload = {2, 0, 0, 0, 0xFC, 0xC0, 0x07, 10, 2, 24, 8, 15, 4, 0x80, 0x0F, 6, 4, 8, 0, 0, 2, 0, 16, 0, 0};

TEST(FramePatches, AFileHoldsThemToTheBitAndADecoderAddsThem) {
  const Sequence s = with_patches();
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(patch_file(), "patches.fmv", &info);
  ASSERT_EQ(back.patches.size(), s.patches.size());
  for (size_t p = 0; p < s.patches.size(); ++p) {
    EXPECT_EQ(back.patches[p].time, s.patches[p].time);
    EXPECT_EQ(back.patches[p].lattice, s.patches[p].lattice);
    EXPECT_EQ(back.patches[p].nodes, s.patches[p].nodes);
    EXPECT_EQ(back.patches[p].displacements, s.patches[p].displacements);
  }
  EXPECT_EQ(info.minor_version, format::kMinorVersion);  // stamped with the writer's own
  EXPECT_EQ(info.frame_patches, 2u);
  EXPECT_EQ(info.patch_nodes, 3u);
  EXPECT_EQ(testing::chunk_count(info, "PTCH"), 1);
  // The file's frame is the blend's plus the patch rotated by the frame's pose, node for node; holes,
  // pose and texture are the blend's.
  const auto from_file = open_sequence_source(patch_file(), "patches.fmv");
  Sequence plain = back;
  plain.patches.clear();
  SequenceDecoder file_decoder(from_file), plain_decoder(std::make_shared<const Sequence>(plain));
  const DiskGrid& grid = file_decoder.geometry().grid();
  DecodeOptions o;
  o.continue_correction = false;
  for (double t : {0.25, 0.4, 0.75, 0.5, 1.0}) {
    SCOPED_TRACE(t);
    const DecodedFrame a = file_decoder.decode(t, o), c = plain_decoder.decode(t, o);
    std::vector<Vec3> d = frame_patch_displacements(back.keyframe_times(), back.patches, t, grid.nodes);
    if (d.empty()) d.assign(grid.nodes.size(), Vec3::Zero());
    double moved = 0;
    for (size_t n = 0; n < a.grid_positions.size(); ++n) {
      EXPECT_LT((a.grid_positions[n] - (c.grid_positions[n] + c.pose.rotation * d[n])).norm(), 1e-12) << n;
      moved = std::max(moved, (a.grid_positions[n] - c.grid_positions[n]).norm());
    }
    EXPECT_EQ(moved > 1e-3, t == 0.25 || t == 0.4 || t == 0.75);  // 0.5 and 1.0 are keyframes
    EXPECT_EQ(a.hole_level, c.hole_level);
    EXPECT_EQ(a.texture.pixels, c.texture.pixels);
    EXPECT_TRUE(a.pose.rotation.isApprox(c.pose.rotation, 1e-15));
  }
  // Without patches no PTCH is written, and the file needs no more than 2.0.
  SequenceFileInfo plain_info;
  decode_sequence_file(encode_sequence_file(plain, small_metadata()), "plain.fmv", &plain_info);
  EXPECT_EQ(testing::chunk_count(plain_info, "PTCH"), 0);
  EXPECT_EQ(plain_info.frame_patches, 0u);
}

TEST(FramePatches, TheWriterRefusesWhatTheFileCannotHoldExactly) {
  Sequence s = with_patches();
  s.patches[0].time = 0.25 + 1e-9;  // off the 64th-of-a-frame lattice
  testing::expect_error(ErrorCode::kInvalidArgument, "64th of a frame period", [&] { encode_sequence_file(s, small_metadata()); });
  s = with_patches();
  s.patches[0].displacements[0].x() = 0.1;  // no power of two from 2^-60 holds 0.1 exactly
  testing::expect_error(ErrorCode::kInvalidArgument, "whole multiples of one power of two",
                        [&] { encode_sequence_file(s, small_metadata()); });
}

// The PTCH payload of patch_file(), edited by `change`.
std::vector<uint8_t> with_patch_payload(const std::function<void(std::vector<uint8_t>&)>& change) {
  return crafted::with_chunk_payload(patch_file(), "PTCH", change);
}

TEST(FramePatches, EveryCheckOfTheChunkRefusesABadOneByName) {
  ASSERT_EQ(crafted::chunk_payload(patch_file(), "PTCH"), kPatchPayload);
  const auto corrupt = [](const std::vector<uint8_t>& bytes, const std::string& fragment) {
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { open_sequence_source(bytes, "crafted.fmv"); });
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { decode_sequence_file(bytes, "crafted.fmv"); });
  };
  corrupt(with_patch_payload([](auto& p) { p[0] = 0; }), "states 0 frame patches");
  corrupt(with_patch_payload([](auto& p) { p[0] = 9; }), "states 9 frame patches");  // its 21 bytes hold 7
  corrupt(with_patch_payload([](auto& p) { p[4] = 31; }), "step exponent 31");
  corrupt(with_patch_payload([](auto& p) { p[4] = 0xC3; }), "step exponent -61");
  corrupt(with_patch_payload([](auto& p) { p[4] = 30; }), "displacement code 4 beyond");  // 2^30 a step: 10^9 holds no code
  corrupt(with_patch_payload([](auto& p) {
            p[13] = 0;
            p[14] = 0;
          }),
          "frame patch 1: its time does not come after");  // a change of 0
  corrupt(with_patch_payload([](auto& p) {
            p[13] = 0x80;
            p[14] = 0x2F;
          }),
          "frame patch 1: its time");  // q = 3488: 1.82 s, past the last keyframe
  corrupt(with_patch_payload([](auto& p) { p[7] = 2; }), "lattice 1 outside");
  corrupt(with_patch_payload([](auto& p) { p[8] = 0x7E; }), "states 63 nodes");  // more than 5 × 5
  corrupt(with_patch_payload([](auto& p) { p[9] = 50; }), "node gap 25 leaves");
  corrupt(with_patch_payload([](auto& p) { p[21] = 1; }), "node gap -1");  // node 4 again
  corrupt(with_patch_payload([](auto& p) { p.push_back(0); }), "1 bytes after its last field");
  // Cut inside a varint (the sizes' bounds catch other cuts first, as corrupt).
  testing::expect_error(ErrorCode::kTruncated, "a patch time's change",
                        [&] { open_sequence_source(with_patch_payload([](auto& p) { p.resize(14); }), "crafted.fmv"); });
  // Their memory against the caller's budget, before a patch's nodes are allocated: 2 patches and 3
  // nodes need one node more than this.
  const uint64_t tight = 2 * sizeof(FramePatch) + 2 * (sizeof(int32_t) + sizeof(Vec3));
  testing::expect_error(ErrorCode::kLimit, "frame patches' nodes need", [&] {
    file_layout::read_patches(kPatchPayload, "tight.fmv", with_patches(), {0.0, 0.5, 1.0}, tight, 4);
  });
  EXPECT_EQ(file_layout::read_patches(kPatchPayload, "roomy.fmv", with_patches(), {0.0, 0.5, 1.0}, tight + 28, 4).size(), 2u);
  // Two PTCH chunks: the extra chunk rebuild adds, renamed.
  const std::vector<uint8_t> two = crafted::rebuild(crafted::rebuild(
                                                        patch_file(), [](const std::string&, std::vector<uint8_t>&) {}, true),
                                                    [&](std::string& type, std::vector<uint8_t>& payload) {
                                                      if (type == "ZZZ1") {
                                                        type = "PTCH";
                                                        payload = kPatchPayload;
                                                      }
                                                    });
  corrupt(two, "two PTCH chunks");
}

// A file stamped 2.3 with a PTCH chunk: skipped, as a 2.3 decoder skips a chunk it does not know
// (not critical), so the frames are the blend's alone.
TEST(FramePatches, InAFileOfAnEarlierMinorVersionTheChunkIsSkipped) {
  const std::vector<uint8_t> bytes = crafted::with_minor_version(patch_file(), 3);
  EXPECT_TRUE(open_sequence_source(bytes, "v2_3.fmv")->outline().patches.empty());
  EXPECT_TRUE(decode_sequence_file(bytes, "v2_3.fmv").patches.empty());
}

}  // namespace
}  // namespace facemorph
