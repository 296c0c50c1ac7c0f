// The face's orientation from geometry alone, against the landmarks the captures carry: fmsynth's
// faces (seeds, expressions, head motion, remeshing, noise) and, when ../shared is there, real ones.
#include "codec/encoder/landmarks/face_orientation.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "codec/meshkit/geometry/distance.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace facemorph {
namespace {

struct Found {
  double tip_error = 0;   // distance to the nose_tip landmark / diagonal
  double up_degrees = 0;  // angle between the found up direction and nose_tip -> nose_bridge
};

Found compare(const TriangleMesh& mesh, const Vec3& nose_tip, const Vec3& nose_bridge, const std::string& name) {
  PrepareOptions options;
  options.keep_largest_component = true;
  const PreparedFrame prepared = prepare_frame(mesh, name, options);
  const FaceOrientation o = find_face_orientation(prepared.mesh, name);
  Found f;
  f.tip_error = (o.nose_tip - nose_tip).norm() / bounding_box_diagonal(prepared.mesh.positions);
  const Vec3 found = (o.up - o.nose_tip).normalized(), given = (nose_bridge - nose_tip).normalized();
  // The landmarks' up direction projected off the facing direction, like the found one.
  const Vec3 given_flat = (given - given.dot(o.facing) * o.facing).normalized();
  const Vec3 found_flat = (found - found.dot(o.facing) * o.facing).normalized();
  f.up_degrees = std::acos(std::clamp(given_flat.dot(found_flat), -1.0, 1.0)) * 180 / std::numbers::pi;
  std::printf("%s: tip %.2f%% of the diagonal off, up %.1f° off (mirror %.2f%%, nose %.2f, up evidence %.2f, facing %.2f)\n", name.c_str(),
              100 * f.tip_error, f.up_degrees, 100 * o.mirror_error, o.nose_prominence, o.up_evidence, o.facing_share);
  return f;
}

TEST(FaceOrientation, SyntheticFacesAgreeWithTheirLandmarks) {
  const struct {
    Expression expression;
    uint64_t seed;
    double head_motion;
    double time;
  } cases[] = {{Expression::kMixed, 1, 0, 0.5},
               {Expression::kTalk, 2, 25, 1.3},
               {Expression::kSmile, 3, 0, 0.8},
               {Expression::kMouth, 4, 15, 0.25},
               {Expression::kBlink, 5, 30, 1.9}};
  for (const auto& c : cases) {
    const SyntheticFace face(c.expression, c.seed, c.head_motion);
    Vec3 tip, bridge;
    for (const NamedPoint& p : face.landmarks()) {
      if (p.name == "nose_tip") tip = face.position(p.material, c.time);
      if (p.name == "nose_bridge") bridge = face.position(p.material, c.time);
    }
    const Found f = compare(face.truth_mesh(c.time, 8000), tip, bridge, "synth seed " + std::to_string(c.seed));
    EXPECT_LT(f.tip_error, 0.015);
    EXPECT_LT(f.up_degrees, 10.0);
  }
}

// What has no face orientation is refused by name: a closed surface faces every way; a flat disk
// has no nose to say which way is up.
TEST(FaceOrientation, SurfacesWithoutAFaceAreRefusedByName) {
  testing::expect_error(ErrorCode::kInvalidArgument, "ball.obj: no face orientation found: the surface faces no single direction",
                        [] { find_face_orientation(testing::icosphere(1, 2), "ball.obj"); });
  const TriangleMesh flat = testing::polar_disk(12, 48, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0.3 * (1 - w.squaredNorm())); });
  testing::expect_error(ErrorCode::kInvalidArgument, "dome.obj: no face orientation found",
                        [&] { find_face_orientation(flat, "dome.obj"); });
}

// Frames across the Medusa capture (468-vertex MediaPipe meshes: laughs, squints, head motion)
// and the ICT face (its neutral mesh; the landmarks are its vertices 4857 and 978, as make_capture.py
// lists them).
TEST(FaceOrientation, RealFacesAgreeWithTheirLandmarks) {
  const auto data = testing::shared_data();
  if (data.empty()) GTEST_SKIP() << "../shared/data absent";
  const Capture medusa = read_capture(data / "medusa-mediapipe-4d/capture");
  const int tip = medusa.landmark_index("nose_tip"), bridge = medusa.landmark_index("nose_bridge");
  ASSERT_GE(tip, 0);
  ASSERT_GE(bridge, 0);
  double worst_tip = 0, worst_up = 0;
  // Every fourth frame (58 of 232, 7.5 frames a second of a 30 fps capture: every laugh and squint
  // lasts longer than that); every sixteenth under AddressSanitizer. All 232 took 40 s plain and
  // 620 s there; the whole capture is fmbench conformal's to sweep.
  const size_t stride = testing::kAddressSanitizer ? 16 : 4;
  for (size_t i = 0; i < medusa.frames.size(); i += stride) {
    const Found f = compare(read_mesh(medusa.mesh_path(i), {.allow_missing_texture = true}), medusa.landmarks[i][static_cast<size_t>(tip)],
                            medusa.landmarks[i][static_cast<size_t>(bridge)], "medusa " + std::to_string(i));
    worst_tip = std::max(worst_tip, f.tip_error);
    worst_up = std::max(worst_up, f.up_degrees);
  }
  std::printf("medusa, %zu frames (every %zu): worst tip %.2f%% of the diagonal, worst up %.1f°\n", medusa.frames.size(), stride,
              100 * worst_tip, worst_up);
  EXPECT_LT(worst_tip, 0.02);
  EXPECT_LT(worst_up, 15.0);
  const TriangleMesh ict = read_mesh(data / "ict-facekit/derived/face_area_neutral.obj", {.allow_missing_texture = true});
  ASSERT_GT(ict.vertex_count(), 4857);
  const Found f = compare(ict, ict.positions[4857], ict.positions[978], "ict neutral");
  EXPECT_LT(f.tip_error, 0.02);
  EXPECT_LT(f.up_degrees, 15.0);
}

}  // namespace
}  // namespace facemorph
