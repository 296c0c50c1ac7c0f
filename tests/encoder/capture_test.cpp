#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>

#include <sys/wait.h>
#include <unistd.h>

namespace facemorph {
namespace {

using testing::expect_error;
using testing::TempDir;
using testing::write_text;

void write_triangle(const std::filesystem::path& path) { write_text(path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"); }

TEST(Capture, ManifestAndLandmarksRoundTrip) {
  TempDir dir;
  Capture c;
  c.root = dir.path();
  c.description = "three triangles";
  c.fps = 24;
  c.units = "cm";
  for (int i = 0; i < 3; ++i) {
    const std::string name = "f" + std::to_string(i) + ".obj";
    write_triangle(dir / name);
    c.frames.push_back({name, i / 24.0});
  }
  c.landmark_names = {"nose_tip", "rim_0"};
  c.landmarks = {{{0, 0, 1}, {1, 0, 0}}, {{0, 0, 1.5}, Vec3::Constant(std::nan(""))}, {{0, 0, 2}, {1, 2, 3}}};
  c.generator = {{"name", "test"}};
  write_capture_manifest(c);
  const Capture back = read_capture(dir.path());
  EXPECT_EQ(back.description, c.description);
  EXPECT_EQ(back.units, "cm");
  EXPECT_DOUBLE_EQ(back.fps, 24);
  ASSERT_EQ(back.frames.size(), 3u);
  EXPECT_DOUBLE_EQ(back.frames[2].time, 2 / 24.0);
  EXPECT_EQ(back.landmark_names, c.landmark_names);
  EXPECT_EQ(back.landmarks[2][1], Vec3(1, 2, 3));
  EXPECT_FALSE(back.landmarks[1][1].allFinite());  // absent in that frame
  EXPECT_EQ(back.generator_value("name"), "test");
  EXPECT_EQ(back.landmark_index("rim_0"), 1);
  EXPECT_DOUBLE_EQ(metres_per_unit(back.units), 0.01);
}

TEST(Capture, BadManifestsAreNamedErrors) {
  TempDir dir;
  write_triangle(dir / "a.obj");
  write_triangle(dir / "b.obj");
  auto manifest = [&](const std::string& text) { write_text(dir / "capture.json", text); };
  manifest("{ not json");
  expect_error(ErrorCode::kParse, "capture.json: not valid JSON", [&] { read_capture(dir.path()); });
  manifest(R"({"frames": [{"mesh": "a.obj"}]})");
  expect_error(ErrorCode::kParse, "missing number 'fps'", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": -3, "frames": [{"mesh": "a.obj"}]})");
  expect_error(ErrorCode::kParse, "fps must be a positive number", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "frames": [{"mesh": "a.obj", "time": 1}, {"mesh": "b.obj", "time": 0.5}]})");
  expect_error(ErrorCode::kParse, "frame 1 (b.obj) has time 0.5", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "frames": [{"mesh": "a.obj"}, {"mesh": "gone.obj"}]})");
  expect_error(ErrorCode::kIo, "gone.obj", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "units": "furlong", "frames": [{"mesh": "a.obj"}]})");
  expect_error(ErrorCode::kInvalidArgument, "furlong", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "frames": []})");
  expect_error(ErrorCode::kParse, "no frames", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "frames": [{"mesh": 7}]})");
  expect_error(ErrorCode::kParse, "frame 0 lacks a 'mesh'", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 30, "frames": [{"mesh": "a.obj", "time": 0}, {"mesh": "b.obj", "time": 1e999}]})");
  expect_error(ErrorCode::kParse, "capture.json: not valid JSON", [&] { read_capture(dir.path()); });
  manifest(R"({"fps": 1e-320, "frames": [{"mesh": "a.obj"}, {"mesh": "b.obj"}]})");  // default time 1 / fps overflows
  expect_error(ErrorCode::kParse, "frame 1 has a non-finite time", [&] { read_capture(dir.path()); });
  expect_error(ErrorCode::kIo, "nowhere: not found", [&] { read_capture(dir / "nowhere"); });
  std::filesystem::create_directory(dir / "empty");
  expect_error(ErrorCode::kIo, "empty/capture.json", [&] { read_capture(dir / "empty"); });
}

// spec/capture.md §2: landmark_vertex_indices is ignored, so no number in it is ever converted.
TEST(Capture, IgnoredMembersMayHoldAnyNumber) {
  TempDir dir;
  write_triangle(dir / "a.obj");
  write_text(dir / "capture.json",
             R"({"fps": 30, "frames": [{"mesh": "a.obj", "time": 0}],)"
             R"( "landmark_vertex_indices": {"nose_tip": 1e300, "chin": -1e300, "rim_0": 2.5, "rim_1": 99999999999999999999999}})");
  const Capture c = read_capture(dir.path());
  EXPECT_EQ(c.frames.size(), 1u);
  EXPECT_TRUE(c.landmark_names.empty());
}

TEST(Capture, BadLandmarkRowsAreNamedErrors) {
  Capture c;
  c.frames = {{"a.obj", 0}, {"b.obj", 0.1}};
  auto parse = [&](const std::string& text) {
    Capture copy = c;
    parse_landmarks_csv(text, "lm.csv", copy);
    return copy;
  };
  expect_error(ErrorCode::kParse, "header", [&] { parse("f,n,x,y,z\n"); });
  expect_error(ErrorCode::kParse, "lm.csv:2: frame '5'", [&] { parse("frame,name,x,y,z\n5,nose,0,0,0\n"); });
  for (const std::string frame : {"1e300", "-1e300", "nan", "inf", "1.0", "1e0", "99999999999999999999", "-9223372036854775809"}) {
    expect_error(ErrorCode::kParse, "lm.csv:2: frame '" + frame + "' is not a frame of the capture (0..1)",
                 [&] { parse("frame,name,x,y,z\n" + frame + ",nose,0,0,0\n"); });
  }
  expect_error(ErrorCode::kParse, "lm.csv:2: coordinate 'nan'", [&] { parse("frame,name,x,y,z\n0,nose,nan,0,0\n"); });
  expect_error(ErrorCode::kParse, "lm.csv:2: expected 5 fields", [&] { parse("frame,name,x,y,z\n0,nose,1,2\n"); });
  expect_error(ErrorCode::kParse, "more than 5", [&] { parse("frame,name,x,y,z\n0,nose,1,2,3,4\n"); });
  expect_error(ErrorCode::kParse, "given twice", [&] { parse("frame,name,x,y,z\n0,nose,1,2,3\n0,nose,1,2,3\n"); });
  const Capture ok = parse("frame,name,x,y,z\n1,chin,1,2,3\n\n0,nose,4,5,6\n");
  EXPECT_EQ(ok.landmark_names, (std::vector<std::string>{"chin", "nose"}));
  EXPECT_EQ(ok.landmarks[0][1], Vec3(4, 5, 6));
  EXPECT_FALSE(ok.landmarks[0][0].allFinite());
}

// Every frame holds a point per landmark name, so the names and the table are bounded as they come:
// the row whose new name passes a limit is named, and nothing past it is allocated.
TEST(Capture, TheLandmarkTableIsBoundedBeforeItGrows) {
  Capture c;
  c.frames = {{"a.obj", 0}, {"b.obj", 0.1}, {"c.obj", 0.2}};
  const std::string rows = "frame,name,x,y,z\n0,a,1,2,3\n1,b,1,2,3\n2,c,1,2,3\n";
  Capture fits = c;
  parse_landmarks_csv(rows, "lm.csv", fits, {.names = 3, .points = 9});
  EXPECT_EQ(fits.landmark_names.size(), 3u);
  expect_error(ErrorCode::kParse, "lm.csv:4: more than 2 landmark names", [&] {
    Capture copy = c;
    parse_landmarks_csv(rows, "lm.csv", copy, {.names = 2, .points = 100});
  });
  expect_error(ErrorCode::kParse, "lm.csv:4: 3 landmark names for 3 frames: more than the 8 landmark points", [&] {
    Capture copy = c;
    parse_landmarks_csv(rows, "lm.csv", copy, {.names = 100, .points = 8});
  });
  // The defaults, from a file: 4097 names for two frames.
  TempDir dir;
  std::string many = "frame,name,x,y,z\n";
  for (int k = 0; k <= 4096; ++k) many += "0,n" + std::to_string(k) + ",0,0,0\n";
  write_text(dir / "lm.csv", many);
  write_triangle(dir / "a.obj");
  write_triangle(dir / "b.obj");
  expect_error(ErrorCode::kParse, "lm.csv:4098: more than 4096 landmark names", [&] { open_capture(dir.path(), 30, dir / "lm.csv"); });
}

// A landmarks file is read a block at a time: rows across the blocks' seams, CRLF line ends and a
// last line without one read as the same text parsed whole; a line too long for a row is refused
// before it is held whole.
TEST(Capture, ALandmarksFileReadsAsItsText) {
  TempDir dir;
  Capture c;
  c.root = dir.path();
  c.fps = 30;
  for (int i = 0; i < 3; ++i) {
    write_triangle(dir / ("f" + std::to_string(i) + ".obj"));
    c.frames.push_back({"f" + std::to_string(i) + ".obj", i / 30.0});
  }
  std::string text = "frame,name,x,y,z\r\n";
  // 3000 rows of 1000 names, made long by digits past a double's precision, so the file spans blocks.
  const std::string digits(200, '7');
  for (int k = 0; k < 3000; ++k) {
    text += std::to_string(k % 3) + ",landmark_" + std::to_string(k / 3) + "," + std::to_string(k) + "." + digits + ",-1.5e-3,7." + digits +
            "\r\n";
  }
  text += "2,last,1,2,3";                   // no line end
  ASSERT_GT(text.size(), size_t{1} << 20);  // past one block
  write_text(dir / "lm.csv", text);
  Capture whole = c;
  parse_landmarks_csv(text, "lm.csv", whole);
  const Capture streamed = open_capture(dir.path(), 30, dir / "lm.csv");
  EXPECT_EQ(streamed.landmark_names, whole.landmark_names);
  ASSERT_EQ(streamed.landmarks.size(), whole.landmarks.size());
  for (size_t f = 0; f < whole.landmarks.size(); ++f) {
    ASSERT_EQ(streamed.landmarks[f].size(), whole.landmarks[f].size());
    for (size_t l = 0; l < whole.landmarks[f].size(); ++l) {
      const Vec3 &a = streamed.landmarks[f][l], &b = whole.landmarks[f][l];
      EXPECT_TRUE(a == b || (a.array().isNaN().all() && b.array().isNaN().all())) << "frame " << f << ", landmark " << l;
    }
  }
  EXPECT_EQ(streamed.landmarks[2].back(), Vec3(1, 2, 3));
  write_text(dir / "long.csv", "frame,name,x,y,z\n0,nose," + std::string(5000, '1') + ",0,0\n");
  expect_error(ErrorCode::kParse, "long.csv:2: a line longer than 4096 bytes", [&] { open_capture(dir.path(), 30, dir / "long.csv"); });
  expect_error(ErrorCode::kParse, "lm.csv:2: a line longer than 4096 bytes",
               [&] { parse_landmarks_csv("frame,name,x,y,z\n0,nose," + std::string(5000, '1') + ",0,0\n", "lm.csv", whole); });
  expect_error(ErrorCode::kIo, "missing.csv: cannot be opened", [&] { open_capture(dir.path(), 30, dir / "missing.csv"); });
  expect_error(ErrorCode::kIo, "is a directory, not a file", [&] { open_capture(dir.path(), 30, dir.path()); });

  // A 4096-byte row whose CRLF straddles the first block's end: accepted, as anywhere else.
  const std::string header = "frame,name,x,y,z\n";
  std::string row = "0,nose,1.";
  row += std::string(4096 - row.size() - 4, '5') + ",2,3";
  ASSERT_EQ(row.size(), 4096u);
  const size_t blank_lines = (size_t{1} << 20) - 1 - header.size() - row.size();  // the "\r" is the block's last byte
  write_text(dir / "seam.csv", header + std::string(blank_lines, '\n') + row + "\r\n");
  const Capture seam = open_capture(dir.path(), 30, dir / "seam.csv");
  EXPECT_NEAR(seam.landmarks[0][0].x(), 1.5555555555555556, 1e-15);
  EXPECT_EQ(seam.landmarks[0][0].z(), 3);
}

// A line is refused once more of it is read than a row may hold, not read whole: /dev/zero, which
// never ends a line, is refused at line 1 (in a child process, so that a reader holding the line
// whole is stopped by the alarm rather than filling memory).
TEST(Capture, ALineIsRefusedBeforeItIsHeldWhole) {
  TempDir dir;
  write_triangle(dir / "a.obj");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    alarm(10);
    try {
      open_capture(dir.path(), 30, "/dev/zero");
    } catch (const Error& e) {
      const std::string what = e.what();
      _exit(e.code() == ErrorCode::kParse && what.find("/dev/zero:1: a line longer than 4096 bytes") != std::string::npos ? 0 : 2);
    }
    _exit(3);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status)) << "the reader did not stop (signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0) << ")";
  EXPECT_EQ(WEXITSTATUS(status), 0);
}

TEST(Capture, PlainFolderIsReadInNaturalOrder) {
  TempDir dir;
  write_triangle(dir / "scan_10.obj");
  write_triangle(dir / "scan_1.obj");
  write_mesh(dir / "scan_2.ply", read_mesh(dir / "scan_1.obj"));
  write_text(dir / "notes.txt", "x");
  write_text(dir / "lm.csv", "frame,name,x,y,z\n2,nose_tip,0,0,1\n");
  const Capture c = scan_capture_folder(dir.path(), 10, dir / "lm.csv");
  ASSERT_EQ(c.frames.size(), 3u);
  EXPECT_EQ(c.frames[0].mesh, "scan_1.obj");
  EXPECT_EQ(c.frames[1].mesh, "scan_2.ply");
  EXPECT_EQ(c.frames[2].mesh, "scan_10.obj");
  EXPECT_DOUBLE_EQ(c.frames[2].time, 0.2);
  EXPECT_EQ(c.landmarks[2][0], Vec3(0, 0, 1));
  expect_error(ErrorCode::kInvalidArgument, "--fps", [&] { scan_capture_folder(dir.path(), 0, {}); });
}

// Every frame of the real Medusa capture loads and validates as a disk.
TEST(RealCaptures, MedusaAllFramesAreDisks) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const Capture c = read_capture(data / "medusa-mediapipe-4d/capture");
  ASSERT_EQ(c.frames.size(), 232u);
  EXPECT_EQ(c.units, "cm");
  EXPECT_GE(c.landmark_names.size(), 20u);
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const TriangleMesh m = read_mesh(c.mesh_path(i));
    ASSERT_FALSE(m.texture.empty()) << c.frames[i].mesh;
    const PreparedFrame p = prepare_frame(m, c.frames[i].mesh.string());
    EXPECT_EQ(p.mesh.vertex_count(), 468) << c.frames[i].mesh;
    EXPECT_TRUE(p.report.holes.empty()) << c.frames[i].mesh;
  }
}

// An ICT capture made with the data's own script: four boundary loops per frame, three filled.
TEST(RealCaptures, IctFramesBecomeDisksByHoleFilling) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  TempDir dir;
  const std::filesystem::path ict = testing::ict_speech_capture("59.2", "0.2", "15", dir / "ict");
  if (ict.empty()) GTEST_SKIP() << "make_capture.py did not run (python3?)";
  const Capture c = read_capture(ict);
  ASSERT_EQ(c.frames.size(), 3u);
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const TriangleMesh m = read_mesh(c.mesh_path(i), {.allow_missing_texture = true});
    PrepareOptions options;
    for (size_t l = 0; l < c.landmark_names.size(); ++l) {
      if (c.landmark_names[l].starts_with("rim_")) options.rim_markers.push_back(c.landmarks[i][l]);
    }
    const PreparedFrame p = prepare_frame(m, c.frames[i].mesh.string(), options);
    EXPECT_EQ(p.report.holes.size(), 3u);
    EXPECT_EQ(p.rim.size(), 204u);  // the outer rim of the face area is kept
    for (const FilledHole& h : p.report.holes) EXPECT_GT(h.min_angle_degrees, 10.0);
  }
}

}  // namespace
}  // namespace facemorph
