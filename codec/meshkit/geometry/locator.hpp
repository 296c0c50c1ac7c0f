// Point location in a planar triangulation (a disk embedding, the shared grid) with a bucket grid.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <optional>
#include <span>
#include <vector>

namespace facemorph {

// A point on a triangulated surface: a face and barycentric coordinates (summing to 1).
struct SurfacePoint {
  int face = -1;
  Vec3 bary = Vec3::Zero();
};

class TriangleLocator {
 public:
  // `points` and `faces` must outlive the locator. About `faces_per_bucket` faces share a bucket.
  TriangleLocator(std::span<const Vec2> points, std::span<const Face> faces, double faces_per_bucket = 2.0);

  // The face containing p (barycentrics clamped into the face when p lies within `tolerance`,
  // relative to the face's size, outside it); nullopt when no face is that close. Where faces
  // overlap (a folded embedding) the one p is deepest inside wins.
  std::optional<SurfacePoint> locate(const Vec2& p, double tolerance = 1e-9) const;

  // Barycentric coordinates of p in face f (may be negative outside it).
  Vec3 barycentric(int face, const Vec2& p) const;

 private:
  std::span<const Vec2> points_;
  std::span<const Face> faces_;
  Vec2 origin_;
  double cell_ = 1;
  int nx_ = 1, ny_ = 1;
  std::vector<int> bucket_start_;
  std::vector<int> bucket_faces_;
  // Each bucket entry's face box, in floats rounded outwards (a box that holds the face's own): a
  // point outside it is outside the face, which locate() skips without its barycentrics (their
  // divisions were a fifth of a texture's resampling onto the disk, profiled on Medusa).
  struct Box {
    float lo_x, lo_y, hi_x, hi_y;
    bool holds(const Vec2& p) const { return p.x() >= lo_x && p.x() <= hi_x && p.y() >= lo_y && p.y() <= hi_y; }
  };
  std::vector<Box> bucket_boxes_;
  static Box outward_box(std::span<const Vec2> points, const Face& face);
};

}  // namespace facemorph
