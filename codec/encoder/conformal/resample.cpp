#include "codec/encoder/conformal/resample.hpp"

#include "codec/encoder/imageio/image_io.hpp"
#include "codec/meshkit/render/render.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {

std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, const DiskGrid& grid) {
  return resample_positions(inverse, grid.nodes);
}

std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, std::span<const Vec2> points) {
  std::vector<Vec3> positions(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec2 w = points[i].norm() > 1 ? Vec2(points[i].normalized()) : points[i];
    const auto hit = inverse.locate(w);
    if (!hit) throw Error(ErrorCode::kNumerical, "disk point " + std::to_string(i) + " lies outside the disk map");
    positions[i] = inverse.position(*hit);
  }
  return positions;
}

Image resample_texture(const DiskMap& map, const InverseDiskMap& inverse, const Image& texture, int size) {
  if (!map.surface.has_uvs()) throw Error(ErrorCode::kMissingTexture, "the frame has no texture coordinates");
  if (size < 2 || size > 16384) throw Error(ErrorCode::kInvalidArgument, "texture size must be in [2, 16384]");
  Image out(size, size, 3);
  std::vector<uint8_t> done(static_cast<size_t>(size) * size, 0);
  auto to_pixel = [size](const Vec2& w) { return Vec2((w.x() + 1) * 0.5 * size - 0.5, (1 - w.y()) * 0.5 * size - 0.5); };
  auto put = [&](int x, int y, const Vec2& uv) {
    const auto rgb = sample_bilinear(texture, uv.x(), uv.y());
    uint8_t* p = out.at(x, y);
    for (int c = 0; c < 3; ++c) p[c] = static_cast<uint8_t>(std::clamp(std::lround(rgb[static_cast<size_t>(c)]), 0L, 255L));
    done[static_cast<size_t>(y) * size + x] = 1;
  };
  // Rasterise the disk triangles: every texel centre inside one takes its barycentric UV.
  const auto& faces = map.surface.faces;
  for (size_t f = 0; f < faces.size(); ++f) {
    const Vec2 a = to_pixel(map.disk[static_cast<size_t>(faces[f][0])]), b = to_pixel(map.disk[static_cast<size_t>(faces[f][1])]),
               c = to_pixel(map.disk[static_cast<size_t>(faces[f][2])]);
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (area == 0) continue;
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(size - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(size - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
    const Face& t = map.surface.uv_faces[f];
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double w0 = ((b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x)) / area;
        const double w1 = ((c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x)) / area;
        const double w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        put(x, y,
            w0 * map.surface.uvs[static_cast<size_t>(t[0])] + w1 * map.surface.uvs[static_cast<size_t>(t[1])] +
                w2 * map.surface.uvs[static_cast<size_t>(t[2])]);
      }
    }
  }
  // The rest: thin gaps between rim chords and the circle, and the corners outside the disk.
  for (int y = 0; y < size; ++y) {
    for (int x = 0; x < size; ++x) {
      if (done[static_cast<size_t>(y) * size + x]) continue;
      Vec2 w(2 * (x + 0.5) / size - 1, 1 - 2 * (y + 0.5) / size);
      if (w.norm() > 1) w.normalize();
      const auto hit = inverse.locate(w);
      if (hit) put(x, y, inverse.texture_uv(*hit));
    }
  }
  return out;
}

void TextureSource::check(const DiskMap& map) const {
  if (image_ && !map.surface.has_uvs()) throw Error(ErrorCode::kMissingTexture, "the frame has no texture coordinates");
  if (!image_ && !map.surface.has_colours()) throw Error(ErrorCode::kMissingTexture, "the frame has no vertex colours");
}

std::array<double, 3> TextureSource::sample(const InverseDiskMap& inverse, const SurfacePoint& p) const {
  if (image_) {
    const Vec2 uv = inverse.texture_uv(p);
    return sample_bilinear(*image_, uv.x(), uv.y());
  }
  // Colours are interpolated as stored (linear 0..1) and coded to 8 bits like an image's texels.
  const Vec3 c = inverse.colour(p);
  return {255 * c.x(), 255 * c.y(), 255 * c.z()};
}

std::optional<TextureSource> frame_texture_source(const DiskMap& map, const std::filesystem::path& texture, Image& image) {
  if (!texture.empty() && map.surface.has_uvs()) {
    image = read_image(texture);
    return TextureSource::image(image);
  }
  if (map.surface.has_colours()) return TextureSource::vertex_colours();
  return std::nullopt;
}

Image resample_texture(const InverseDiskMap& inverse, const Image& texture, int size, const DiskWarp& warp) {
  return resample_texture(inverse, TextureSource::image(texture), size, warp);
}

Image resample_texture(const InverseDiskMap& inverse, const TextureSource& source, int size, const DiskWarp& warp) {
  if (size < 2 || size > 16384) throw Error(ErrorCode::kInvalidArgument, "texture size must be in [2, 16384]");
  // The warp on a lattice of every 4th texel centre (plus the last), interpolated between.
  const int stride = 4, lattice = (size - 1) / stride + 2;
  auto texel_disk = [size](double x, double y) { return Vec2(2 * (x + 0.5) / size - 1, 1 - 2 * (y + 0.5) / size); };
  std::vector<Vec2> warped(static_cast<size_t>(lattice) * lattice);
  for (int j = 0; j < lattice; ++j) {
    for (int i = 0; i < lattice; ++i) {
      Vec2 w = texel_disk(std::min(i * stride, size - 1), std::min(j * stride, size - 1));
      if (w.norm() > 1) w.normalize();  // outside the disk a texel repeats the rim along its ray
      warped[static_cast<size_t>(j) * lattice + i] = w;
    }
  }
  warp(warped);
  Image out(size, size, 3);
  for (int y = 0; y < size; ++y) {
    const int j = std::min(y / stride, lattice - 2);
    const int y0 = j * stride, y1 = std::min((j + 1) * stride, size - 1);
    const double fy = y1 > y0 ? static_cast<double>(y - y0) / (y1 - y0) : 0.0;
    for (int x = 0; x < size; ++x) {
      const int i = std::min(x / stride, lattice - 2);
      const int x0 = i * stride, x1 = std::min((i + 1) * stride, size - 1);
      const double fx = x1 > x0 ? static_cast<double>(x - x0) / (x1 - x0) : 0.0;
      auto at = [&](int a, int b) { return warped[static_cast<size_t>(b) * lattice + a]; };
      Vec2 w = (1 - fy) * ((1 - fx) * at(i, j) + fx * at(i + 1, j)) + fy * ((1 - fx) * at(i, j + 1) + fx * at(i + 1, j + 1));
      if (w.norm() > 1) w.normalize();
      const auto hit = inverse.locate(w);
      if (!hit)
        throw Error(ErrorCode::kNumerical, "texel (" + std::to_string(x) + ", " + std::to_string(y) + ") maps outside the disk map");
      const auto rgb = source.sample(inverse, *hit);
      uint8_t* p = out.at(x, y);
      for (int c = 0; c < 3; ++c) p[c] = static_cast<uint8_t>(std::clamp(std::lround(rgb[static_cast<size_t>(c)]), 0L, 255L));
    }
  }
  return out;
}

}  // namespace facemorph
