// Flipped triangles of a disk map: signed areas, their count, and the re-solve that unflips them.
#pragma once

#include "codec/core/geometry/elementary.hpp"
#include "codec/encoder/conformal/conformal.hpp"

#include <vector>

namespace facemorph {

// Faces with non-positive signed area in the embedding w.
int count_flipped(const std::vector<Vec2>& w, const std::vector<Face>& faces);

// Removes flipped triangles from a disk map: the vertices within `rings` of a flipped face (rim
// excluded) are re-solved with mean-value weights, the patch border fixed; the patch doubles until
// no face is flipped. At worst the patch is the whole disk, whose border (the rim on the circle)
// is convex, and the result is then guaranteed to be an embedding. Returns the vertices moved.
// Throws kNumerical when a patch system is singular or even the whole disk stays flipped.
int untangle(DiskMap& map);

// The last stage of the conformal map: orients map.disk counter-clockwise (w -> conj(w) and the rim
// reversed where it is not), counts the flipped faces and untangles them, into map.report. If that
// throws and `fallback_disk` is not empty (the linear map: an embedding by construction), starts
// again from it, reports the linear method and why. QIEM can return without an error and still
// collapse the disk: measured on a 20k-vertex frame with 1 mm of noise, its whole disk within 1e-16.
void finish_disk_map(DiskMap& map, std::vector<Vec2> fallback_disk);

}  // namespace facemorph
