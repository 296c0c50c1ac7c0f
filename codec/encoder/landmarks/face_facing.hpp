// find_face with a hint of where the face looks: for a whole head, whose surface faces no one way.
#pragma once

#include "codec/encoder/landmarks/face_orientation.hpp"

namespace facemorph {

// find_face, but where the surface faces no one way (a whole head) the face region is looked for
// along `facing_hint` (when not null) instead of along each of 26 directions: the encoder passes
// the normals of the frame's filled holes (eyes, mouth, nostrils look out of the face).
FaceOrientation find_face_facing(const TriangleMesh& mesh, const Image* texture, const std::string& name, const Vec3* vertical_hint,
                                 const Vec3* facing_hint, const FaceFindingOptions& options = {});

// How finely find_face_orientation_up_side looks for the mirror plane: the default is
// find_face_orientation's (up to 600 samples, planes every 3° then 0.5° about the best); a coarse
// search (150 samples, every 12° then 2°) ranks a whole head's 26 candidate regions at a tenth of
// the cost before the few best are read in full (find_by_region).
struct MirrorSearch {
  int samples = 600;
  double step_degrees = 3;
  double refine_degrees = 0.5;
};
inline constexpr MirrorSearch kCoarseMirrorSearch{150, 12, 2};

// find_face_orientation, but up is the side of the midline `up_side` points to (when not null and
// within 60° of the midline), whatever the surface's readings say: a whole head's neck lies below
// its face. In a region of a whole head the readings are taken at the region's small scale, on the
// nose rather than the sockets, and ICT's head read up the wrong way on 5 of 12 frames (evidence
// 0.71-0.76) while the others read it right: the registration then turned the face over between them.
FaceOrientation find_face_orientation_up_side(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint, double up_scale,
                                              const Vec3* up_side, const MirrorSearch& search = {});

// Throws kInvalidArgument: frame `name` has no face orientation, because `why`; it advises giving
// the capture its landmarks (what the orientation and the face finding both refuse with).
[[noreturn]] void refuse_face_orientation(const std::string& name, const std::string& why);

}  // namespace facemorph
