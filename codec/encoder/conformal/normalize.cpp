// Landmark normalisation: the disk Möbius map sending the centre landmark to 0, the direction one up.
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include "codec/encoder/conformal/untangle.hpp"

#include <cmath>
#include <numbers>

namespace facemorph {

Vec2 disk_point(const DiskMap& map, const SurfacePoint& point) {
  const Face& f = map.surface.faces[static_cast<size_t>(point.face)];
  return point.bary[0] * map.disk[static_cast<size_t>(f[0])] + point.bary[1] * map.disk[static_cast<size_t>(f[1])] +
         point.bary[2] * map.disk[static_cast<size_t>(f[2])];
}

void normalize(DiskMap& map, const Vec3& centre, const Vec3& direction) {
  const PointToMesh to_surface(map.surface);
  const SurfacePoint c = to_surface.closest(centre), d = to_surface.closest(direction);
  // Möbius maps are not affine, so a landmark's interpolated disk point moves slightly when the
  // map is transformed. Iterating to the fixed point (centre interpolates to 0, direction onto the
  // positive imaginary axis, in the final coordinates) makes the result independent of whatever
  // Möbius map the disk came with.
  for (int iteration = 0; iteration < 20; ++iteration) {
    const Complex cw = to_complex(disk_point(map, c));
    if (std::abs(cw) >= 1) throw Error(ErrorCode::kInvalidArgument, "the centre landmark lies on the boundary of the face");
    const DiskMoebius m = DiskMoebius::normalizing(cw, to_complex(disk_point(map, d)));
    for (Vec2& w : map.disk) w = m(w);
    for (int v : map.rim) map.disk[static_cast<size_t>(v)].normalize();
    map.normalization = m.after(map.normalization);
    if (std::abs(m.a) < 1e-15 && std::abs(std::remainder(m.theta, 2 * std::numbers::pi)) < 1e-15) break;
  }
  // In floating point a Möbius map can turn over triangles whose disk area is ~1e-18 (crowded
  // regions); the map keeps its no-flip guarantee.
  map.report.untangled_vertices += untangle(map);
}

}  // namespace facemorph
