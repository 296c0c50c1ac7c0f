// Where a face looks and which way is up, from its geometry alone (spec/method.md §7.14): what the
// encoder uses in place of the nose_tip and nose_bridge landmarks when a capture has none.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"

#include <cstdint>
#include <functional>
#include <string>

namespace facemorph {

// A face mirrored in its best plane lands within this share of its bounding-box diagonal of itself
// (expressions included); a surface that does not is no face.
inline constexpr double kMaxFaceMirrorError = 0.03;

// How a frame's orientation was found (find_face): the order in which find_face tries them.
enum class FaceFindingMethod : uint8_t {
  kWholeSurface = 0,  // the mirror plane of the whole surface
  kTexture = 1,       // a face detected in a rendered view of the textured surface, its region read as a face
  kFaceRegion = 2,    // the mirror plane of the region around the most protruding point (no texture, or none detected)
};
const char* face_finding_method_name(FaceFindingMethod method);  // "whole surface", "texture", "face region"

struct FaceOrientation {
  Vec3 nose_tip = Vec3::Zero();  // a vertex of the surface: the most protruding, smoothed
  Vec3 up = Vec3::Zero();        // a point of the surface up the face's midline from the tip (nose_bridge's role)
  Vec3 facing = Vec3::Zero();    // unit: the area-weighted mean normal (out of the face)
  Vec3 vertical = Vec3::Zero();  // unit, towards the forehead, in the face's mirror plane
  double facing_share = 0;       // |Σ area·normal| / Σ area: 1 for a flat face, 0 for a closed one
  double mirror_error = 0;       // RMS distance of the mirrored surface to itself / diagonal, at the plane chosen
  // How sharply the surface falls away from the tip along the midline, between 2% and 6% of the
  // diagonal, on its steeper side (towards the lip on a face): mean drop per unit distance. A nose
  // falls steeply; a dome's top, as symmetric as a face, barely falls.
  double nose_prominence = 0;
  double up_evidence = 0;     // in [0, 1]: how clearly the surface says which way is up
  bool up_from_hint = false;  // the surface did not say; the hint's side was taken
  FaceFindingMethod method = FaceFindingMethod::kWholeSurface;
  // In [0, 1]: how sure the finding is. Geometry: 1 - mirror_error / 3% (the largest accepted);
  // texture: half the detector's neighbour count / 12, capped at 1 (a detection alone is coarse);
  // both readings, where both hold, combined as independent ones (1 - (1 - g)(1 - t)).
  double confidence = 0;
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
// up: give such a capture its landmarks. `up` is taken 8% of `up_scale` (metres; 0: the mesh's
// diagonal) up the midline: a region of a larger scan gives the scan's measure, so that every frame
// of a capture places it at one distance whichever region was read.
FaceOrientation find_face_orientation(const TriangleMesh& mesh, const std::string& name, const Vec3* vertical_hint = nullptr,
                                      double up_scale = 0);

struct FaceFindingOptions {
  bool whole_surface = true;  // each step may be turned off (the tests show what each finds alone)
  bool texture = true;
  bool face_region = true;
  // Called with (regions read, regions to read) as the face region step reads its regions: around a
  // whole head without holes, 26 directions read coarsely, then the best 3 at three reaches.
  std::function<void(int, int)> progress = nullptr;
  // Around a whole head without holes (26 directions), rank the directions by a coarse reading of
  // their largest regions first and read only the best 3 in full (about a sixth of the time; off:
  // every region read in full, as before, for the tests to compare).
  bool coarse_first_pass = true;
};

// Finds the face in a scan that may hold more than a face (hair, ears, shoulders), spec/method.md
// §7.14: first the whole surface (find_face_orientation); where that finds no face, a face
// detected by OpenCV's frontal-face cascade in rendered views of the surface coloured by `texture`
// (the mesh's per-corner UVs) or by its vertex colours, its region read by find_face_orientation
// with the detection's up as the hint; then, without a texture or a detection, the mirror plane of
// ever smaller regions around the most protruding point. Throws kInvalidArgument naming `name`
// ("no face orientation found: ...", each step's reason) where neither geometry nor texture shows
// a face. Where `texture` is null or empty the image the mesh names (mesh.texture) is read, only
// if the texture step is reached.
FaceOrientation find_face(const TriangleMesh& mesh, const Image* texture, const std::string& name, const Vec3* vertical_hint = nullptr,
                          const FaceFindingOptions& options = {});

}  // namespace facemorph
