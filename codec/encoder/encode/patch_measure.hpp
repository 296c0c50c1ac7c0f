// Measuring a frame patch (spec/method.md §7.19): the p99 point error of a patched frame against its
// captured mesh, exactly as fmbench measures it, and an upper bound of it cheap enough for the
// patch search's many tries.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/meshkit/geometry/distance.hpp"

#include <vector>

namespace facemorph {

// A point of one surface, where on the disk it lies and the offset to the other surface.
struct OffsetSample {
  Vec2 w;
  Vec3 offset;  // to the captured surface, capture coordinates
};

// Each captured vertex to the shown surface and each shown vertex to the captured one, as
// surface_distance measures them (vertices no face uses are left out), with the disk point of the
// shown side (the shown mesh's UV is (w + 1) / 2).
// `to_shown` and `to_captured` locate on `shown` and `captured` (the captured one built once per
// frame: the captured mesh does not move).
std::vector<OffsetSample> offset_samples(const TriangleMesh& shown, const TriangleMesh& captured, const PointToMesh& to_shown,
                                         const PointToMesh& to_captured);

// A patched frame's p99 against its captured mesh, two ways. exact(): surface_distance's (the
// patched surface's own locator, built for each patch: what fmbench measures). approximate(): each
// captured vertex keeps the point of the unpatched surface nearest to it (face and barycentric
// coordinates, found once per frame) and measures to that point as the patch moves it, or to the
// faces the patch moved (a locator of those alone), whichever is nearer: no locator of the whole
// surface per patch. Each distance is to some point of the patched surface, so it is at least the
// exact one, and the approximate p99 is at least the exact p99 (a patch it puts under the bound is
// under it). The shown side is exact (the captured mesh's locator, built once), and only the
// vertices the patch moves are measured again. The patched mesh has the unpatched one's faces (the
// hole cut follows the level alone), so a face index names the same triangle in both. Holds
// references to its arguments, which must outlive it.
class PatchMeasure {
 public:
  PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before);

  const ShownFrame& shown() const { return shown_; }
  const TriangleMesh& captured() const { return captured_; }
  double diagonal() const { return diagonal_; }  // the captured mesh's
  // Each captured vertex to the unpatched surface and each of its nodes to the captured one.
  const std::vector<OffsetSample>& samples() const { return samples_; }

  const PointToMesh& to_captured() const { return to_captured_; }
  double p99_before() const { return p99_before_; }  // surface_distance(captured, before).p99

  TriangleMesh patched(const FramePatch& patch) const {
    return shown_mesh(grid_, patched_positions(grid_, shown_, patch), shown_.hole_level);
  }

  double exact(const FramePatch& patch) const;

  double approximate(const FramePatch& patch) const;

 private:
  struct Anchor {
    int32_t vertex;
    SurfacePoint point;  // on `before`
    double distance;     // to `before`
  };

  // The patched surface's vertices to the captured one: the unpatched distance where a vertex did not move.
  std::vector<double> shown_side(const TriangleMesh& mesh) const;

  const DiskGrid& grid_;
  const ShownFrame& shown_;
  const TriangleMesh& captured_;
  const TriangleMesh& before_;
  PointToMesh to_captured_;
  PointToMesh to_before_;
  std::vector<OffsetSample> samples_;
  double diagonal_ = 0;
  std::vector<double> before_distance_;  // per vertex of `before` to the captured surface; -1: no face uses it
  std::vector<Anchor> anchors_;          // the captured vertices faces use
  double p99_before_ = 0;
};


}  // namespace facemorph
