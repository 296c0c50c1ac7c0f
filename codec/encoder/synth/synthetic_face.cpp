// The analytic synthetic face (see codec/encoder/synth/synth.hpp for the model).
#include "format/error.hpp"

#include "codec/core/util/enum_names.hpp"
#include "codec/encoder/synth/synth.hpp"

#include "codec/meshkit/geometry/delaunay.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

constexpr double kA = SyntheticFace::kHalfWidth;
constexpr double kB = SyntheticFace::kHalfHeight;

// Anisotropic Gaussian bump centred at c.
double bump(const Vec2& m, double cx, double cy, double sx, double sy) {
  const double dx = (m.x() - cx) / sx, dy = (m.y() - cy) / sy;
  return std::exp(-0.5 * (dx * dx + dy * dy));
}

double logistic(double x) { return 1.0 / (1.0 + std::exp(-x)); }

double smooth_clamp01(double x) { return std::clamp(x, 0.0, 1.0); }

// Hash-based value noise in [0, 1], smooth (C1) between lattice points.
double hash01(int64_t x, int64_t y, uint64_t seed) {
  uint64_t h = static_cast<uint64_t>(x) * 0x9E3779B97F4A7C15ull ^ static_cast<uint64_t>(y) * 0xC2B2AE3D27D4EB4Full ^ seed;
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 32;
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

double value_noise(const Vec2& m, double cell, uint64_t seed) {
  const double x = m.x() / cell, y = m.y() / cell;
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy);
  double u = x - fx, v = y - fy;
  u = u * u * (3 - 2 * u);
  v = v * v * (3 - 2 * v);
  const double a = hash01(ix, iy, seed), b = hash01(ix + 1, iy, seed);
  const double c = hash01(ix, iy + 1, seed), d = hash01(ix + 1, iy + 1, seed);
  return (a * (1 - u) + b * u) * (1 - v) + (c * (1 - u) + d * u) * v;
}

std::array<double, 3> mix(const std::array<double, 3>& a, const std::array<double, 3>& b, double t) {
  t = smooth_clamp01(t);
  return {a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t};
}

// Distance (approximately, exact on the boundary) from m to the ellipse, positive inside.
double inside_distance(const Vec2& m) {
  const double rho = std::hypot(m.x() / kA, m.y() / kB);
  if (rho < 1e-12) return kA;
  const double gx = m.x() / (kA * kA * rho), gy = m.y() / (kB * kB * rho);
  return (1.0 - rho) / std::hypot(gx, gy);
}

// Cumulative arc length of the ellipse, sampled at `steps` equal angles (last entry = perimeter).
std::vector<double> ellipse_arc_lengths(int steps) {
  std::vector<double> arc(static_cast<size_t>(steps) + 1, 0.0);
  for (int k = 1; k <= steps; ++k) {
    const Vec2 a = SyntheticFace::rim_point(2 * std::numbers::pi * (k - 1) / steps);
    const Vec2 b = SyntheticFace::rim_point(2 * std::numbers::pi * k / steps);
    arc[static_cast<size_t>(k)] = arc[static_cast<size_t>(k) - 1] + (b - a).norm();
  }
  return arc;
}

// Angle θ at which the arc length from θ = 0 reaches `length`.
double angle_at_arc_length(const std::vector<double>& arc, double length) {
  const int steps = static_cast<int>(arc.size()) - 1;
  length = std::fmod(length, arc.back());
  if (length < 0) length += arc.back();
  const auto it = std::upper_bound(arc.begin(), arc.end(), length);
  const int k = std::clamp(static_cast<int>(it - arc.begin()) - 1, 0, steps - 1);
  const double span = arc[static_cast<size_t>(k) + 1] - arc[static_cast<size_t>(k)];
  const double f = span > 0 ? (length - arc[static_cast<size_t>(k)]) / span : 0.0;
  return 2 * std::numbers::pi * (k + f) / steps;
}

}  // namespace

namespace {

constexpr EnumName<Expression> kExpressionNames[] = {{Expression::kBlink, "blink"},
                                                     {Expression::kMouth, "mouth"},
                                                     {Expression::kSmile, "smile"},
                                                     {Expression::kTalk, "talk"},
                                                     {Expression::kMixed, "mixed"}};

}  // namespace

Expression parse_expression(const std::string& name) { return parse_name(kExpressionNames, name, "expression"); }

const char* expression_name(Expression expression) { return name_of(kExpressionNames, expression); }

Vec2 SyntheticFace::rim_point(double theta) { return {kA * std::cos(theta), kB * std::sin(theta)}; }

Vec2 SyntheticFace::texture_coordinate(const Vec2& m) { return {0.5 + 0.5 * m.x() / kA, 0.5 + 0.5 * m.y() / kB}; }

SyntheticFace::SyntheticFace(Expression expression, uint64_t seed, double head_motion_degrees, double speech_rate)
    : expression_(expression), seed_(seed), head_motion_degrees_(head_motion_degrees), speech_rate_(speech_rate) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> spread(-1.0, 1.0);
  for (double& f : identity_) f = 1.0 + 0.1 * spread(rng);

  // Subject's right is -x (the viewer's left), as in a frontal photograph.
  landmarks_ = {
      {"nose_tip", {0, -0.014}},
      {"nose_bridge", {0, 0.012}},
      {"between_eyes", {0, 0.028}},
      {"forehead_top_midline", {0, 0.080}},
      {"chin_bottom_midline", {0, -0.084}},
      {"upper_lip_top_midline", {0, -0.036}},
      {"upper_lip_inner_midline", {0, -0.0435}},
      {"lower_lip_inner_midline", {0, -0.0485}},
      {"lower_lip_bottom_midline", {0, -0.058}},
      {"mouth_corner_right", {-0.023, -0.046}},
      {"mouth_corner_left", {0.023, -0.046}},
      {"right_eye_outer_corner", {-0.044, 0.025}},
      {"right_eye_inner_corner", {-0.020, 0.025}},
      {"right_eye_upper_lid", {-0.032, 0.0305}},
      {"right_eye_lower_lid", {-0.032, 0.0195}},
      {"left_eye_inner_corner", {0.020, 0.025}},
      {"left_eye_outer_corner", {0.044, 0.025}},
      {"left_eye_upper_lid", {0.032, 0.0305}},
      {"left_eye_lower_lid", {0.032, 0.0195}},
      {"right_brow_inner", {-0.016, 0.046}},
      {"right_brow_outer", {-0.050, 0.046}},
      {"left_brow_inner", {0.016, 0.046}},
      {"left_brow_outer", {0.050, 0.046}},
      {"face_oval_right_side", {-0.070, 0.0}},
      {"face_oval_left_side", {0.070, 0.0}},
  };
  // Boundary markers evenly spaced by arc length, rim_0 at the top, counter-clockwise.
  const auto arc = ellipse_arc_lengths(4096);
  const double top = arc.back() / 4;  // θ = π/2
  for (int k = 0; k < 8; ++k) {
    landmarks_.push_back({"rim_" + std::to_string(k), rim_point(angle_at_arc_length(arc, top + k * arc.back() / 8))});
  }

  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int k = 0; k < 90; ++k) {
    const Vec2 m(kA * (2 * unit(rng) - 1), kB * (2 * unit(rng) - 1));
    if (std::hypot(m.x() / kA, m.y() / kB) < 0.92) freckles_.push_back({m.x(), m.y(), 0.0008 + 0.0012 * unit(rng), 0.15 + 0.2 * unit(rng)});
  }
}

ExpressionWeights SyntheticFace::weights(double time) const {
  auto blink = [](double t) {
    const double period = 2.3;
    const double u = std::fmod(t + 0.8, period) - 0.5 * period;
    return std::exp(-(u * u) / (2 * 0.06 * 0.06));
  };
  auto wave = [](double t, double period, double phase) { return 0.5 * (1 - std::cos(2 * std::numbers::pi * t / period + phase)); };
  ExpressionWeights w;
  switch (expression_) {
    case Expression::kBlink: w.blink = blink(time); break;
    case Expression::kMouth: w.jaw = 0.8 * wave(time, 2.0, 0); break;
    case Expression::kSmile:
      w.smile = wave(time, 3.0, 0);
      w.brow = 0.3 * w.smile;
      break;
    case Expression::kTalk:
    case Expression::kMixed: {
      const double scale = expression_ == Expression::kMixed ? 0.8 : 1.0;
      const double mouth_time = speech_rate_ * time;  // only the mouth speeds up: blinks and brows keep their pace
      w.jaw = scale * (0.35 + 0.22 * std::sin(2 * std::numbers::pi * 2.7 * mouth_time) +
                       0.12 * std::sin(2 * std::numbers::pi * 4.1 * mouth_time + 1.3));
      w.pucker = scale * 0.6 * wave(mouth_time, 0.77, 0.4);
      w.brow = 0.25 * (1 + std::sin(2 * std::numbers::pi * 0.6 * time));
      if (expression_ == Expression::kMixed) {
        w.blink = blink(time);
        w.smile = 0.7 * wave(time, 4.0, 0);
      }
      break;
    }
  }
  return w;
}

double SyntheticFace::height(const Vec2& m, const ExpressionWeights& w) const {
  const double X = m.x() / kA, Y = m.y() / kB;
  const double rho2 = X * X + Y * Y;
  double z = 0.09 * (std::sqrt(std::max(1.0 - 0.85 * rho2, 0.0)) - std::sqrt(0.15));
  for (double side : {-1.0, 1.0}) {
    z -= 0.011 * identity_[0] * bump(m, side * 0.032, 0.026, 0.016, 0.011);                       // eye socket
    z += 0.007 * (1 - 0.3 * w.blink) * bump(m, side * 0.032, 0.025, 0.010, 0.0065);               // eyeball
    z += 0.002 * w.blink * bump(m, side * 0.032, 0.026, 0.012, 0.007);                            // closed lid
    z += 0.006 * identity_[1] * bump(m, side * 0.034, 0.047, 0.020, 0.006);                       // brow ridge
    z += 0.004 * bump(m, side * 0.014, -0.020, 0.007, 0.006);                                     // nostril wing
    z += (0.006 + 0.004 * w.smile) * identity_[3] * bump(m, side * 0.046, -0.012, 0.020, 0.018);  // cheek
  }
  z += 0.016 * identity_[2] * bump(m, 0, 0.004, 0.007, 0.022);                                                            // nose bridge
  z += 0.012 * identity_[2] * bump(m, 0, -0.014, 0.011, 0.009);                                                           // nose tip
  z += 0.006 * identity_[4] * bump(m, 0, -0.040, 0.020, 0.0045);                                                          // upper lip
  z += 0.0065 * identity_[4] * bump(m, 0, -0.053, 0.018, 0.005);                                                          // lower lip
  z += 0.004 * w.pucker * bump(m, 0, -0.046, 0.014, 0.010);                                                               // lips pushed out
  z -= (0.003 + 0.012 * w.jaw) * bump(m, 0, -0.046, 0.021 + 0.003 * w.smile - 0.004 * w.pucker, 0.0022 + 0.004 * w.jaw);  // mouth
  z += 0.007 * identity_[5] * bump(m, 0, -0.078, 0.020, 0.011);                                                           // chin
  return z;
}

Vec2 SyntheticFace::displacement(const Vec2& m, const ExpressionWeights& w) const {
  Vec2 d = Vec2::Zero();
  // Jaw: everything below the mouth line drops, fading sideways. |∇d| <= 0.5: a diffeomorphism.
  d.y() -= 0.012 * w.jaw * logistic((-0.044 - m.y()) / 0.006) * std::exp(-(m.x() * m.x()) / (0.05 * 0.05));
  for (double side : {-1.0, 1.0}) {
    const double corner = bump(m, side * 0.023, -0.046, 0.014, 0.014);
    d.x() += side * (0.005 * w.smile - 0.005 * w.pucker) * corner;
    d.y() += 0.004 * w.smile * corner;
    d.y() += 0.005 * w.brow * bump(m, side * 0.034, 0.047, 0.025, 0.015);
  }
  return d;
}

Vec3 SyntheticFace::head_pose(const Vec3& p, double time) const {
  if (head_motion_degrees_ == 0) return p;
  const double amplitude = head_motion_degrees_ * std::numbers::pi / 180.0;
  const double yaw = amplitude * std::sin(2 * std::numbers::pi * 0.15 * time);
  const double pitch = 0.5 * amplitude * std::sin(2 * std::numbers::pi * 0.23 * time + 1.0);
  const double roll = 0.3 * amplitude * std::sin(2 * std::numbers::pi * 0.11 * time + 2.0);
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(yaw, Vec3::UnitY()) * Eigen::AngleAxisd(pitch, Vec3::UnitX()) * Eigen::AngleAxisd(roll, Vec3::UnitZ()))
          .toRotationMatrix();
  const Vec3 pivot(0, -0.12, -0.05);  // roughly the neck
  return R * (p - pivot) + pivot;
}

Vec3 SyntheticFace::unposed_position(const Vec2& material, double time) const {
  const ExpressionWeights w = weights(time);
  const Vec2 xy = material + displacement(material, w);
  return Vec3(xy.x(), xy.y(), height(material, w));
}

Vec3 SyntheticFace::position(const Vec2& material, double time) const { return head_pose(unposed_position(material, time), time); }

Vec3 SyntheticFace::normal(const Vec2& material, double time) const {
  const double h = 1e-6;
  const Vec3 ds = position(material + Vec2(h, 0), time) - position(material - Vec2(h, 0), time);
  const Vec3 dt = position(material + Vec2(0, h), time) - position(material - Vec2(0, h), time);
  return ds.cross(dt).normalized();
}

std::array<uint8_t, 3> SyntheticFace::color(const Vec2& m, double time) const {
  const ExpressionWeights w = weights(time);
  const double tone = 1.0 + 0.07 * (value_noise(m, 0.012, seed_) - 0.5) + 0.05 * (value_noise(m, 0.0015, seed_ + 7) - 0.5);
  std::array<double, 3> c = {226 * tone, 178 * tone, 152 * tone};
  for (const auto& f : freckles_) {
    const double r = std::hypot(m.x() - f[0], m.y() - f[1]) / f[2];
    if (r < 1) c = mix(c, {150, 95, 70}, f[3] * (1 - r * r));
  }
  for (double side : {-1.0, 1.0}) {
    const double brow = bump(m, side * 0.034, 0.049, 0.018, 0.0042);
    c = mix(c, {75, 52, 40}, (brow - 0.35) / 0.3);
  }
  // Lips, and the dark mouth interior showing as the jaw opens.
  const double lip = std::hypot(m.x() / 0.024, (m.y() + 0.047) / 0.0115);
  c = mix(c, {178, 84, 92}, (1.0 - lip) / 0.15);
  const double opening = (0.0008 + 0.0045 * w.jaw) * std::max(0.0, 1 - std::pow(m.x() / 0.021, 2));
  if (std::abs(m.y() + 0.046) < opening) c = {70, 25, 30};
  // Eyes: sclera, iris, pupil; the upper lid descends with the blink.
  for (double side : {-1.0, 1.0}) {
    const Vec2 e(side * 0.032, 0.025);
    const double inside = std::hypot((m.x() - e.x()) / 0.012, (m.y() - e.y()) / 0.0055);
    if (inside >= 1) continue;
    const double lid = e.y() + 0.0055 - w.blink * 0.0112;
    if (m.y() > lid) {
      c = {205, 150, 130};
    } else {
      const double r = (m - e).norm();
      c = r < 0.0022   ? std::array<double, 3>{15, 15, 20}
          : r < 0.0052 ? std::array<double, 3>{70, 105, 125}
                       : std::array<double, 3>{238, 236, 230};
    }
    if (std::abs(m.y() - lid) < 0.0006) c = {40, 30, 30};  // lashes
  }
  return {static_cast<uint8_t>(std::clamp(c[0], 0.0, 255.0)), static_cast<uint8_t>(std::clamp(c[1], 0.0, 255.0)),
          static_cast<uint8_t>(std::clamp(c[2], 0.0, 255.0))};
}

MaterialSampling sample_material_ellipse(int vertices, bool jitter_per_frame, uint64_t frame_seed) {
  if (vertices < 16) throw Error(ErrorCode::kInvalidArgument, "a synthetic face needs at least 16 vertices");
  std::mt19937_64 rng(jitter_per_frame ? frame_seed * 0x9E3779B97F4A7C15ull + 17 : 12345);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double target = vertices;
  if (jitter_per_frame) target *= 1.0 + 0.1 * (2 * unit(rng) - 1);
  const double area = std::numbers::pi * kA * kB;
  const auto arc = ellipse_arc_lengths(4096);
  // Spacing d of a hexagonal lattice giving `target` points, boundary samples included.
  double d = std::sqrt(area / (target * std::sqrt(3.0) / 2));
  d *= std::sqrt(1.0 + arc.back() / d / target);  // the boundary takes its share of the budget

  MaterialSampling sampling;
  const int rim = std::max(8, static_cast<int>(std::lround(arc.back() / d)));
  const double phase = jitter_per_frame ? unit(rng) * arc.back() : 0.0;
  for (int k = 0; k < rim; ++k) {
    sampling.points.push_back(SyntheticFace::rim_point(angle_at_arc_length(arc, phase + k * arc.back() / rim)));
  }
  sampling.boundary_count = rim;

  const double angle = jitter_per_frame ? unit(rng) * std::numbers::pi / 3 : 0.1;
  const Vec2 offset = jitter_per_frame ? Vec2(unit(rng) * d, unit(rng) * d) : Vec2(0.3 * d, 0.2 * d);
  const Eigen::Rotation2Dd rotate(angle);
  const double row = d * std::sqrt(3.0) / 2;
  const int span = static_cast<int>(std::ceil(1.5 * kB / d)) + 2;
  for (int j = -span; j <= span; ++j) {
    for (int i = -span; i <= span; ++i) {
      Vec2 lattice(i * d + (j & 1) * 0.5 * d, j * row);
      lattice += offset + Vec2((unit(rng) - 0.5) * 0.5 * d, (unit(rng) - 0.5) * 0.5 * d);
      const Vec2 m = rotate * lattice;
      if (inside_distance(m) >= 0.55 * d) sampling.points.push_back(m);
    }
  }
  sampling.faces = delaunay_triangulation(sampling.points);
  return sampling;
}

TriangleMesh SyntheticFace::truth_mesh(double time, int vertices) const {
  const MaterialSampling sampling = sample_material_ellipse(vertices, false, 0);
  TriangleMesh mesh;
  mesh.faces = sampling.faces;
  mesh.positions.reserve(sampling.points.size());
  for (const Vec2& m : sampling.points) {
    mesh.positions.push_back(position(m, time));
    mesh.uvs.push_back(texture_coordinate(m));
  }
  mesh.uv_faces = mesh.faces;
  return mesh;
}

}  // namespace facemorph
