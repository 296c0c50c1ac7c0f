// fmsynth --surround (and --no-face): the synthetic face inside a head-and-shoulders scan, hair
// heaped on one side and a shoulder forward on the other, textured (face, hair, shirt); or the same
// surround with a plain dome and bare skin where the face was, a surface with no face that
// --landmarks auto must refuse (spec/method.md §7.14).
#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/delaunay.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace facemorph {
namespace {

// The scan's extent in the face's material plane (metres): the face is 0.16 x 0.20 in the middle.
constexpr double kLeft = -0.22, kRight = 0.22, kBottom = -0.34, kTop = 0.2;
constexpr int kPixelsPerMetre = 800;

bool on_face(const Vec2& m) {
  const double X = m.x() / SyntheticFace::kHalfWidth, Y = m.y() / SyntheticFace::kHalfHeight;
  return X * X + Y * Y <= 1;
}

// Outside the face's ellipse: hair heaped on the left (seen from the front), a shoulder forward on
// the right; zero on the ellipse, so the surface is continuous.
double surround_height(const Vec2& m) {
  const double X = m.x() / SyntheticFace::kHalfWidth, Y = m.y() / SyntheticFace::kHalfHeight;
  const double out = std::sqrt(X * X + Y * Y) - 1;
  if (out <= 0) return 0;
  const double hair = 0.07 * smoothstep(out / 0.4) * smoothstep((m.y() + 0.05) / 0.08) * smoothstep(-m.x() / 0.06 + 0.3);
  const double shoulder = 0.07 * smoothstep((-0.13 - m.y()) / 0.1) * smoothstep(m.x() / 0.08 + 0.2);
  return hair + shoulder;
}

constexpr std::array<uint8_t, 3> kSkin = {200, 150, 125};

std::array<uint8_t, 3> surround_colour(const Vec2& m) {
  if (m.y() < -0.13) return {40, 60, 130};                             // shirt
  if (surround_height(m) > 0.01 || m.y() > 0.07) return {55, 38, 28};  // hair
  return kSkin;                                                        // neck and ears
}

// Where the face was, without it: a smooth dome as high as the face, no nose, sockets or mouth.
double dome_height(const Vec2& m) {
  return 0.09 * (std::sqrt(std::max(1 - 0.85 * std::pow(m.x() / 0.08, 2) - 0.85 * std::pow(m.y() / 0.1, 2), 0.0)) - std::sqrt(0.15));
}

}  // namespace

std::vector<Vec2> surround_material(double spacing, uint64_t seed) {
  std::mt19937 random(static_cast<unsigned>(seed));
  std::uniform_real_distribution<double> jitter(-0.3 * spacing, 0.3 * spacing);
  std::vector<Vec2> material;
  for (double y = kBottom; y <= kTop + 1e-9; y += spacing) {
    for (double x = kLeft; x <= kRight + 1e-9; x += spacing) {
      const bool edge = x == kLeft || y == kBottom || x + spacing > kRight + 1e-9 || y + spacing > kTop + 1e-9;
      material.emplace_back(x + (edge ? 0 : jitter(random)), y + (edge ? 0 : jitter(random)));
    }
  }
  return material;
}

double surround_spacing(int vertices) { return std::sqrt((kRight - kLeft) * (kTop - kBottom) / std::max(vertices, 100)); }

SurroundedFrame surrounded_frame(const SyntheticFace& face, const std::vector<Vec2>& material, const std::vector<Face>& faces, double time,
                                 const Eigen::Matrix3d& pose, bool with_face) {
  SurroundedFrame frame;
  frame.mesh.faces = faces;
  for (const Vec2& m : material) {
    Vec3 p = face.position(m, time);
    if (!with_face) p.z() = dome_height(m);
    p.z() += surround_height(m);
    frame.mesh.positions.push_back(pose * p);
    frame.mesh.uvs.emplace_back((m.x() - kLeft) / (kRight - kLeft), (m.y() - kBottom) / (kTop - kBottom));
  }
  frame.mesh.uv_faces = frame.mesh.faces;
  const int width = static_cast<int>((kRight - kLeft) * kPixelsPerMetre), height = static_cast<int>((kTop - kBottom) * kPixelsPerMetre);
  frame.texture = Image(width, height, 3);
  for (int j = 0; j < height; ++j) {
    for (int i = 0; i < width; ++i) {
      const Vec2 m(kLeft + (i + 0.5) / width * (kRight - kLeft), kTop - (j + 0.5) / height * (kTop - kBottom));
      const std::array<uint8_t, 3> c = on_face(m) ? (with_face ? face.color(m, time) : kSkin) : surround_colour(m);
      std::copy(c.begin(), c.end(), frame.texture.at(i, j));
    }
  }
  return frame;
}

SurroundedFrame surrounded_frame(const SyntheticFace& face, double spacing, uint64_t seed, double time, const Eigen::Matrix3d& pose,
                                 bool with_face) {
  const std::vector<Vec2> material = surround_material(spacing, seed);
  return surrounded_frame(face, material, delaunay_triangulation(material), time, pose, with_face);
}

}  // namespace facemorph
