// find_face with a hint of where the face looks: for a whole head, whose surface faces no one way.
#pragma once

#include "facemorph/encoder/face_orientation.hpp"

namespace facemorph {

// find_face, but where the surface faces no one way (a whole head) the face region is looked for
// along `facing_hint` (when not null) instead of along each of 26 directions: the encoder passes
// the normals of the frame's filled holes (eyes, mouth, nostrils look out of the face).
FaceOrientation find_face_facing(const TriangleMesh& mesh, const Image* texture, const std::string& name, const Vec3* vertical_hint,
                                 const Vec3* facing_hint, const FaceFindingOptions& options = {});

}  // namespace facemorph
