#include "codec/meshkit/render/render.hpp"

#include "codec/core/geometry/differential.hpp"  // area_weighted_normals: the decoder's one normal rule
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace facemorph {

SurfaceShader constant_shader(std::array<double, 3> rgb) {
  return [rgb](int, const Vec3&) { return rgb; };
}

namespace {

Vec2 corner_uv(const TriangleMesh& mesh, int face, const Vec3& bary) {
  const Face& t = mesh.uv_faces[static_cast<size_t>(face)];
  return bary[0] * mesh.uvs[static_cast<size_t>(t[0])] + bary[1] * mesh.uvs[static_cast<size_t>(t[1])] +
         bary[2] * mesh.uvs[static_cast<size_t>(t[2])];
}

}  // namespace

SurfaceShader texture_shader(const TriangleMesh& mesh, const Image& texture) {
  if (!mesh.has_uvs() || texture.empty()) return constant_shader({180, 180, 180});
  return [&mesh, &texture](int face, const Vec3& bary) {
    const Vec2 uv = corner_uv(mesh, face, bary);
    return sample_bilinear(texture, uv.x(), uv.y());
  };
}

SurfaceShader checkerboard_shader(const TriangleMesh& mesh, double squares) {
  if (!mesh.has_uvs()) return constant_shader({180, 180, 180});
  return [&mesh, squares](int face, const Vec3& bary) {
    const Vec2 uv = corner_uv(mesh, face, bary) * squares;
    const bool dark = (static_cast<int64_t>(std::floor(uv.x())) + static_cast<int64_t>(std::floor(uv.y()))) & 1;
    return dark ? std::array<double, 3>{40, 60, 120} : std::array<double, 3>{235, 235, 225};
  };
}

std::vector<Vec3> shading_normals(const TriangleMesh& mesh) {
  std::vector<float> packed(3 * mesh.positions.size());
  area_weighted_normals(mesh.positions, mesh.faces, packed);
  std::vector<Vec3> normals(mesh.positions.size());
  for (size_t v = 0; v < normals.size(); ++v) normals[v] = Vec3(packed[3 * v], packed[3 * v + 1], packed[3 * v + 2]);
  return normals;
}

Image render(const TriangleMesh& mesh, const SurfaceShader& shader, const RenderOptions& options, std::span<const Vec3> vertex_normals) {
  if (!vertex_normals.empty() && vertex_normals.size() != mesh.positions.size()) {
    throw Error(ErrorCode::kInvalidArgument,
                "render: " + std::to_string(vertex_normals.size()) + " normals for " + std::to_string(mesh.positions.size()) + " vertices");
  }
  Image image(options.width, options.height, 3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) std::copy(options.background.begin(), options.background.end(), image.at(x, y));
  }
  if (mesh.positions.empty() || mesh.faces.empty()) return image;

  const double yaw = options.yaw_degrees * std::numbers::pi / 180;
  const double pitch = options.pitch_degrees * std::numbers::pi / 180;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(pitch, Vec3::UnitX()) * Eigen::AngleAxisd(yaw, Vec3::UnitY())).toRotationMatrix();
  std::vector<Vec3> p(mesh.positions.size());
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (size_t i = 0; i < p.size(); ++i) p[i] = R * mesh.positions[i];
  // The normals turned as the mesh is (the headlight looks down -z after the turn).
  std::vector<Vec3> turned_normals(vertex_normals.size());
  for (size_t i = 0; i < turned_normals.size(); ++i) turned_normals[i] = R * vertex_normals[i];
  const bool smooth = options.shading && !turned_normals.empty();
  // Fit what is drawn: vertices referenced by faces.
  for (const Face& face : mesh.faces) {
    for (int32_t v : face) {
      const Vec3& q = p[static_cast<size_t>(v)];
      if (!q.allFinite()) continue;
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  const double extent = std::max(hi.x() - lo.x(), hi.y() - lo.y());
  if (!(extent > 0)) return image;
  const double usable = (1 - 2 * options.margin) * std::min(options.width, options.height);
  const double scale = usable / extent;
  const Vec2 center(0.5 * (lo.x() + hi.x()), 0.5 * (lo.y() + hi.y()));
  auto to_screen = [&](const Vec3& q) {
    return Vec3(options.width / 2.0 + (q.x() - center.x()) * scale, options.height / 2.0 - (q.y() - center.y()) * scale, q.z());
  };

  std::vector<double> depth(static_cast<size_t>(options.width) * options.height, -std::numeric_limits<double>::infinity());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Face& face = mesh.faces[f];
    const Vec3& pa = p[static_cast<size_t>(face[0])];
    const Vec3& pb = p[static_cast<size_t>(face[1])];
    const Vec3& pc = p[static_cast<size_t>(face[2])];
    const Vec3 a = to_screen(pa), b = to_screen(pb), c = to_screen(pc);
    if (!a.allFinite() || !b.allFinite() || !c.allFinite()) continue;
    const Vec3 n = (pb - pa).cross(pc - pa);
    const double light = options.shading ? 0.25 + 0.75 * std::abs(n.z()) / std::max(n.norm(), 1e-300) : 1.0;
    // Screen y points down, so orientation flips; both sides of a face are drawn.
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(options.width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(options.height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double w0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) / area;
        const double w1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) / area;
        const double w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const double z = w0 * a.z() + w1 * b.z() + w2 * c.z();
        double& stored = depth[static_cast<size_t>(y) * options.width + x];
        if (z <= stored) continue;
        stored = z;
        const auto rgb = shader(static_cast<int>(f), Vec3(w0, w1, w2));
        double lit = light;
        if (smooth) {
          const Vec3 interpolated = w0 * turned_normals[static_cast<size_t>(face[0])] + w1 * turned_normals[static_cast<size_t>(face[1])] +
                                    w2 * turned_normals[static_cast<size_t>(face[2])];
          const double length = interpolated.norm();
          if (length > 1e-12) lit = 0.25 + 0.75 * std::abs(interpolated.z()) / length;
        }
        uint8_t* out = image.at(x, y);
        for (int k = 0; k < 3; ++k) {
          out[k] = static_cast<uint8_t>(std::clamp(rgb[static_cast<size_t>(k)] * lit, 0.0, 255.0));
        }
      }
    }
  }
  if (options.wireframe) {
    // Edges drawn last and without depth test: meant for flat embeddings and close-ups.
    for (const Face& face : mesh.faces) {
      for (int k = 0; k < 3; ++k) {
        const Vec3 a = to_screen(p[static_cast<size_t>(face[k])]), b = to_screen(p[static_cast<size_t>(face[(k + 1) % 3])]);
        const int steps = static_cast<int>(std::ceil(std::max(std::abs(b.x() - a.x()), std::abs(b.y() - a.y())))) + 1;
        if (!(steps > 0) || steps > 4 * (options.width + options.height)) continue;
        for (int i = 0; i <= steps; ++i) {
          const double t = static_cast<double>(i) / steps;
          const int x = static_cast<int>(a.x() + t * (b.x() - a.x())), y = static_cast<int>(a.y() + t * (b.y() - a.y()));
          if (x < 0 || y < 0 || x >= options.width || y >= options.height) continue;
          std::copy(options.wire_color.begin(), options.wire_color.end(), image.at(x, y));
        }
      }
    }
  }
  return image;
}

}  // namespace facemorph
