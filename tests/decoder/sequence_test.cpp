// The decoder's side of the temporal model: hole cutting and playing a sequence back.
#include "codec/decoder/sequence/hole_cut.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/meshkit/mesh/topology.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

using testing::kPi;

using testing::sample_nodes;

double area(const TriangleMesh& mesh) {
  double a = 0;
  for (const Face& f : mesh.faces) {
    a += 0.5 * (mesh.positions[static_cast<size_t>(f[1])] - mesh.positions[static_cast<size_t>(f[0])])
                   .cross(mesh.positions[static_cast<size_t>(f[2])] - mesh.positions[static_cast<size_t>(f[0])])
                   .norm();
  }
  return a;
}

TEST(HoleCut, KeepsThePositiveSideAndClipsAlongTheZeroLevel) {
  const DiskGrid grid = make_disk_grid(65);
  const auto flat = sample_nodes(grid, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); });
  // A round hole of radius 0.3 at (0.2, -0.1): level = distance to its outline, negative inside.
  const Vec2 centre(0.2, -0.1);
  std::vector<double> level;
  for (const Vec2& w : grid.nodes) level.push_back((w - centre).norm() - 0.3);
  const TriangleMesh cut = cut_holes(grid, flat, level);
  const MeshTopology topology(cut.faces, cut.vertex_count());
  EXPECT_TRUE(topology.is_manifold());
  ASSERT_EQ(topology.boundary_loops().size(), 2u);  // the rim and the hole
  EXPECT_EQ(topology.euler_characteristic(), 0);    // an annulus
  // Every vertex of the new loop lies on the circle (to the grid's chord error), every vertex's UV
  // is its disk point, and the area is the disk polygon's less the hole's.
  const auto& loops = topology.boundary_loops();
  const auto& hole = loops[0].size() < loops[1].size() ? loops[0] : loops[1];
  for (int v : hole)
    EXPECT_NEAR((cut.positions[static_cast<size_t>(v)].head<2>() - centre).norm(), 0.3, 1e-3);  // the chord error of h = 1/32
  for (int v = 0; v < cut.vertex_count(); ++v) {
    EXPECT_LT((cut.uvs[static_cast<size_t>(v)] - 0.5 * (cut.positions[static_cast<size_t>(v)].head<2>() + Vec2(1, 1))).norm(), 1e-12);
  }
  const double polygon = grid.rim_count / 2.0 * std::sin(2 * kPi / grid.rim_count);
  EXPECT_NEAR(area(cut), polygon - kPi * 0.09, 2e-3);
  // No hole: the whole grid; all inside a hole: nothing.
  EXPECT_EQ(cut_holes(grid, flat, std::vector<double>(grid.nodes.size(), 1.0)).face_count(), static_cast<int>(grid.faces.size()));
  EXPECT_EQ(cut_holes(grid, flat, std::vector<double>(grid.nodes.size(), -1.0)).face_count(), 0);
  testing::expect_error(ErrorCode::kInvalidArgument, "level values", [&] { cut_holes(grid, flat, {1.0}); });
  level[7] = std::nan("");
  testing::expect_error(ErrorCode::kInvalidArgument, "non-finite value at node 7", [&] { cut_holes(grid, flat, level); });
}

// Keyframes of a bump that grows, on a head that turns at constant speed about a vertical axis,
// a mouth-like hole that is closed in the first keyframe and open in the second.
std::shared_ptr<Sequence> turning_bump(SplineKind spline, bool hole) {
  auto sequence = std::make_shared<Sequence>();
  sequence->grid_n = 33;
  sequence->spline = spline;
  sequence->fps = 30;
  sequence->first_time = 0;
  sequence->last_time = 1;
  sequence->pose_centre = Vec3(0, 0, 0.2);
  const GridGeometry geometry(make_disk_grid(33));
  const std::vector<double> times = {0.0, 0.3, 0.55, 1.0};
  for (size_t k = 0; k < times.size(); ++k) {
    Keyframe key;
    key.time = times[k];
    const double s = key.time;
    key.fields = compute_fields(
        geometry,
        sample_nodes(geometry.grid(), [s](const Vec2& w) { return Vec3(w.x(), w.y(), (0.2 + 0.2 * s) * std::exp(-3 * w.squaredNorm())); }),
        Representation::kHLT);
    key.pose.rotation = Eigen::AngleAxisd(0.6 * s, Vec3::UnitY()).toRotationMatrix();
    key.pose.translation = sequence->pose_centre - key.pose.rotation * sequence->pose_centre;  // turning about the centre
    if (hole) {
      for (const Vec2& w : geometry.grid().nodes) {
        // Open (radius 0.3 around (0, -0.4)) from the second keyframe on; closed in the first.
        key.hole_level.push_back(k == 0 ? kHoleLevelBand : std::min((w - Vec2(0, -0.4)).norm() - 0.3, kHoleLevelBand));
      }
    }
    sequence->keyframes.push_back(std::move(key));
  }
  return sequence;
}

TEST(SequenceDecoder, KeyframesComeBackAndTheHeadTurnsAtConstantSpeed) {
  auto sequence = turning_bump(SplineKind::kCatmullRom, false);
  SequenceDecoder decoder(sequence);
  for (const Keyframe& key : sequence->keyframes) {
    const DecodedFrame frame = decoder.decode(key.time, {.reconstruct = {.tolerance = 1e-9}});
    ASSERT_EQ(frame.weights.keys.size(), 1u);
    EXPECT_TRUE(frame.converged);
    const double s = key.time;
    double error = 0;
    for (size_t v = 0; v < frame.grid_positions.size(); ++v) {
      const Vec2& w = decoder.geometry().grid().nodes[v];
      const Vec3 local(w.x(), w.y(), (0.2 + 0.2 * s) * std::exp(-3 * w.squaredNorm()));
      error = std::max(error, (frame.grid_positions[v] - key.pose.apply(local)).norm());
    }
    EXPECT_LT(error, 1e-6) << "t = " << s;
  }
  // Between keyframes the pose is the constant-speed turn (the spline reproduces linear motion).
  for (double t : {0.1, 0.42, 0.8}) {
    const DecodedFrame frame = decoder.decode(t);
    const Eigen::Matrix3d expected = Eigen::AngleAxisd(0.6 * t, Vec3::UnitY()).toRotationMatrix();
    EXPECT_LT((frame.pose.rotation - expected).norm(), 1e-12) << "t = " << t;
    EXPECT_LT((frame.pose.apply(sequence->pose_centre) - sequence->pose_centre).norm(), 1e-12);
  }
}

// A clip decoded frame after frame continues the last frames' correction (decoded − spline of the
// keyframes' surfaces): it must land on the same surfaces as frames started from the spline alone,
// within the tolerance, in fewer steps; a jump in t starts from the spline alone.
TEST(SequenceDecoder, AClipContinuesTheCorrectionInFewerStepsToTheSameSurfaces) {
  auto sequence = turning_bump(SplineKind::kCatmullRom, false);
  SequenceDecoder tight(sequence), alone(sequence), continued(sequence);
  DecodeOptions reference_options, alone_options, continued_options;
  reference_options.reconstruct.tolerance = 1e-11;
  reference_options.continue_correction = alone_options.continue_correction = false;
  int steps_alone = 0, steps_continued = 0;
  double worst_alone = 0, worst_continued = 0;
  for (int i = 0; i <= 30; ++i) {
    const double t = i / 30.0;
    const DecodedFrame reference = tight.decode(t, reference_options);
    const DecodedFrame a = alone.decode(t, alone_options);
    const DecodedFrame c = continued.decode(t, continued_options);
    ASSERT_TRUE(a.converged && c.converged) << "t = " << t;
    steps_alone += a.iterations;
    steps_continued += c.iterations;
    for (size_t v = 0; v < reference.grid_positions.size(); ++v) {
      worst_alone = std::max(worst_alone, (a.grid_positions[v] - reference.grid_positions[v]).norm());
      worst_continued = std::max(worst_continued, (c.grid_positions[v] - reference.grid_positions[v]).norm());
    }
  }
  // The rim spans ~2 units and the tolerance is 1e-5 of it per step: both land within a few steps'
  // worth of the converged surface.
  EXPECT_LT(worst_alone, 1e-4);
  EXPECT_LT(worst_continued, 1e-4);
  EXPECT_LT(steps_continued, steps_alone);
  // After a jump the start is the spline's again: the same steps and surface as a fresh decoder.
  SequenceDecoder fresh(sequence);
  const DecodedFrame jumped = continued.decode(0.42, continued_options);
  const DecodedFrame first = fresh.decode(0.42, continued_options);
  EXPECT_EQ(jumped.iterations, first.iterations);
  for (size_t v = 0; v < first.grid_positions.size(); ++v) ASSERT_EQ(jumped.grid_positions[v], first.grid_positions[v]);
}

// The texture is the keyframes' blend rounded to the nearest byte and clamped (Catmull-Rom weights
// can be negative): against the sum in double precision, never more than rounding apart.
TEST(SequenceDecoder, TexturesBlendToTheNearestByte) {
  auto sequence = turning_bump(SplineKind::kCatmullRom, false);
  std::mt19937 rng(7);
  for (Keyframe& key : sequence->keyframes) {
    key.texture = Image(37, 23, 3);
    for (uint8_t& p : key.texture.pixels) p = static_cast<uint8_t>(rng() % 256);
    key.texture.pixels[5] = 255;  // extremes, where an overshooting weight leaves 0..255
    key.texture.pixels[6] = 0;
  }
  SequenceDecoder decoder(sequence);
  for (double t : {0.0, 0.1, 0.42, 0.8}) {
    const DecodedFrame frame = decoder.decode(t);
    ASSERT_EQ(frame.texture.pixels.size(), 37u * 23u * 3u);
    for (size_t p = 0; p < frame.texture.pixels.size(); ++p) {
      double sum = 0;
      for (size_t i = 0; i < frame.weights.keys.size(); ++i) {
        sum += frame.weights.weights[i] * sequence->keyframes[static_cast<size_t>(frame.weights.keys[i])].texture.pixels[p];
      }
      const double expected = std::clamp(sum, 0.0, 255.0);
      ASSERT_LE(std::abs(frame.texture.pixels[p] - expected), 0.5 + 1e-4) << "t = " << t << ", byte " << p;
    }
  }
  DecodeOptions no_texture;
  no_texture.texture = false;
  EXPECT_TRUE(decoder.decode(0.42, no_texture).texture.empty());
}

TEST(SequenceDecoder, AHoleOpensBetweenKeyframesAlongTheBlendedOutline) {
  auto sequence = turning_bump(SplineKind::kLinear, true);
  SequenceDecoder decoder(sequence);
  // Between keyframes 0 (closed: +band everywhere) and 1 (open, radius 0.3) with weights 1 - s
  // and s, the blend (1 - s) 0.1 + s (r - 0.3) is zero at r = 0.3 - 0.1 (1 - s) / s: the hole
  // opens at s = 0.25 from its centre and grows to its full radius.
  for (const auto& [t, radius] : {std::pair{0.15, 0.2}, std::pair{0.2, 0.25}, std::pair{0.3, 0.3}}) {
    const DecodedFrame frame = decoder.decode(t);
    const MeshTopology topology(frame.mesh.faces, frame.mesh.vertex_count());
    ASSERT_EQ(topology.boundary_loops().size(), 2u) << "t = " << t;
    const auto& loops = topology.boundary_loops();
    const auto& hole = loops[0].size() < loops[1].size() ? loops[0] : loops[1];
    for (int v : hole) {
      const Vec2 w = 2 * frame.mesh.uvs[static_cast<size_t>(v)] - Vec2(1, 1);
      EXPECT_NEAR((w - Vec2(0, -0.4)).norm(), radius, 0.01) << "t = " << t;
    }
  }
  // Before s = 0.25 (t = 0.075) there is no hole; with the fill kept, never.
  const DecodedFrame closed = decoder.decode(0.07);
  EXPECT_EQ(MeshTopology(closed.mesh.faces, closed.mesh.vertex_count()).boundary_loops().size(), 1u);
  DecodeOptions keep_fill;
  keep_fill.cut_holes = false;
  const DecodedFrame kept = decoder.decode(0.3, keep_fill);
  EXPECT_EQ(kept.mesh.face_count(), static_cast<int>(decoder.geometry().grid().faces.size()));
}

TEST(SequenceDecoder, TimesOutsideTheSaneRangeAreNamedOrClamped) {
  SequenceDecoder decoder(turning_bump(SplineKind::kCatmullRom, false));
  // Sane: one keyframe interval past each end: [0 - 0.3, 1 + 0.45].
  EXPECT_NO_THROW(decoder.decode(1.4));
  testing::expect_error(ErrorCode::kOutOfRange, "outside the range", [&] { decoder.decode(1.5); });
  testing::expect_error(ErrorCode::kOutOfRange, "outside the range", [&] { decoder.decode(-0.31); });
  DecodeOptions clamp;
  clamp.clamp_to_sane_range = true;
  EXPECT_DOUBLE_EQ(decoder.decode(9, clamp).time, 1.45);
  testing::expect_error(ErrorCode::kInvalidArgument, "not finite", [&] { decoder.decode(std::nan("")); });
}

TEST(SequenceDecoder, MalformedSequencesAreNamed) {
  auto check = [](const char* fragment, const std::function<void(Sequence&)>& damage) {
    auto sequence = turning_bump(SplineKind::kCatmullRom, true);
    damage(*sequence);
    testing::expect_error(ErrorCode::kInvalidArgument, fragment, [&] { SequenceDecoder decoder(sequence); });
  };
  check("no keyframes", [](Sequence& s) { s.keyframes.clear(); });
  check("keyframe 2: time does not increase", [](Sequence& s) { s.keyframes[2].time = s.keyframes[1].time; });
  check("keyframe 1: fields: tangential_u has", [](Sequence& s) { s.keyframes[1].fields.tangential_u.pop_back(); });
  check("keyframe 3: the pose", [](Sequence& s) { s.keyframes[3].pose.rotation(0, 0) = 2; });
  check("keyframe 1: hole levels present in some", [](Sequence& s) { s.keyframes[0].hole_level.clear(); });
  check("keyframe 2: 3 hole levels", [](Sequence& s) { s.keyframes[2].hole_level.resize(3); });
  check("keyframe 2: a hole level is not finite", [](Sequence& s) { s.keyframes[2].hole_level[5] = std::nan(""); });
  check("keyframe 2: a hole level is not finite", [](Sequence& s) { s.keyframes[2].hole_level.back() = INFINITY; });
  check("fixed-frame nodes differ", [](Sequence& s) {
    const DiskGrid grid = make_disk_grid(33);
    s.keyframes[1].fields = compute_fields(GridGeometry(grid), sample_nodes(grid, [](const Vec2& w) { return Vec3(w.x(), w.y(), 0); }),
                                           Representation::kHLT, {grid.node(16, 16)});
  });
}

}  // namespace
}  // namespace facemorph
