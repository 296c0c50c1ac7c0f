// Measuring a frame patch (spec/method.md §7.19): the p99 point error of a patched frame against its
// captured mesh, exactly as fmbench measures it, and an upper bound of it cheap enough for the
// patch search's many tries.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/patch_solve.hpp"
#include "codec/meshkit/geometry/distance.hpp"

#include <cstddef>
#include <vector>

namespace facemorph {

// What a frame's unpatched surface measured against its captured mesh, all that exact() needs of it:
// the fit keeps it between its passes (12 bytes a captured vertex, 8 a node) where it keeps the
// decoded frames, so that a frame measured again with other patches queries only what they moved.
struct UnpatchedDistances {
  std::vector<double> shown;             // each vertex of the unpatched mesh to the captured surface; -1: no face uses it
  std::vector<int32_t> anchor_face;      // each captured vertex faces use (in order): its nearest face of the unpatched mesh
  std::vector<double> anchor_squared;    // and its squared distance to it (infinity: no face)
  double p99 = 0;                        // surface_distance(captured, unpatched).p99
  size_t bytes() const { return shown.size() * sizeof(double) + anchor_face.size() * (sizeof(int32_t) + sizeof(double)); }
};

// A patched frame's p99 against its captured mesh, two ways. exact(): surface_distance's, to the
// bit (what fmbench measures), but querying only what the patch moved: a vertex of the shown mesh
// that did not move keeps its distance; a captured vertex whose nearest face did not move is nearer
// only to a moved face (a locator of those alone), and one whose face moved searches the still faces
// (the unpatched locator, skipping the moved ones) and the moved ones. approximate(): each
// captured vertex measures to its nearest point of the unpatched surface as the patch moves it, or
// to the moved faces, whichever is nearer (no search of the still faces): each distance is to some
// point of the patched surface, so it is at least the exact one, and the approximate p99 is at
// least the exact p99 (a patch it puts under the bound is under it). The patched mesh has the
// unpatched one's faces (the hole cut follows the level alone), so a face index names the same
// triangle in both. Holds references to its arguments, which must outlive it; one thread's at a time.
class PatchMeasure {
 public:
  // Measures the unpatched frame: one closest-point search for each vertex of either mesh.
  PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before);
  // With what an earlier PatchMeasure of the same frame measured (distances()): no search until a
  // patch moves something; exact() alone (samples() is empty, approximate() and samples_of() throw).
  PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before,
               UnpatchedDistances distances);

  const ShownFrame& shown() const { return shown_; }
  const TriangleMesh& captured() const { return captured_; }
  double diagonal() const { return diagonal_; }  // the captured mesh's
  // Each captured vertex to the unpatched surface and each of its vertices to the captured one, as
  // surface_distance measures them (vertices no face uses left out), with the disk point of the
  // shown side (the shown mesh's UV is (w + 1) / 2) and the offset to the captured surface.
  const std::vector<OffsetSample>& samples() const { return samples_; }
  // The same for `mesh`, the shown mesh with a patch (patched()): the samples a search of the whole
  // patched mesh would give, in the same order, from searches of what the patch moved.
  std::vector<OffsetSample> samples_of(const TriangleMesh& mesh) const;

  double p99_before() const { return distances_.p99; }  // surface_distance(captured, before).p99
  const UnpatchedDistances& distances() const { return distances_; }

  TriangleMesh patched(const FramePatch& patch) const {
    return shown_mesh(grid_, patched_positions(grid_, shown_, patch), shown_.hole_level);
  }

  double exact(const FramePatch& patch) const { return exact_at(patched_positions(grid_, shown_, patch)); }
  // exact() for the shown frame's nodes moved to `positions` (a patch, or patches interpolated in t).
  double exact_at(const std::vector<Vec3>& positions) const;

  double approximate(const FramePatch& patch) const;

 private:
  class MovedFaces;

  // The references and locators alone (both public constructors start here).
  PatchMeasure(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, const TriangleMesh& before, std::nullptr_t);

  // The patched surface's vertices to the captured one: the unpatched distance where a vertex did not move.
  std::vector<double> shown_side(const TriangleMesh& mesh) const;
  // The nearest point of the patched surface to anchor a (face: an index of the patched mesh, bary
  // where its search found it) and its squared distance.
  SurfacePoint nearest_patched(size_t a, const MovedFaces& moved, double& squared) const;
  Vec3 anchor_position(size_t a) const { return captured_.positions[static_cast<size_t>(anchor_vertex_[a])]; }

  const DiskGrid& grid_;
  const ShownFrame& shown_;
  const TriangleMesh& captured_;
  const TriangleMesh& before_;
  PointToMesh to_captured_;
  PointToMesh to_before_;
  double diagonal_ = 0;
  UnpatchedDistances distances_;
  std::vector<int32_t> anchor_vertex_;  // the captured vertices faces use
  std::vector<OffsetSample> samples_;
  // Where each anchor's and each shown vertex's sample sits in samples_ (-1: none), for samples_of.
  std::vector<int32_t> anchor_sample_, shown_sample_;
  // Each unpatched vertex's nearest captured face (the first constructor's; empty with kept
  // distances): where a search for the vertex moved a little starts (closest_from).
  std::vector<int32_t> shown_face_;
  // shown_side's last position of each vertex and its distance (NaN: none yet): a measure is one
  // thread's (one frame's fit), so its const methods may keep this.
  mutable std::vector<Vec3> last_position_;
  mutable std::vector<double> last_distance_;
};

}  // namespace facemorph
