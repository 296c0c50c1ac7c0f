// The encoder's first stages, frame by frame: map (landmarks on the disk, found landmarks, frames
// that cannot be mapped dropped and named, the reference moved) and register (frames dropped there,
// tracked frames).
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

// `mesh` with a second surface beside it (a loose eyeball, say): not one open surface any more.
TriangleMesh with_a_second_component(TriangleMesh mesh) {
  mesh.uvs.clear();
  mesh.uv_faces.clear();
  mesh.texture.clear();
  const auto offset = static_cast<int32_t>(mesh.positions.size());
  const TriangleMesh ball = testing::icosphere(0.01, 1);
  for (const Vec3& p : ball.positions) mesh.positions.push_back(p + Vec3(0.3, 0, 0));
  for (const Face& f : ball.faces) mesh.faces.push_back({f[0] + offset, f[1] + offset, f[2] + offset});
  return mesh;
}

// An error in one frame's conformal map names that frame (the capture has hundreds): QIEM allowed
// no step and no fallback fails on every frame, frame_0000 first with one thread.
TEST(SequenceEncoder, AMappingErrorNamesItsFrame) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 0);
  EncodeOptions options;
  options.texture = false;
  options.conformal.fallback = false;
  options.conformal.max_iterations = 0;
  options.threads = 1;
  SequenceEncoder encoder(capture, options);
  testing::expect_error(ErrorCode::kNotConverged, "frame_0000.obj: QIEM: no convergence in 0 steps", [&] { map_frames(encoder); });
}

// The registration's input: every landmark both frames have, in the capture's order; rim_*
// markers flagged and exactly on the circle, the others inside it.
TEST(SequenceEncoder, DiskLandmarksFlagTheRimMarkersAndOnlyThem) {
  testing::TempDir dir;
  Capture capture = testing::small_remeshed_capture(dir, 0);
  capture.frames.resize(3);
  capture.landmarks.resize(3);
  EncodeOptions options;
  options.texture = false;
  SequenceEncoder encoder(capture, options);
  map_frames(encoder);
  const DiskLandmarks l = disk_landmarks(capture, 0, encoder.frame(0)->map, 2, encoder.frame(2)->map);
  ASSERT_EQ(l.reference.size(), capture.landmark_names.size());
  int rim = 0;
  for (size_t j = 0; j < l.reference.size(); ++j) {
    const bool named_rim = capture.landmark_names[j].rfind("rim_", 0) == 0;
    EXPECT_EQ(l.on_rim[j] != 0, named_rim) << capture.landmark_names[j];
    for (const Vec2& w : {l.reference[j], l.frame[j]}) {
      if (named_rim)
        EXPECT_NEAR(w.norm(), 1.0, 1e-12) << capture.landmark_names[j];
      else
        EXPECT_LT(w.norm(), 0.999) << capture.landmark_names[j];
    }
    rim += named_rim;
  }
  EXPECT_GE(rim, 3);
  EXPECT_LT(rim, static_cast<int>(l.reference.size()) - 3);
}

// Without --strict, a frame that cannot be encoded is dropped and named, never chosen as a
// keyframe, and the spline covers its time; a landmark off its frame's surface is ignored and
// named. Here: frame 5 has a second surface (an eyeball), frame 8's nose tip lies 5 cm off it (so,
// unless found from the geometry, frame 8 cannot be put in the reference pose either), frame 3's chin lies 5 cm off (chin_bottom_midline)
// (ignored; the frame is kept).
TEST(SequenceEncoder, AFrameThatCannotBeEncodedIsDroppedAndNamed) {
  testing::TempDir dir;
  Capture capture = testing::small_remeshed_capture(dir, 0);
  const TriangleMesh frame5 = read_mesh(capture.mesh_path(5), {.allow_missing_texture = true});
  write_mesh(capture.mesh_path(5), with_a_second_component(frame5));
  const auto nose = static_cast<size_t>(capture.landmark_index("nose_tip")),
             chin = static_cast<size_t>(capture.landmark_index("chin_bottom_midline"));
  ASSERT_LT(chin, capture.landmark_names.size());
  capture.landmarks[8][nose] += Vec3(0, 0, 0.05);
  capture.landmarks[3][chin] += Vec3(0, 0, 0.05);
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.grid = 49;
  options.texture = false;
  options.find_landmarks = false;  // frame 8 then lacks its nose tip (below: found from its geometry)
  EncodeReport report;
  const Sequence sequence = encode_capture(capture, options, &report);
  ASSERT_EQ(report.dropped.size(), 2u);
  EXPECT_EQ(report.dropped[0].index, 5);
  EXPECT_NE(report.dropped[0].reason.find("2 components"), std::string::npos) << report.dropped[0].reason;
  EXPECT_EQ(report.dropped[0].name, capture.frames[5].mesh.string());
  EXPECT_EQ(report.dropped[1].index, 8);
  EXPECT_NE(report.dropped[1].reason.find("lacks the landmarks nose_tip"), std::string::npos) << report.dropped[1].reason;
  EXPECT_EQ(report.frames.size(), 10u);
  std::string warnings;
  for (const std::string& w : report.warnings) warnings += w + "\n";
  EXPECT_NE(warnings.find(capture.frames[8].mesh.string() + ": landmark 'nose_tip' lies "), std::string::npos) << warnings;
  EXPECT_NE(warnings.find(capture.frames[3].mesh.string() + ": landmark 'chin_bottom_midline' lies "), std::string::npos) << warnings;
  // The capture keeps its span; no keyframe sits at a dropped frame's time.
  EXPECT_EQ(sequence.first_time, capture.frames.front().time);
  EXPECT_EQ(sequence.last_time, capture.frames.back().time);
  for (const Keyframe& key : sequence.keyframes) {
    EXPECT_NE(key.time, capture.frames[5].time);
    EXPECT_NE(key.time, capture.frames[8].time);
  }
  // The spline covers the dropped frame: decoded at its time, the face is where the frame was.
  SequenceDecoder decoder(std::make_shared<const Sequence>(sequence));
  const SurfaceDistance d = surface_distance(frame5, decoder.decode(capture.frames[5].time).mesh);
  EXPECT_LT(d.rms / d.diagonal, 0.006);

  // Finding landmarks (the default), frame 8 keeps its nose tip found from the geometry.
  options.find_landmarks = true;
  EncodeReport found;
  encode_capture(capture, options, &found);
  ASSERT_EQ(found.dropped.size(), 1u);
  EXPECT_EQ(found.dropped[0].index, 5);
  EXPECT_EQ(found.orientation_found, 1);

  // The landmarks as the encoder keeps them, out of its capture, spilled or in memory alike: the
  // frames kept, renumbered; the far ones ignored; frame 8's nose tip and up found from its geometry.
  const auto bridge = static_cast<size_t>(capture.landmark_index("nose_bridge"));
  for (const bool spill : {true, false}) {
    SCOPED_TRACE(spill ? "spilled" : "in memory");
    options.spill_frames = spill;
    SequenceEncoder encoder(capture, options);
    EXPECT_TRUE(encoder.capture().landmarks.empty());
    map_frames(encoder);
    ASSERT_EQ(encoder.frame_count(), static_cast<int>(capture.frames.size()) - 1);
    for (int i = 0; i < encoder.frame_count(); ++i) {
      const auto source = static_cast<size_t>(encoder.source_index(i));
      const std::vector<Vec3> points = encoder.landmarks(i);
      ASSERT_EQ(points.size(), encoder.capture().landmark_names.size());
      for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
        const Vec3& given = capture.landmarks[source][l];
        if (source == 3 && l == chin) {
          EXPECT_FALSE(points[l].allFinite());
        } else if (source == 8 && l == nose) {
          ASSERT_TRUE(points[l].allFinite());
          EXPECT_GT((points[l] - given).norm(), 0.02);  // found on the surface, not the one 5 cm off it
        } else if (source == 8 && l == bridge) {
          EXPECT_TRUE(points[l].allFinite());  // the found up direction's point
        } else if (given.allFinite()) {
          EXPECT_EQ(points[l], given) << "frame " << source << ", landmark " << l;
        }
      }
    }
  }
  options.spill_frames = true;

  // --strict: the first of them ends the encode, named (one thread: frame 3's chin comes first).
  options.strict = true;
  options.threads = 1;
  testing::expect_error(ErrorCode::kInvalidArgument, capture.frames[3].mesh.string() + ": landmark 'chin_bottom_midline' lies",
                        [&] { encode_capture(capture, options); });
  capture.landmarks[3][chin] -= Vec3(0, 0, 0.05);
  testing::expect_error(ErrorCode::kNotADisk, capture.frames[5].mesh.string() + ": 2 components",
                        [&] { encode_capture(capture, options); });
}

// Frames the registration cannot take (two lack every landmark: their nose tip and up are found, but
// the capture's rim markers are not, so they share 2 landmarks with the reference) are dropped there,
// and the frames after them keep their own registrations. A temporary file the registrations cannot
// be written to is no fault of any frame: it ends the encode instead of dropping them all.
TEST(SequenceEncoder, FramesDroppedAtRegistrationLeaveTheOthersTheirOwn) {
  testing::TempDir dir;
  Capture capture = testing::small_remeshed_capture(dir, 10);
  for (const size_t f : {3u, 4u}) capture.landmarks[f].assign(capture.landmark_names.size(), Vec3::Constant(std::nan("")));
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.grid = 49;
  options.texture = false;
  for (const bool spill : {true, false}) {
    SCOPED_TRACE(spill ? "spilled" : "in memory");
    options.spill_frames = spill;
    SequenceEncoder encoder(capture, options);
    map_frames(encoder);
    ASSERT_EQ(encoder.frame_count(), 12);
    register_frames(encoder);
    ASSERT_EQ(encoder.report().dropped.size(), 2u);
    EXPECT_EQ(encoder.report().dropped[0].index, 3);
    EXPECT_EQ(encoder.report().dropped[1].index, 4);
    EXPECT_NE(encoder.report().dropped[0].reason.find("shares only 2 landmarks"), std::string::npos) << encoder.report().dropped[0].reason;
    ASSERT_EQ(encoder.frame_count(), 10);
    // Frame 5 of the capture is frame 3 now, with its own registration: it matches its landmarks.
    for (int i = 0; i < encoder.frame_count(); ++i) {
      const DiskLandmarks l = encoder.frame_disk_landmarks(i);
      const std::shared_ptr<const DiskRegistration> f = encoder.registration(i);
      EXPECT_LT(matching_energy(*f, l), 1e-6) << "frame " << encoder.source_index(i);
    }
  }
  {
    // Frames dropped before the reference renumber it: its map stays pinned under its new number
    // (FrameMaps::keep), so every frame still reads back its own map.
    options.reference_frame = 8;
    SequenceEncoder encoder(capture, options);
    map_frames(encoder);
    register_frames(encoder);
    ASSERT_EQ(encoder.options().reference_frame, 6);
    for (int i = 0; i < encoder.frame_count(); ++i)
      EXPECT_EQ(encoder.frame(i)->name, encoder.capture().frames[static_cast<size_t>(i)].mesh.string())
          << "frame " << encoder.source_index(i);
    options.reference_frame = 0;
  }
  options.spill_frames = true;
  SequenceEncoder encoder(capture, options);
  map_frames(encoder);
  const testing::ScopedEnv no_temporary_folder("TMPDIR", (dir.path() / "no-such-folder").string());
  testing::expect_error(ErrorCode::kIo, "the frames' registrations", [&] { register_frames(encoder); });
}

// Without landmarks and without tracking, every frame gets its nose tip, up and rim markers from its
// geometry, kept by the encoder (spilled or not) for the registration, which then drops no frame.
TEST(SequenceEncoder, LandmarksFoundFromTheGeometryAreKeptForTheRegistration) {
  testing::TempDir dir;
  Capture capture = testing::small_remeshed_capture(dir, 10);
  capture.landmark_names.clear();
  capture.landmarks.assign(capture.frames.size(), {});
  EncodeOptions options;
  options.texture = false;
  for (const bool spill : {true, false}) {
    SCOPED_TRACE(spill ? "spilled" : "in memory");
    options.spill_frames = spill;
    SequenceEncoder encoder(capture, options);
    map_frames(encoder);
    const std::vector<std::string>& names = encoder.capture().landmark_names;
    for (int i = 0; i < encoder.frame_count(); ++i) {
      const std::vector<Vec3> points = encoder.landmarks(i);
      ASSERT_EQ(points.size(), names.size());
      int rim = 0;
      for (size_t l = 0; l < names.size(); ++l) {
        EXPECT_TRUE(points[l].allFinite()) << "frame " << i << ": " << names[l];
        rim += names[l].rfind("rim_", 0) == 0;
      }
      EXPECT_EQ(rim, 6) << "frame " << i;
    }
    register_frames(encoder);
    EXPECT_TRUE(encoder.report().dropped.empty()) << encoder.report().dropped.front().reason;
  }
}

// A capture without landmarks: the nose tip and up come from each frame's geometry, rim markers
// from its rim, interior points by tracking, and the encode decodes about as close to every frame as with the capture's own
// landmarks. Without find_landmarks every frame lacks its pose landmarks and the encode fails.
TEST(SequenceEncoder, ACaptureWithoutLandmarksEncodesFromItsGeometry) {
  testing::TempDir dir;
  const Capture given = testing::small_remeshed_capture(dir, 10);
  Capture bare = given;
  bare.landmark_names.clear();
  bare.landmarks.assign(bare.frames.size(), {});
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.grid = 65;
  options.texture = false;
  options.track_landmarks = true;
  // A coarser grid than the default 0.05 (about 200 points, not 900): the thin plate through the
  // tracked points is most of this test's time (115 s under the sanitizers at 0.05).
  options.tracking.spacing = 0.1;
  auto held_out = [&](const Capture& capture, EncodeReport& report) {
    const Sequence sequence = encode_capture(capture, options, &report);
    SequenceDecoder decoder(std::make_shared<const Sequence>(sequence));
    double sum = 0;
    int count = 0;
    for (size_t i = 0; i < given.frames.size(); ++i) {
      if (std::binary_search(report.keyframes.begin(), report.keyframes.end(), static_cast<int>(i))) continue;
      const SurfaceDistance d = surface_distance(read_mesh(given.mesh_path(i)), decoder.decode(given.frames[i].time).mesh);
      sum += d.rms / d.diagonal;
      ++count;
    }
    return sum / count;
  };
  EncodeReport with, without;
  const double landmarked = held_out(given, with), found = held_out(bare, without);
  std::printf("held-out mean RMS: landmarks %.4f%%, found from the geometry %.4f%%\n", 100 * landmarked, 100 * found);
  EXPECT_EQ(with.orientation_found, 0);
  EXPECT_FALSE(with.rim_markers_found);
  EXPECT_EQ(without.orientation_found, static_cast<int>(given.frames.size()));
  EXPECT_TRUE(without.rim_markers_found);
  EXPECT_TRUE(without.dropped.empty()) << without.dropped.front().name << ": " << without.dropped.front().reason;
  EXPECT_LE(without.up_from_hint, 2);  // a coarse (3k-vertex) face may leave a frame or two to its neighbours
  // Interior correspondence tracked from the reference onto every other frame (not where the
  // capture's own landmarks give it).
  EXPECT_EQ(with.tracked_frames, 0);
  EXPECT_EQ(without.tracked_frames, static_cast<int>(given.frames.size()) - 1);
  EXPECT_GT(without.tracked_points_mean, 50);
  EXPECT_LT(without.tracked_round_trip_median, 0.005);
  EXPECT_LT(found, 1.3 * landmarked);
  options.find_landmarks = false;
  testing::expect_error(ErrorCode::kInvalidArgument, "lacks the landmarks nose_tip", [&] { encode_capture(bare, options); });
}

// Frames registered through tracked points take the smoothing thin plate (spec/method.md §7.14,
// item 5); frames with the capture's own interior landmarks keep the spline through them.
TEST(SequenceEncoder, TrackedFramesTakeASmoothingSpline) {
  testing::TempDir dir;
  Capture given = testing::small_remeshed_capture(dir, 0);
  given.frames.resize(3);
  given.landmarks.resize(3);
  Capture bare = given;
  bare.landmark_names.clear();
  bare.landmarks.assign(bare.frames.size(), {});
  EncodeOptions options;
  options.texture = false;
  options.track_landmarks = true;
  options.tracking.spacing = 0.1;
  for (const Capture* capture : {&given, &bare}) {
    SequenceEncoder encoder(*capture, options);
    map_frames(encoder);
    register_frames(encoder);
    const double expected = capture == &bare ? options.tracking.registration_smoothing : 0.0;
    for (int i = 1; i < encoder.frame_count(); ++i) {
      if (encoder.registration(i)->fallback == RegistrationFallback::kNone) {
        EXPECT_EQ(encoder.registration(i)->smoothing, expected) << i;
      }
    }
  }
}

// A frame sampled at G's nodes on several threads (runs of nodes side by side, as the grid choice
// samples the reference) is, to the bit, the frame sampled on one: each point is a function of its
// node alone. A run that skips or repeats a node, or maps one twice, fails here.
TEST(SequenceEncoder, AFrameSampledOnAnyThreadsIsTheSame) {
  testing::TempDir dir;
  const Capture capture = testing::small_remeshed_capture(dir, 0);
  EncodeOptions options;
  options.texture = false;
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const PlanFrames frames = plan_frames(encoder);
  const DiskGrid grid = make_disk_grid(41);
  // Frames away from the reference (whose registration is nearest the identity).
  for (const int i : {static_cast<int>(capture.frames.size()) / 2, static_cast<int>(capture.frames.size()) - 1}) {
    const std::shared_ptr<const MappedFrame> frame = frames.maps.frame(i);
    const std::vector<Vec3> one = frames.sampler.sample_surface(*frame, i, grid.nodes, 1);
    ASSERT_EQ(one.size(), grid.nodes.size());
    for (const int threads : {2, 3, 7}) EXPECT_EQ(frames.sampler.sample_surface(*frame, i, grid.nodes, threads), one) << "frame " << i << ", " << threads << " threads";
  }
}

// The reference frame dropped: the nearest frame kept takes its place, and the report says so.
// Every frame dropped: an error naming the first.
TEST(SequenceEncoder, ADroppedReferenceMovesToTheNearestFrame) {
  testing::TempDir dir;
  Capture capture = testing::small_remeshed_capture(dir, 0);
  capture.frames.resize(6);
  capture.landmarks.resize(6);
  write_mesh(capture.mesh_path(0), with_a_second_component(read_mesh(capture.mesh_path(0), {.allow_missing_texture = true})));
  EncodeOptions options;
  options.keyframe_fraction = 0.5;
  options.grid = 33;
  options.texture = false;
  EncodeReport report;
  const Sequence sequence = encode_capture(capture, options, &report);
  ASSERT_EQ(report.dropped.size(), 1u);
  EXPECT_EQ(report.reference_frame, 1);
  ASSERT_FALSE(report.warnings.empty());
  EXPECT_NE(report.warnings.back().find("the reference frame was dropped"), std::string::npos) << report.warnings.back();
  EXPECT_EQ(sequence.first_time, capture.frames[0].time);
  EXPECT_EQ(sequence.keyframes.front().time, capture.frames[1].time);
  for (size_t i = 1; i < capture.frames.size(); ++i) {
    write_mesh(capture.mesh_path(i), with_a_second_component(read_mesh(capture.mesh_path(i), {.allow_missing_texture = true})));
  }
  testing::expect_error(ErrorCode::kNotADisk,
                        "no frame of the capture could be encoded (6 dropped); the first, " + capture.frames[0].mesh.string(),
                        [&] { encode_capture(capture, options); });
}

}  // namespace
}  // namespace facemorph
