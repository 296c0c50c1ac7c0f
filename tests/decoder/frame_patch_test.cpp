// Frame patches (format 2.4, spec/container.md §7.5, spec/method.md §7.19): the displacement,
// analytically (bilinear on the lattice, linear in t between nodes, 0 at keyframes and past the
// ends); continuity in t; the PTCH chunk's round trip to the bit and what a decoder shows with it;
// every check of its reader, in both codings (2.4's varints, 2.5's range-coded stream, §7.5.1); a
// file stamped 2.3 skips it.
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/decoder/container/chunk_readers.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "format/ranged_patches.hpp"
#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <optional>

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

// Patches read back equal to those written, to the bit.
void expect_same_patches(const std::vector<FramePatch>& back, const std::vector<FramePatch>& written) {
  ASSERT_EQ(back.size(), written.size());
  for (size_t p = 0; p < written.size(); ++p) {
    EXPECT_EQ(back[p].time, written[p].time);
    EXPECT_EQ(back[p].lattice, written[p].lattice);
    EXPECT_EQ(back[p].nodes, written[p].nodes);
    EXPECT_EQ(back[p].displacements, written[p].displacements);
  }
}

// Format 2.4's coding of with_patches(): u32 count 2, i8 e = -4; 480 (zigzag 960: 0xC0 0x07), C 5,
// 1 node: gap 12, codes 4, -8, 2; change 960 (0x80 0x0F), C 3, 2 nodes: gap 4, codes 0, 0, 1; gap 0,
// codes 8, 0, 0 (all zigzag).
const std::vector<uint8_t> kPatchPayload = {2, 0, 0, 0, 0xFC, 0xC0, 0x07, 10, 2, 24, 8, 15, 4, 0x80, 0x0F, 6, 4, 8, 0, 0, 2, 0, 16, 0, 0};

// The same patches as a file stamped 2.4 writes them (the writer writes 2.5's coding; a rebuilt
// file is stamped with the writer's version, so the stamp comes after).
std::vector<uint8_t> patch_file_v2_4() {
  return crafted::with_minor_version(crafted::with_chunk_payload(patch_file(), "PTCH", [](auto& p) { p = kPatchPayload; }), 4);
}

// Format 2.5's coding of with_patches() (§7.5.1): varint count 2 (zigzag 4), i8 e = -4, varint
// stream length, then the stream: times 480 = 7.5 frames and 960 = 15 frames after it, lattices 5
// and 3, node 12 of 25 and nodes 4 and 5 of 9, the codes as above.
const std::vector<uint8_t> kRangedPatchPayload = {4,    0xFC, 38,   0,    0x86, 0xC5, 0xFA, 0x19, 0,    0x64, 0x18,
                                                   0x3F, 0x19, 0xA2, 0xB1, 0x92, 0x1B, 0x8B, 0x23, 0xFE, 0x80, 0};

TEST(FramePatches, AFileHoldsThemToTheBitAndADecoderAddsThem) {
  const Sequence s = with_patches();
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(patch_file(), "patches.fmv", &info);
  expect_same_patches(back.patches, s.patches);
  EXPECT_EQ(info.minor_version, format::kMinorVersion);
  EXPECT_EQ(crafted::chunk_payload(patch_file(), "PTCH"), kRangedPatchPayload);
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

// The PTCH payload of patch_file_v2_4(), edited by `change`, in a file stamped 2.4.
std::vector<uint8_t> with_patch_payload(const std::function<void(std::vector<uint8_t>&)>& change) {
  return crafted::with_minor_version(crafted::with_chunk_payload(patch_file_v2_4(), "PTCH", change), 4);
}

// A file stamped 2.4 reads its PTCH as 2.4 wrote it, to the same patches as the 2.5 file's.
TEST(FramePatches, AFileStamped2_4ReadsTheVarintCoding) {
  const Sequence s = with_patches();
  SequenceFileInfo info;
  const Sequence back = decode_sequence_file(patch_file_v2_4(), "v2_4.fmv", &info);
  EXPECT_EQ(info.minor_version, 4);
  expect_same_patches(back.patches, s.patches);
  // The 2.5 coding in a file stamped 2.4 is not what 2.4 wrote: its stream's first byte (0) reads
  // as a time change of 0, refused by name, never misread; the 2.4 coding in a 2.5 file likewise.
  testing::expect_error(ErrorCode::kCorrupt, "frame patches",
                        [&] { open_sequence_source(crafted::with_minor_version(patch_file(), 4), "v2_4.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "frame patches", [&] {
    open_sequence_source(crafted::with_minor_version(patch_file_v2_4(), format::kMinorVersion), "v2_5.fmv");
  });
}

TEST(FramePatches, EveryCheckOfTheChunkRefusesABadOneByName) {
  ASSERT_EQ(crafted::chunk_payload(patch_file_v2_4(), "PTCH"), kPatchPayload);
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
  // nodes need one node more than this. The charge is fixed on every platform (64 bytes a patch, 28
  // a node, §7.5), whatever a patch holds there (40 bytes in WebAssembly): the numbers, not sizeof.
  const uint64_t tight = 2 * 64 + 2 * 28;
  testing::expect_error(ErrorCode::kLimit, "frame patches' nodes need", [&] {
    file_layout::read_patches(kPatchPayload, "tight.fmv", with_patches(), {0.0, 0.5, 1.0}, tight, 4);
  });
  EXPECT_EQ(file_layout::read_patches(kPatchPayload, "roomy.fmv", with_patches(), {0.0, 0.5, 1.0}, tight + 28, 4).size(), 2u);
  // Two PTCH chunks: the extra chunk rebuild adds, renamed.
  const std::vector<uint8_t> two = crafted::with_minor_version(
      crafted::rebuild(crafted::rebuild(patch_file_v2_4(), [](const std::string&, std::vector<uint8_t>&) {}, true),
                       [&](std::string& type, std::vector<uint8_t>& payload) {
                         if (type == "ZZZ1") {
                           type = "PTCH";
                           payload = kPatchPayload;
                         }
                       }),
      4);
  corrupt(two, "two PTCH chunks");
}

// ---- Format 2.5's coding (§7.5.1) ----

// with_patches()' patches as the stream codes them: 7.5 and 15 frames, in 16ths.
std::vector<format::CodedPatch> coded_patches() {
  return {{480, 5, {12}, {{4, -8, 2}}}, {960, 3, {4, 5}, {{0, 0, 1}, {8, 0, 0}}}};
}

std::vector<uint8_t> stream_of(const std::vector<format::CodedPatch>& patches) {
  format::PatchStreamWriter w;
  for (const auto& p : patches) w.add(p);
  return w.finish();
}

// A 2.5 PTCH payload: varint count, i8 e, varint stream length `stated` (none: the stream's), the
// stream, then `after` bytes.
std::vector<uint8_t> ranged_payload(int64_t count, int8_t e, const std::vector<uint8_t>& stream, std::optional<int64_t> stated = {},
                                    size_t after = 0) {
  format::ByteWriter w;
  file_layout::write_varint(w, count);
  w.write(e);
  file_layout::write_varint(w, stated.value_or(static_cast<int64_t>(stream.size())));
  w.bytes(stream);
  for (size_t i = 0; i < after; ++i) w.write(uint8_t{0});
  return w.take();
}

// A stream written decision by decision as §7.5.1 lays it out, with values no writer writes.
struct RawPatchStream {
  format::RangedStreamWriter stream;
  format::PatchModels m;
  RawPatchStream& time(bool off_frame, int64_t coded, int64_t remainder = 0) {
    stream.decision(m.off_frame, off_frame);
    stream.number(m.frames, coded);
    if (off_frame) stream.number(m.remainder, remainder);
    return *this;
  }
  RawPatchStream& lattice(bool is_new, int64_t c = 0) {
    stream.decision(m.new_lattice, is_new);
    if (is_new) stream.number(m.lattice, c);
    return *this;
  }
  // Not empty, and `nodes` flags 0 (each under context 0: no neighbour or earlier patch moved).
  RawPatchStream& still_flags(int nodes) {
    stream.decision(m.empty, false);
    for (int i = 0; i < nodes; ++i) stream.decision(m.occupied[0], false);
    return *this;
  }
  std::vector<uint8_t> finish() { return stream.finish(); }
};

TEST(FramePatches, TheRangeCodedChunkHoldsThemToTheBit) {
  // The writer's coding of the patches, and its reading to the same patches as 2.4's varints.
  EXPECT_EQ(ranged_payload(2, -4, stream_of(coded_patches())), kRangedPatchPayload);
  const Sequence a = decode_sequence_file(patch_file(), "v2_5.fmv"), b = decode_sequence_file(patch_file_v2_4(), "v2_4.fmv");
  expect_same_patches(a.patches, b.patches);
  // An empty patch, a lattice kept, a time off the frame lattice, codes past the unary part and
  // the escape's longest: read back as written.
  const std::vector<format::CodedPatch> varied = {{1, 17, {0, 1, 18, 288}, {{1, 2, 3}, {-9, 100, 0}, {0, 0, -1}, {int64_t{1} << 34, 0, 0}}},
                                                  {64, 17, {}, {}},
                                                  {129, 17, {1, 18, 19}, {{0, 5, 0}, {-(int64_t{1} << 34), 1, 1}, {7, 7, 7}}},
                                                  {64, 129, {16640}, {{3, 0, 0}}}};
  const std::vector<uint8_t> varied_stream = stream_of(varied);  // the reader holds a view of it
  format::PatchStreamReader r(varied_stream, "varied");
  for (const auto& p : varied) {
    EXPECT_EQ(r.time_change(), p.time_change);
    EXPECT_EQ(r.lattice(), p.lattice);
    ASSERT_EQ(r.occupancy(), p.nodes.size());
    std::vector<int32_t> nodes(p.nodes.size());
    std::vector<std::array<int64_t, 3>> codes(p.nodes.size());
    r.nodes_and_codes(nodes, codes);
    EXPECT_EQ(nodes, p.nodes);
    EXPECT_EQ(codes, p.codes);
  }
  EXPECT_NO_THROW(r.expect_end());
  // What no stream may hold, refused by the writer.
  for (const format::CodedPatch& bad : std::vector<format::CodedPatch>{{0, 3, {}, {}},
                                                                     {1, 130, {}, {}},
                                                                     {1, 3, {4, 4}, {{1, 0, 0}, {1, 0, 0}}},
                                                                     {1, 3, {9}, {{1, 0, 0}}},
                                                                     {1, 3, {4}, {{(int64_t{1} << 34) + 1, 0, 0}}}}) {
    format::PatchStreamWriter w;
    EXPECT_THROW(w.add(bad), Error);
  }
}

TEST(FramePatches, EveryCheckOfTheRangeCodedChunkRefusesABadOneByName) {
  ASSERT_EQ(crafted::chunk_payload(patch_file(), "PTCH"), kRangedPatchPayload);
  const std::vector<uint8_t> good = stream_of(coded_patches());
  const auto corrupt = [](const std::vector<uint8_t>& payload, const std::string& fragment) {
    SCOPED_TRACE(fragment);
    const std::vector<uint8_t> bytes = crafted::with_chunk_payload(patch_file(), "PTCH", [&](auto& p) { p = payload; });
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { open_sequence_source(bytes, "crafted.fmv"); });
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { decode_sequence_file(bytes, "crafted.fmv"); });
  };
  const std::string s = std::to_string(good.size());
  corrupt(ranged_payload(0, -4, good), "states 0 frame patches");
  corrupt(ranged_payload(72 * static_cast<int64_t>(good.size()) + 1, -4, good), "its stream of " + s + " bytes holds 1 to");
  corrupt(ranged_payload(2, -4, good, static_cast<int64_t>(good.size()) + 1), "a patch stream of");
  corrupt(ranged_payload(2, -4, good, -5), "a patch stream of -5 bytes");
  corrupt(ranged_payload(2, 31, good), "step exponent 31");
  corrupt(ranged_payload(2, 30, good), "displacement code 4 beyond");  // 2^30 a step: 10^9 holds no code
  corrupt(ranged_payload(3, -4, good), "ends before its last value");  // a third patch the stream has not
  corrupt(ranged_payload(2, -4, std::vector<uint8_t>(good.begin(), good.end() - 1)), "range-coded");
  std::vector<uint8_t> longer = good;
  longer.push_back(0);
  corrupt(ranged_payload(2, -4, longer), "range-coded");  // a byte the stream does not read
  corrupt(ranged_payload(2, -4, good, {}, 1), "1 bytes after its last field");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, -1).finish()), "time change of -1 frames");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(true, 0, 64).finish()), "remainder 64 outside");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(true, 0, 0).finish()), "remainder 0 outside");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, 100).lattice(true, 3).finish()), "is not strictly between two keyframes");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, 6).lattice(false).finish()), "lattice 0 outside");  // no lattice before
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, 6).lattice(true, 130).finish()), "lattice 130 outside");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, 6).lattice(true, 1).finish()), "lattice 1 outside");
  corrupt(ranged_payload(1, -4, RawPatchStream().time(false, 6).lattice(true, 3).still_flags(9).finish()), "moves none");
  // Their memory against the caller's budget: the count's before anything is allocated, each
  // patch's nodes before they are (2 patches and 3 nodes need one node more than `tight`), at the
  // fixed charge of every platform (64 bytes a patch, 28 a node).
  const uint64_t tight = 2 * 64 + 2 * 28;
  const uint16_t minor = format::kMinorVersion;
  testing::expect_error(ErrorCode::kLimit, "frame patches' nodes need", [&] {
    file_layout::read_patches(kRangedPatchPayload, "tight.fmv", with_patches(), {0.0, 0.5, 1.0}, tight, minor);
  });
  testing::expect_error(ErrorCode::kLimit, "2 frame patches need", [&] {
    file_layout::read_patches(kRangedPatchPayload, "tight.fmv", with_patches(), {0.0, 0.5, 1.0}, 2 * 64 - 1, minor);
  });
  EXPECT_EQ(file_layout::read_patches(kRangedPatchPayload, "roomy.fmv", with_patches(), {0.0, 0.5, 1.0}, tight + 28, minor).size(), 2u);
}

// The patches are held with the residual frames: they are charged against what the residual frames
// left of the budget, not the whole of it (each within the whole let a file of a few kilobytes hold
// twice the budget before the memory plan refused it). 60,000 residual frames (3.8 MB) and one
// patch under a budget one byte short of both (64 bytes a residual frame, 64 a patch, 28 a node, on
// every platform, §10.1): the PTCH's reader refuses, by name.
TEST(FramePatches, TheirMemoryIsWhatTheResidualFramesLeftOfTheBudget) {
  Sequence s = crafted::small_sequence(9, 8);
  for (size_t k = 0; k < s.keyframes.size(); ++k) s.keyframes[k].time = 50.0 * static_cast<double>(k);
  s.last_time = 100;
  constexpr int kResiduals = 60'000;
  for (int j = 1; j <= kResiduals; ++j) s.residuals.push_back({j / 1920.0, {0.25, -0.125, -0.125}});  // 64ths of a frame at 30 fps
  s.patches = {{60.0, 3, {4}, {Vec3(0, 0, 1)}}};
  const std::vector<uint8_t> bytes = encode_sequence_file(s, crafted::small_metadata());
  DecoderLimits limits;
  limits.max_memory_bytes = kResiduals * 64 + 64 + 28 - 1;
  testing::expect_error(ErrorCode::kLimit, "frame patches: frame patches' nodes need", [&] { open_sequence_source(bytes, "both.fmv", limits); });
  limits.max_memory_bytes = DecoderLimits{}.max_memory_bytes;
  EXPECT_EQ(open_sequence_source(bytes, "both.fmv", limits)->outline().residuals.size(), size_t{kResiduals});
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
