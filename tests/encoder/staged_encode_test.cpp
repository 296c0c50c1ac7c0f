// The staged encode (spec/part-file.md): parts sampled apart and assembled give the one-process
// encode's file, byte for byte; parts that do not make up one capture, or that were damaged or
// crafted, are refused with the file and the frame named.
#include "codec/encoder/encode/staged_encode.hpp"
#include "codec/encoder/encode/options_json.hpp"
#include "codec/encoder/encode/part_file.hpp"
#include "codec/encoder/encode/registration_store.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/header_dictionary.hpp"
#include "format/zstd_frame.hpp"

#include "format/file_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

namespace facemorph {
namespace {

Capture small_capture(const std::filesystem::path& dir, int frames = 12) {
  SynthOptions options;
  options.frames = frames;
  options.vertices = 2500;
  options.remesh = true;
  options.noise = 0.0005;
  options.texture_size = 64;
  options.head_motion_degrees = 15;
  write_synthetic_capture(dir, options);
  return read_capture(dir);
}

EncodeOptions small_options() {
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.texture_size = 64;
  options.threads = 2;
  return options;
}

std::vector<uint8_t> file_of(const StoredSequence& sequence, const std::filesystem::path& path) {
  SequenceFileMetadata metadata;
  metadata.encoder = "test";
  write_sequence_file(path, sequence, metadata);
  return format::read_file(path);
}

// Samples `capture` in the parts `ranges` (each on its own encoder) and assembles them, the parts
// given in reverse: the file, and the report through `report`.
std::vector<uint8_t> staged_file(const Capture& capture, const EncodeOptions& options, const std::vector<FrameRange>& ranges,
                                 const testing::TempDir& dir, EncodeReport* report) {
  std::vector<std::filesystem::path> parts;
  for (const FrameRange& range : ranges) {
    parts.push_back(dir.path() / ("part_" + std::to_string(range.first) + ".fms"));
    encode_part(capture, options, range, parts.back());
  }
  std::reverse(parts.begin(), parts.end());
  return file_of(*assemble_parts(parts, options, report), dir.path() / "staged.fmv");
}

void expect_same_report(const EncodeReport& one, const EncodeReport& staged) {
  EXPECT_EQ(one.keyframes, staged.keyframes);
  EXPECT_EQ(one.grid, staged.grid);
  EXPECT_EQ(one.reference_frame, staged.reference_frame);
  EXPECT_EQ(one.warnings, staged.warnings);
  ASSERT_EQ(one.dropped.size(), staged.dropped.size());
  for (size_t k = 0; k < one.dropped.size(); ++k) {
    EXPECT_EQ(one.dropped[k].index, staged.dropped[k].index);
    EXPECT_EQ(one.dropped[k].reason, staged.dropped[k].reason);
  }
  EXPECT_EQ(one.orientation_found, staged.orientation_found);
  // How each face was found and how sure, carried by the parts (part file 3.0; 2.0 read back every
  // one as "whole surface" at confidence 0).
  EXPECT_EQ(one.orientation_methods, staged.orientation_methods);
  EXPECT_EQ(one.lowest_face_confidence, staged.lowest_face_confidence);
  // The disk's crowding, measured on the reference by every part and by the assembler alike, and the
  // radial map it decides (radial_equalising is 0 on these faces: the half-area radii are what can differ).
  EXPECT_EQ(one.density_equalising.half_area_radius_before, staged.density_equalising.half_area_radius_before);
  EXPECT_EQ(one.density_equalising.half_area_radius_after, staged.density_equalising.half_area_radius_after);
  EXPECT_EQ(one.radial_equalising, staged.radial_equalising);
  EXPECT_EQ(one.rim_markers_found, staged.rim_markers_found);
  EXPECT_EQ(one.frames_without_interior_landmarks, staged.frames_without_interior_landmarks);
  ASSERT_EQ(one.frames.size(), staged.frames.size());
  for (size_t i = 0; i < one.frames.size(); ++i) {
    EXPECT_EQ(one.frames[i].name, staged.frames[i].name);
    EXPECT_EQ(one.frames[i].energy, staged.frames[i].energy);
    EXPECT_EQ(one.frames[i].predicted_error, staged.frames[i].predicted_error);
  }
}

TEST(StagedEncode, PartsAssembleToTheOneProcessFile) {
  testing::TempDir dir;
  const Capture capture = small_capture(dir.path() / "capture");
  // The reference in the middle part, registered through its geodesic frame: the frames before it
  // come to the assembling encoder before the partition their registrations need.
  EncodeOptions options = small_options();
  options.reference_frame = 6;
  options.registration.method = RegistrationMethod::kFrame;
  EncodeReport one_report, staged_report;
  const std::vector<uint8_t> one = file_of(*encode_capture_stored(capture, options, &one_report), dir.path() / "one.fmv");
  const std::vector<uint8_t> staged = staged_file(capture, options, {{0, 4}, {4, 9}, {9, 12}}, dir, &staged_report);
  EXPECT_TRUE(one == staged) << "the assembled file differs from the one-process file";
  expect_same_report(one_report, staged_report);
}

TEST(StagedEncode, AFrameDroppedAndAReferenceMovedAreSettledAlikeInEveryPart) {
  testing::TempDir dir;
  Capture capture = small_capture(dir.path() / "capture", 10);
  // Frame 5, the reference, and frame 9 cannot be read: every part must register to frame 4 (as
  // near as 6, earlier), and the landmarks are found from the geometry (rim markers on every frame).
  for (int k : {5, 9}) {
    std::ofstream(capture.mesh_path(static_cast<size_t>(k))) << "v 0 0 0\n";
  }
  capture.landmark_names.clear();
  capture.landmarks.assign(capture.frames.size(), {});
  EncodeOptions options = small_options();
  options.reference_frame = 5;
  // Through the geodesic frame: its points are the found landmarks, in the names' order.
  options.registration.method = RegistrationMethod::kFrame;
  EncodeReport one_report, staged_report;
  const std::vector<uint8_t> one = file_of(*encode_capture_stored(capture, options, &one_report), dir.path() / "one.fmv");
  ASSERT_EQ(one_report.reference_frame, 4);
  ASSERT_EQ(one_report.dropped.size(), 2u);
  ASSERT_TRUE(one_report.rim_markers_found);
  ASSERT_GT(one_report.lowest_face_confidence, 0);
  ASSERT_GT(one_report.density_equalising.half_area_radius_before, 0.3);  // not a 0 compared with a 0
  const std::vector<uint8_t> staged = staged_file(capture, options, {{0, 3}, {3, 7}, {7, 10}}, dir, &staged_report);
  EXPECT_TRUE(one == staged) << "the assembled file differs from the one-process file";
  expect_same_report(one_report, staged_report);
}

TEST(StagedEncode, FramesDroppedAtRegistrationAndLandmarksIgnoredAreReportedAlike) {
  testing::TempDir dir;
  Capture capture = small_capture(dir.path() / "capture");
  // Frames 5 and 10 keep only their pose landmarks: two shared with the reference, so each is
  // dropped at registration (after it was mapped); frame 3's first landmark lies far off its
  // surface and is ignored with a warning.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const int tip = capture.landmark_index("nose_tip"), bridge = capture.landmark_index("nose_bridge");
  ASSERT_GE(tip, 0);
  ASSERT_GE(bridge, 0);
  for (int k : {5, 10}) {
    for (int l = 0; l < static_cast<int>(capture.landmark_names.size()); ++l) {
      if (l != tip && l != bridge) capture.landmarks[static_cast<size_t>(k)][static_cast<size_t>(l)] = Vec3::Constant(nan);
    }
  }
  const int far = tip == 0 ? 1 : 0;
  capture.landmarks[3][static_cast<size_t>(far)] += Vec3(0.5, 0, 0);
  EncodeOptions options = small_options();
  options.reference_frame = 7;
  EncodeReport one_report, staged_report;
  const std::vector<uint8_t> one = file_of(*encode_capture_stored(capture, options, &one_report), dir.path() / "one.fmv");
  ASSERT_EQ(one_report.dropped.size(), 2u);
  EXPECT_NE(one_report.dropped[0].reason.find("frame 5 shares only 2 landmarks"), std::string::npos) << one_report.dropped[0].reason;
  ASSERT_EQ(one_report.warnings.size(), 1u);
  const std::vector<uint8_t> staged = staged_file(capture, options, {{0, 4}, {4, 6}, {6, 12}}, dir, &staged_report);
  EXPECT_TRUE(one == staged) << "the assembled file differs from the one-process file";
  expect_same_report(one_report, staged_report);
}

// The working folder moved between the stages (another machine's): a capture named by a relative
// path still gives the same file, its texture images found where the parts say.
TEST(StagedEncode, TheAssembleStageNeedsNotRunWhereTheSampleStageRan) {
  testing::TempDir dir;
  const std::filesystem::path before = std::filesystem::current_path();
  std::filesystem::current_path(dir.path());
  struct Back {
    std::filesystem::path to;
    ~Back() { std::filesystem::current_path(to); }
  } back{before};
  small_capture("capture", 6);
  const Capture capture = read_capture("capture");
  const EncodeOptions options = small_options();
  const std::vector<uint8_t> one = file_of(*encode_capture_stored(capture, options), dir.path() / "one.fmv");
  encode_part(capture, options, {0, 3}, "a.fms");
  encode_part(capture, options, {3, 6}, "b.fms");
  std::filesystem::create_directories("elsewhere");
  std::filesystem::current_path("elsewhere");
  EXPECT_TRUE(one == file_of(*assemble_parts({"../a.fms", "../b.fms"}, options), "staged.fmv"))
      << "the assembled file differs from the one-process file";
}

TEST(StagedEncode, PartsThatAreNotOneCaptureOnceAreRefused) {
  testing::TempDir dir;
  const Capture capture = small_capture(dir.path() / "capture", 8);
  const EncodeOptions options = small_options();
  const auto part = [&](int first, int end, const EncodeOptions& o = small_options()) {
    const std::filesystem::path path =
        dir.path() / ("p" + std::to_string(first) + "_" + std::to_string(end) + "_" + std::to_string(o.reference_frame) + ".fms");
    if (!std::filesystem::exists(path)) encode_part(capture, o, {first, end}, path);
    return path;
  };
  const auto refused = [&](const std::vector<std::filesystem::path>& parts, const std::string& says) {
    try {
      assemble_parts(parts, options);
      ADD_FAILURE() << "assembled parts that should be refused (" << says << ")";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused({part(0, 3), part(5, 8)}, "frames 3:5 are in no part");
  refused({part(0, 3), part(3, 5)}, "frames 5:8 are in no part");
  refused({part(0, 5), part(3, 8)}, "frames 3:5 are in two parts");
  EncodeOptions other = small_options();
  other.reference_frame = 2;
  refused({part(0, 3), part(3, 8, other)}, "other settings");
  // A part of another capture (another frame count).
  const Capture longer = small_capture(dir.path() / "longer", 9);
  encode_part(longer, options, {3, 9}, dir.path() / "longer.fms");
  refused({part(0, 3), dir.path() / "longer.fms"}, "different captures");
  // A copy of the capture elsewhere: the same frames, names, times and landmarks, another folder.
  std::filesystem::copy(dir.path() / "capture", dir.path() / "copy", std::filesystem::copy_options::recursive);
  encode_part(read_capture(dir.path() / "copy"), options, {3, 8}, dir.path() / "copy.fms");
  refused({part(0, 3), dir.path() / "copy.fms"}, "different captures");
  // The part stage's own refusals.
  EXPECT_THROW(encode_part(capture, options, {5, 9}, dir.path() / "x.fms"), Error);
  EncodeOptions tracking = small_options();
  tracking.track_landmarks = true;
  try {
    encode_part(capture, tracking, {0, 8}, dir.path() / "x.fms");
    ADD_FAILURE() << "sampled a part with tracking";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kUnsupported);
  }
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "x.fms"));
  // Every frame once, in any order: assembles.
  EXPECT_NO_THROW(assemble_parts({part(3, 5), part(5, 8), part(0, 3)}, options));
}

// A part written by the writer from `frames` as read from a good part, with `edit` applied to
// record k: what a crafted file with every checksum right looks like.
std::filesystem::path crafted(const std::filesystem::path& good, const std::filesystem::path& out, size_t k,
                              const std::function<void(SampledFrame&)>& edit) {
  const PartReader reader(good);
  PartWriter writer(out, reader.header());
  for (size_t j = 0; j < static_cast<size_t>(reader.header().range.size()); ++j) {
    SampledFrame f = reader.frame(j);
    if (j == k) edit(f);
    writer.add(f);
  }
  writer.finish();
  return out;
}

TEST(PartFile, ADamagedOrCraftedPartIsRefusedWithItsFrameNamed) {
  testing::TempDir dir;
  const Capture capture = small_capture(dir.path() / "capture", 6);
  const std::filesystem::path good = dir.path() / "good.fms";
  encode_part(capture, small_options(), {0, 6}, good);
  EXPECT_NO_THROW(PartReader(good).verify());
  const std::vector<uint8_t> bytes = format::read_file(good);
  const auto refused = [&](const std::filesystem::path& path, ErrorCode code, const std::string& says) {
    try {
      PartReader(path).verify();
      ADD_FAILURE() << path << " was read as a part (" << says << ")";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), code) << e.what();
      EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what() << " (expected: " << says << ")";
    }
  };
  // Damaged: cut short, a byte flipped inside a record, another file's magic.
  const auto write = [&](const std::string& name, std::vector<uint8_t> content) {
    const std::filesystem::path path = dir.path() / name;
    format::write_file_atomically(path, content);
    return path;
  };
  refused(write("cut.fms", std::vector<uint8_t>(bytes.begin(), bytes.begin() + static_cast<long>(bytes.size() / 2))), ErrorCode::kTruncated,
          "truncated");
  std::vector<uint8_t> flipped = bytes;
  flipped[bytes.size() * 3 / 4] ^= 0x20;
  refused(write("flipped.fms", flipped), ErrorCode::kCorrupt, "checksum");
  std::vector<uint8_t> other = bytes;
  other[3] = 'V';
  refused(write("magic.fms", other), ErrorCode::kCorrupt, "not a facemorph part file");
  // Crafted, every checksum right: each check the assembling encoder relies on.
  refused(crafted(good, dir.path() / "face.fms", 2,
                  [](SampledFrame& f) {
                    MappedFrame m = FrameStore::deserialize(f.map.data(), f.map.size());
                    m.map.surface.faces[7][1] = static_cast<int32_t>(m.map.surface.positions.size());
                    f.map = FrameStore::serialize(m);
                  }),
          ErrorCode::kCorrupt, "frame 2: its map's surface has a coordinate not finite or a face outside its vertices");
  refused(crafted(good, dir.path() / "disk.fms", 1,
                  [](SampledFrame& f) {
                    MappedFrame m = FrameStore::deserialize(f.map.data(), f.map.size());
                    m.map.disk.pop_back();
                    f.map = FrameStore::serialize(m);
                  }),
          ErrorCode::kCorrupt, "frame 1: its map's disk does not fit its surface");
  refused(crafted(good, dir.path() / "hole.fms", 3,
                  [](SampledFrame& f) {
                    MappedFrame m = FrameStore::deserialize(f.map.data(), f.map.size());
                    m.prepared.report.holes.push_back({});
                    m.prepared.report.holes.back().loop = {0, 1, -4};
                    f.map = FrameStore::serialize(m);
                  }),
          ErrorCode::kCorrupt, "frame 3: a hole's outline lies outside");
  // A count that would allocate far more than the record holds: refused before it is allocated.
  refused(crafted(good, dir.path() / "holes.fms", 3,
                  [](SampledFrame& f) {
                    const MappedFrame m = FrameStore::deserialize(f.map.data(), f.map.size());
                    const size_t at = 8 + m.name.size() + 8 + 4 * m.prepared.rim.size() + 8 + 4 * m.prepared.source_vertex.size() + 18 * 4 +
                                      2 * 8;  // the repair report's counts and totals (spec/part-file.md §4), then the hole count
                    const uint64_t holes = uint64_t{1} << 58;
                    std::memcpy(f.map.data() + at, &holes, sizeof holes);
                  }),
          ErrorCode::kCorrupt, "frame 3: its map: ");
  refused(crafted(good, dir.path() / "moebius.fms", 4,
                  [](SampledFrame& f) {
                    DiskRegistration r = RegistrationStore::deserialize(f.registration.data(), f.registration.size(), nullptr);
                    r.moebius.a = Complex(1.5, 0);
                    f.registration = RegistrationStore::serialize(r);
                  }),
          ErrorCode::kCorrupt, "frame 4: its registration's Möbius map is not one of the disk");
  refused(crafted(good, dir.path() / "samples.fms", 0,
                  [](SampledFrame& f) { f.selection.local[10].x() = std::numeric_limits<float>::quiet_NaN(); }),
          ErrorCode::kCorrupt, "frame 0: its selection samples have a number not finite");
  refused(crafted(good, dir.path() / "names.fms", 5, [](SampledFrame& f) { f.landmarks.push_back(Vec3::Zero()); }), ErrorCode::kCorrupt,
          "frame 5: it holds");
  refused(crafted(good, dir.path() / "nodes.fms", 5, [](SampledFrame& f) { f.selection.normal.pop_back(); }), ErrorCode::kCorrupt,
          "frame 5: its selection samples are not the selection grid's");
  // Each check the assembling encoder relies on, once: a record edited as it is rewritten.
  const auto edit_map = [](const std::function<void(MappedFrame&)>& change) {
    return [change](SampledFrame& f) {
      MappedFrame m = FrameStore::deserialize(f.map.data(), f.map.size());
      change(m);
      f.map = FrameStore::serialize(m);
    };
  };
  const std::vector<std::pair<std::function<void(SampledFrame&)>, std::string>> records = {
      {edit_map([](MappedFrame& m) { m.map.surface.faces.clear(); }), "its map has no surface"},
      {edit_map([](MappedFrame& m) { m.map.surface.positions[4] *= 1e300; }), "its map's surface has a coordinate past"},
      {edit_map([](MappedFrame& m) { m.map.disk[static_cast<size_t>(m.map.rim[0])] *= 0.5; }),
       "its map's rim does not lie on the unit circle"},
      {edit_map([](MappedFrame& m) { m.map.rim.push_back(static_cast<int>(m.map.disk.size())); }),
       "its map's rim is not a loop of its vertices"},
      {edit_map([](MappedFrame& m) {
         for (Vec2& w : m.map.disk) w.y() = -w.y();
       }),
       "its map's disk does not cover the unit disk once"},
      {edit_map([](MappedFrame& m) { m.map.surface.uv_faces.pop_back(); }), "its map's texture coordinates do not fit its faces"},
      {edit_map([](MappedFrame& m) { m.map.surface.colours = {Vec3(1, 0, 0)}; }), "its map's colours do not fit its vertices"},
      {[](SampledFrame& f) { f.mapped = false; }, "it is kept but was never mapped"},
      {[](SampledFrame& f) { f.warnings.assign(5000, "w"); }, "it holds more warnings than a frame has landmarks"},
      {[](SampledFrame& f) { f.warnings = {std::string(5000, 'w')}; }, "a warning is longer than"},
      {[](SampledFrame& f) { f.time = f.selection.time = 1e9; }, "its time is outside the capture's"},
      {[](SampledFrame& f) { f.summary.vertices = -1; }, "its summary is out of range"},
      {[](SampledFrame& f) { f.selection.pose.rotation *= 2; }, "its head pose is not a rigid motion"},
      {[](SampledFrame& f) { f.selection.diagonal = 0; }, "its selection samples have a number not finite"},
      {[](SampledFrame& f) { f.selection.local[3] *= 1e20f; }, "its selection samples have a coordinate past"},
      {[](SampledFrame& f) { f.landmarks[0] = Vec3::Constant(std::numeric_limits<double>::infinity()); },
       "a landmark is neither a point nor missing"},
      {[](SampledFrame& f) { f.texture = "/dev/zero"; }, "its texture /dev/zero is not a file"},
      {[](SampledFrame& f) { f.texture = "relative.jpg"; }, "its texture's path is not absolute"},
      {[](SampledFrame& f) { f.registration.back() = 7; },
       "its registration: registration store: a stored registration holds 7 where a truth value belongs"},
  };
  for (size_t c = 0; c < records.size(); ++c) {
    refused(crafted(good, dir.path() / ("record_" + std::to_string(c) + ".fms"), 1, records[c].first), ErrorCode::kCorrupt,
            "frame 1: " + records[c].second);
  }
  // What only the assembling encoder sees (a frame's time not after the one before it, which the
  // part's records cannot tell alone) is named by the part and the frame as well.
  const std::filesystem::path early =
      crafted(good, dir.path() / "early.fms", 3, [&](SampledFrame& f) { f.time = f.selection.time = capture.frames[2].time; });
  EXPECT_NO_THROW(PartReader(early).verify());
  testing::expect_error(ErrorCode::kInvalidArgument, early.string() + ": frame 3: ", [&] { assemble_parts({early}, small_options()); });
  // And the header's.
  const auto header_of = [&](const std::function<void(PartHeader&)>& change, const std::string& name) {
    PartHeader header = PartReader(good).header();
    change(header);
    PartWriter writer(dir.path() / name, header);
    for (int k = header.range.first; k < header.range.end; ++k) {
      SampledFrame f;
      f.index = k;
      f.dropped = "crafted";
      f.time = header.capture.first_time;
      writer.add(f);
    }
    writer.finish();
    return dir.path() / name;
  };
  refused(header_of([](PartHeader& h) { h.capture.frame_count = 0, h.range = {0, 0}; }, "frames.fms"), ErrorCode::kLimit, "outside 1..");
  refused(header_of(
              [](PartHeader& h) {
                h.range = {4, 9};
              },
              "range.fms"),
          ErrorCode::kCorrupt, "its frames are not a range of its capture's");
  refused(header_of([](PartHeader& h) { h.capture.reference = 6; }, "reference.fms"), ErrorCode::kCorrupt,
          "its reference frame is not one of its capture's");
  refused(header_of([](PartHeader& h) { h.capture.root = "relative"; }, "root.fms"), ErrorCode::kCorrupt,
          "its capture's folder is not an absolute path");
  refused(header_of([](PartHeader& h) { h.capture.given_landmark_names = {"x"}; }, "names.fms"), ErrorCode::kCorrupt,
          "do not begin with the capture's own");
  refused(header_of([](PartHeader& h) { h.settings = std::string(40, '[') + std::string(40, ']'); }, "deep.fms"), ErrorCode::kCorrupt,
          "nests deeper than");
  // A writer that does not finish leaves nothing; one that finishes replaces the file whole.
  {
    const PartReader reader(good);
    PartWriter writer(dir.path() / "unfinished.fms", reader.header());
    writer.add(reader.frame(0));
  }
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "unfinished.fms"));
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << "a temporary file was left: " << entry.path();
  }
}

// A part whose chunks are those of `good`, each re-prepared as the part writer prepares them, and
// `type`'s (with `against_dictionary`) compressed against the header dictionary with flag bit 2
// set: every checksum right, the chunk as a 2.5 facemorph file would hold it. The container kind is
// the good part's own (its magic, the version PartReader reads).
std::vector<uint8_t> part_with_dictionary_chunk(const std::filesystem::path& good, std::string_view type, bool against_dictionary) {
  const std::vector<uint8_t> bytes = format::read_file(good);
  format::ContainerKind kind{{}, kPartMajorVersion, kPartMinorVersion, "part file"};
  std::copy_n(bytes.begin(), kind.magic.size(), kind.magic.begin());
  const format::ContainerReader reader(bytes, good.string(), UINT64_MAX, kind);
  format::ContainerWriter writer(kind);
  for (const format::ChunkView& c : reader.chunks()) {
    std::vector<uint8_t> raw = reader.payload(c);
    format::PreparedChunk chunk = format::prepare_chunk(c.type, raw, c.critical(), 3);
    if (c.type == type && against_dictionary) {
      chunk.stored = format::compress_frame(raw, 19, format::header_dictionary());
      chunk.flags |= format::kChunkCompressed | format::kChunkDictionary;
      chunk.raw_size = raw.size();
    }
    writer.add(chunk);
  }
  return writer.finish();
}

// Chunk flag bit 2 (the header dictionary, spec/container.md §3.4) is the facemorph file's from 2.5
// on; a part file (spec/part-file.md) never has it: the part's reader refuses a chunk that sets it,
// naming the file and the chunk, whether it is the header or a frame's record. Rebuilt the same way
// without the flag, the part reads: what is refused is the flag.
TEST(PartFile, AChunkAgainstTheHeaderDictionaryIsRefusedByName) {
  testing::TempDir dir;
  const Capture capture = small_capture(dir.path() / "capture", 4);
  const std::filesystem::path good = dir.path() / "good.fms";
  encode_part(capture, small_options(), {0, 4}, good);
  const std::filesystem::path plain = dir.path() / "plain.fms";
  format::write_file_atomically(plain, part_with_dictionary_chunk(good, "PHDR", false));
  EXPECT_NO_THROW(PartReader(plain).verify());
  for (const std::string_view type : {"PHDR", "PFRM"}) {
    const std::filesystem::path path = dir.path() / (std::string(type) + ".fms");
    format::write_file_atomically(path, part_with_dictionary_chunk(good, type, true));
    testing::expect_error(ErrorCode::kCorrupt, path.string() + ": chunk " + std::string(type) + " at offset", [&] { PartReader(path).verify(); });
    testing::expect_error(ErrorCode::kCorrupt, "sets reserved flags", [&] { PartReader(path).verify(); });
  }
}

TEST(StagedEncode, PartRangesCoverACaptureOnce) {
  const std::vector<FrameRange> ranges = part_ranges(10, 4);
  ASSERT_EQ(ranges.size(), 3u);
  EXPECT_EQ(ranges[0].first, 0);
  EXPECT_EQ(ranges[1].first, 4);
  EXPECT_EQ(ranges[2].first, 8);
  EXPECT_EQ(ranges[2].end, 10);
  EXPECT_EQ(part_ranges(3, 10).size(), 1u);
  EXPECT_THROW(part_ranges(3, 0), Error);
}

// The options' one schema (options_json.hpp): the bytes part files have always held, read back
// field by field, and what cannot be read refused by name.
TEST(EncodeOptionsSchema, TheSampleOptionsAreTheBytesPartFilesHold) {
  // A part file's header as facemorph wrote it before the schema (default options).
  const std::string stored =
      R"({"conformal":{"energy_tolerance":1e-07,"fallback":true,"max_iterations":100,"method":0},"density_equalising":{"max_steps":100,"radial":-1.0,)"
      R"("step":0.05,"strength":0.0,"tolerance":0.01},"find_landmarks":true,"landmark_tolerance":0.02,"largest_component":false,"reference_frame":0,)"
      R"("registration":{"allow_fallback":true,"boundary_spacing_degrees":5.0,"fold_grid":129,"form":0,"max_substeps":8,"method":1,"min_area_ratio":0.02,)"
      R"("moebius_start":0,"paper_grid_n":8,"smoothing":0.0,"smoothing_tries":4},"strict":false,"texture":true,"track_landmarks":false})";
  EXPECT_EQ(write_options(EncodeOptions{}, OptionsScope::kSample), stored);
  EXPECT_TRUE(same_options(stored, EncodeOptions{}, OptionsScope::kSample));
  // Compared as values: spaces and a number's form do not matter; a key the schema lacks does.
  std::string spaced = stored;
  spaced.replace(spaced.find("\"max_iterations\":100"), 20, "\"max_iterations\" : 100.0");
  EXPECT_TRUE(same_options(spaced, EncodeOptions{}, OptionsScope::kSample));
  std::string more = stored;
  more.insert(1, "\"later_option\":1,");
  EXPECT_FALSE(same_options(more, EncodeOptions{}, OptionsScope::kSample));
}

TEST(EncodeOptionsSchema, WhatIsWrittenReadsBackAsTheSameOptions) {
  EncodeOptions options;
  options.reference_frame = 3;
  options.conformal.method = ConformalMethod::kTutte;
  options.registration.method = RegistrationMethod::kFrame;
  options.density_equalising.radial = 0.25;
  options.keyframe_fraction = 0.3;
  options.representation = Representation::kXYZ;
  options.spline = SplineKind::kLinear;
  options.texture_codec = TextureCodec::kWebp;
  options.field_precision.intra_period = 4;
  options.keyframe_fit = false;
  for (const OptionsScope scope : {OptionsScope::kSample, OptionsScope::kSegment}) {
    const std::string text = write_options(options, scope);
    EXPECT_EQ(write_options(read_options(text, scope), scope), text);
    EXPECT_TRUE(same_options(text, options, scope));
    EXPECT_FALSE(same_options(text, EncodeOptions{}, scope));
  }
  const EncodeOptions read = read_options(write_options(options, OptionsScope::kSegment), OptionsScope::kSegment);
  EXPECT_EQ(read.reference_frame, 3);
  EXPECT_EQ(read.conformal.method, ConformalMethod::kTutte);
  EXPECT_EQ(read.registration.method, RegistrationMethod::kFrame);
  EXPECT_EQ(read.density_equalising.radial, 0.25);
  EXPECT_EQ(read.representation, Representation::kXYZ);
  EXPECT_EQ(read.spline, SplineKind::kLinear);
  EXPECT_EQ(read.texture_codec, TextureCodec::kWebp);
  EXPECT_EQ(read.field_precision.intra_period, 4);
  EXPECT_FALSE(read.keyframe_fit);
  // A sample scope's text holds none of the assemble stage's options: those stay as given.
  EXPECT_EQ(read_options(write_options(options, OptionsScope::kSample), OptionsScope::kSample).spline, EncodeOptions{}.spline);
}

TEST(EncodeOptionsSchema, OptionsThatCannotBeReadAreRefusedByName) {
  const std::string good = write_options(EncodeOptions{}, OptionsScope::kSample);
  auto refused = [](const std::string& text, const std::string& what) {
    try {
      read_options(text, OptionsScope::kSample);
      ADD_FAILURE() << "read: " << text;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kCorrupt);
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
    EXPECT_FALSE(same_options(text, EncodeOptions{}, OptionsScope::kSample));
  };
  std::string text = good;
  text.replace(text.find("\"strict\":false"), 14, "\"strict\":0");
  refused(text, "\"strict\"");
  text = good;
  text.replace(text.find("\"method\":1"), 10, "\"method\":7");
  refused(text, "the options (registration)'s \"method\" is no choice of its kind (7)");
  text = good;
  text.erase(text.find("\"texture\":true,"), 15);
  refused(text, "lacks \"texture\"");
  refused("[1]", "not a JSON object");
}

}  // namespace
}  // namespace facemorph
