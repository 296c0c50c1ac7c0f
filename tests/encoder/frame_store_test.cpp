// The encoder's frame store: a spilled map reads back as the same numbers, the encoder holds a few
// maps at once whatever the capture's length, and spilling leaves the output as it was.
#include "codec/encoder/encode/frame_store.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

namespace facemorph {
namespace {

// Every field FrameStore writes (all of MappedFrame but the prepared mesh), compared exactly.
void expect_same(const MappedFrame& a, const MappedFrame& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.prepared.rim, b.prepared.rim);
  EXPECT_EQ(a.prepared.source_vertex, b.prepared.source_vertex);
  const RepairReport &ra = a.prepared.report, &rb = b.prepared.report;
  EXPECT_EQ(ra.summary(), rb.summary());
  EXPECT_EQ(ra.merged_vertices, rb.merged_vertices);
  EXPECT_EQ(ra.dropped_component_faces, rb.dropped_component_faces);
  ASSERT_EQ(ra.holes.size(), rb.holes.size());
  for (size_t h = 0; h < ra.holes.size(); ++h) {
    EXPECT_EQ(ra.holes[h].loop, rb.holes[h].loop);
    EXPECT_EQ(ra.holes[h].first_vertex, rb.holes[h].first_vertex);
    EXPECT_EQ(ra.holes[h].face_count, rb.holes[h].face_count);
    EXPECT_EQ(ra.holes[h].area, rb.holes[h].area);
    EXPECT_EQ(ra.holes[h].sharpest_hole_corner_degrees, rb.holes[h].sharpest_hole_corner_degrees);
  }
  const TriangleMesh &sa = a.map.surface, &sb = b.map.surface;
  EXPECT_EQ(sa.positions, sb.positions);
  EXPECT_EQ(sa.faces, sb.faces);
  EXPECT_EQ(sa.uvs, sb.uvs);
  EXPECT_EQ(sa.uv_faces, sb.uv_faces);
  EXPECT_EQ(sa.texture, sb.texture);
  EXPECT_EQ(sa.colours, sb.colours);
  EXPECT_EQ(a.map.disk, b.map.disk);
  EXPECT_EQ(a.map.rim, b.map.rim);
  EXPECT_EQ(a.map.source_vertex, b.map.source_vertex);
  EXPECT_EQ(a.map.normalization.a, b.map.normalization.a);
  EXPECT_EQ(a.map.normalization.theta, b.map.normalization.theta);
  EXPECT_EQ(a.map.report.method, b.map.report.method);
  EXPECT_EQ(a.map.report.fallback_reason, b.map.report.fallback_reason);
  EXPECT_EQ(a.map.report.iterations, b.map.report.iterations);
  EXPECT_EQ(a.map.report.untangled_vertices, b.map.report.untangled_vertices);
  EXPECT_EQ(a.map.report.energy_excess, b.map.report.energy_excess);
  EXPECT_EQ(a.map.report.seconds_finish, b.map.report.seconds_finish);
  EXPECT_EQ(a.normalized, b.normalized);
  ASSERT_EQ(a.found.has_value(), b.found.has_value());
  if (a.found) {
    EXPECT_EQ(a.found->nose_tip, b.found->nose_tip);
    EXPECT_EQ(a.found->vertical, b.found->vertical);
    EXPECT_EQ(a.found->up_evidence, b.found->up_evidence);
    EXPECT_EQ(a.found->up_from_hint, b.found->up_from_hint);
  }
  EXPECT_EQ(a.found_rim, b.found_rim);
  EXPECT_EQ(a.seconds_prepare, b.seconds_prepare);
  EXPECT_EQ(a.seconds_map, b.seconds_map);
}

// A flat disk with a round hole (filled by preparation: a FilledHole to carry).
TriangleMesh holed_disk() {
  TriangleMesh disk = testing::polar_disk(16, 64, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0.1 * w.squaredNorm()); });
  std::vector<Face> kept;
  for (const Face& f : disk.faces) {
    Vec3 c = Vec3::Zero();
    for (int32_t v : f) c += disk.positions[static_cast<size_t>(v)] / 3;
    if ((c.head<2>() - Vec2(0.3, 0)).norm() > 0.3) kept.push_back(f);
  }
  disk.faces = kept;
  return disk;
}

TEST(FrameStore, ASpilledFrameReadsBackAsTheSameNumbers) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 1;
  synth.vertices = 2000;
  synth.texture_size = 32;
  write_synthetic_capture(dir.path() / "textured", synth);
  synth.vertex_colour = true;
  write_synthetic_capture(dir.path() / "coloured", synth);
  std::vector<MappedFrame> frames;
  MapFrameOptions find;
  find.find_orientation = true;  // no landmarks given: the orientation and rim markers are found, so they are stored too
  for (const char* name : {"textured", "coloured"}) {
    const Capture capture = read_capture(dir.path() / name);
    frames.push_back(map_frame(read_mesh(capture.mesh_path(0)), name, {}, find));
  }
  frames.push_back(map_frame(holed_disk(), "holed disk", {}));
  ASSERT_TRUE(frames[0].map.surface.has_uvs() && !frames[0].map.surface.texture.empty());
  ASSERT_TRUE(frames[0].found && frames[0].found_rim.size() == static_cast<size_t>(kFoundRimMarkers));
  ASSERT_TRUE(frames[1].map.surface.has_colours());
  ASSERT_EQ(frames[2].prepared.report.holes.size(), 1u);

  FrameStore store;
  EXPECT_EQ(store.mode(), FrameStore::Mode::kSpill);
  store.reset(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) store.put(i, MappedFrame(frames[i]));
  EXPECT_GT(store.spilled_bytes(), 0u);
  EXPECT_EQ(store.held(), 0);  // nothing in memory once written
  for (size_t i = frames.size(); i-- > 0;) {
    const std::shared_ptr<const MappedFrame> back = store.get(i);
    EXPECT_EQ(store.held(), 1);
    expect_same(frames[i], *back);
    EXPECT_TRUE(back->prepared.mesh.positions.empty());  // not stored: map.surface is the same surface
  }
  EXPECT_EQ(store.held(), 0);
  EXPECT_EQ(store.peak_held(), 1);
  {
    const auto a = store.get(0), b = store.get(1);
    EXPECT_EQ(store.held(), 2);
  }
  EXPECT_EQ(store.peak_held(), 2);
  // Dropping frames renumbers the rest.
  store.keep({0, 2});
  ASSERT_EQ(store.size(), 2u);
  expect_same(frames[2], *store.get(1));
  testing::expect_error(ErrorCode::kInternal, "frame 2", [&] { store.get(2); });
  // A frame cut short is an error, not a frame of zeros.
  std::vector<char> bytes = FrameStore::serialize(frames[2]);
  expect_same(frames[2], FrameStore::deserialize(bytes.data(), bytes.size()));
  testing::expect_error(ErrorCode::kInternal, "cut short", [&] { FrameStore::deserialize(bytes.data(), bytes.size() - 1); });

  // In memory: the frame itself, counted while stored.
  FrameStore memory(FrameStore::Mode::kMemory);
  memory.reset(2);
  memory.put(0, MappedFrame(frames[0]));
  memory.put(1, MappedFrame(frames[1]));
  EXPECT_EQ(memory.held(), 2);
  EXPECT_EQ(memory.spilled_bytes(), 0u);
  EXPECT_EQ(memory.get(1).get(), memory.get(1).get());
  EXPECT_EQ(memory.get(1)->prepared.mesh.positions, frames[1].prepared.mesh.positions);
}

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The encoder holds the reference's map and one per thread, not the capture's: 16 frames on two
// threads, at most 3 maps at once; kept in memory, all 16 (and the one being stored). Either way the file is the same bytes.
TEST(FrameStore, TheEncoderHoldsAFewFramesAtOnceAndWritesTheSameFile) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 16;
  synth.vertices = 2000;
  synth.remesh = true;
  synth.texture_size = 64;
  synth.head_motion_degrees = 10;
  write_synthetic_capture(dir.path(), synth);
  const Capture capture = read_capture(dir.path());
  std::string files[2];
  int peaks[2] = {0, 0};
  for (const bool spill : {true, false}) {
    EncodeOptions options;
    options.threads = 2;
    options.keyframe_fraction = 0.25;
    options.texture_size = 64;
    options.spill_frames = spill;
    EncodeReport report;
    const Sequence sequence = encode_capture(capture, options, &report);
    ASSERT_GE(sequence.keyframes.size(), 4u);  // a fit over frames between keyframes, textures at keyframes and between
    EXPECT_EQ(report.spilled_bytes > 0, spill);
    SequenceFileMetadata metadata;
    metadata.keyframe_texture_qualities = report.texture_qualities;
    metadata.field_coding = report.field_coding;
    const auto path = dir.path() / (spill ? "spilled.fmv" : "in_memory.fmv");
    write_sequence_file(path, sequence, metadata);
    files[spill] = file_bytes(path);
    peaks[spill] = report.peak_frames_in_memory;
  }
  EXPECT_LE(peaks[1], 3) << "spilled: the reference and one frame per thread";
  EXPECT_GE(peaks[1], 2);
  EXPECT_GE(peaks[0], 16) << "in memory: every frame";
  ASSERT_FALSE(files[1].empty());
  EXPECT_TRUE(files[0] == files[1]) << "spilling the maps changed the file";
}

}  // namespace
}  // namespace facemorph
