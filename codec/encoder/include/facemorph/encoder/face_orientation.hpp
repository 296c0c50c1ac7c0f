// Where a face looks and which way is up, from its geometry alone (spec/method.md §7.14): what the
// encoder uses in place of the nose_tip and nose_bridge landmarks when a capture has none.
#pragma once

#include "facemorph/mesh.hpp"

#include <string>

namespace facemorph {

struct FaceOrientation {
  Vec3 nose_tip = Vec3::Zero();  // a vertex of the surface: the most protruding, smoothed
  Vec3 up = Vec3::Zero();        // a point of the surface up the face's midline from the tip (nose_bridge's role)
  Vec3 facing = Vec3::Zero();    // unit: the area-weighted mean normal (out of the face)
  Vec3 vertical = Vec3::Zero();  // unit, towards the forehead, in the face's mirror plane
  double facing_share = 0;       // |Σ area·normal| / Σ area: 1 for a flat face, 0 for a closed one
  double mirror_error = 0;       // RMS distance of the mirrored surface to itself / diagonal, at the plane chosen
  double up_evidence = 0;        // in [0, 1]: how clearly the surface says which way is up
  bool up_from_hint = false;     // the surface did not say; the hint's side was taken
};

// Finds the orientation of `mesh` (a prepared frame: one open surface, faces oriented out of the
// face): the facing direction from the mean normal; the nose tip as the most protruding vertex
// along it (heights smoothed over two rings); the mirror plane through the tip that best maps the
// surface onto itself (faces are nearly symmetric); and up along that plane from two readings of
// the surface: the nose's profile (it falls away more slowly towards the forehead than towards the
// lip) and the eye sockets (deeper beside the midline above the tip than the cheeks below).
// Where the readings do not say which way is up, `vertical_hint` (another frame's `vertical`: a
// face does not turn upside down between frames) decides, if it is not nearly perpendicular.
// Throws kInvalidArgument naming `name` when the surface faces no single direction (a closed or
// whole-head surface), has no mirror plane, or neither the readings nor a hint say which way is
// up: give such a capture its landmarks.
FaceOrientation find_face_orientation(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint = nullptr);

}  // namespace facemorph
