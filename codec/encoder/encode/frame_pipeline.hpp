// The one path from a captured frame to what a keyframe stores (spec/method.md §2-5), shared by
// the encoder, the benches and the tests:
//
//   prepare (validate, repair, fill holes) -> conformal map -> normalise by the landmarks
//     -> resample on G -> fields (with the decoder's operators) -> 16-bit quantisation
//
// Each stage is a function, so a caller that needs an intermediate (the resampled surface for the
// resampling floor, the map for its distortion) takes it on the way.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/landmarks/face_orientation.hpp"
#include "codec/encoder/prepare/frame.hpp"

#include <optional>
#include <string>
#include <vector>

namespace facemorph {

// The landmarks one frame's encoding uses, as 3D points on (or near) the frame.
struct FrameLandmarks {
  std::vector<Vec3> rim_markers;  // the rim_* markers: they pick the outer loop among the boundaries
  std::optional<Vec3> centre;     // nose_tip: sent to the disk's centre
  std::optional<Vec3> up;         // nose_bridge (else between_eyes): onto the positive imaginary axis
};

// The landmarks of frame `frame` of `capture` (those the frame lacks are left out); or of one
// frame's `points`, one per name of `names` (NaN where the frame lacks it).
FrameLandmarks capture_frame_landmarks(const Capture& capture, size_t frame);
FrameLandmarks frame_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& points);

struct MapFrameOptions {
  bool fill_holes = true;
  bool keep_largest_component = false;  // see PrepareOptions
  bool repair_non_manifold = true;      // see PrepareOptions (false: fmenc --strict)
  ConformalOptions conformal;
  // A frame without centre or up landmarks: find them from its geometry or texture (find_face)
  // and put its disk in the pose they give, instead of leaving it unnormalised.
  bool find_orientation = false;
  std::optional<Vec3> vertical_hint;  // see find_face
};

// Rim markers found on a normalised disk: the rim points at these disk angles, the first straight
// up (the direction the `up` landmark is turned to), the others evenly round the circle. Frames in
// the same pose put the same names at the same angles, so the registration can match boundaries
// without markers from the capture.
inline constexpr int kFoundRimMarkers = 6;

// A frame made a disk and mapped conformally onto the unit disk, in the reference pose when the
// landmarks give one (spec/method.md §3.5).
struct MappedFrame {
  std::string name;
  PreparedFrame prepared;
  DiskMap map;
  bool normalized = false;               // centre and up were known (given or found)
  std::optional<FaceOrientation> found;  // set when the centre and up were found from the geometry
  std::vector<Vec3> found_rim;           // kFoundRimMarkers points on the rim (after normalisation; empty if not normalised)
  double seconds_prepare = 0;            // validation, repair, hole filling
  double seconds_map = 0;                // the conformal map (normalisation included)
};

// Stages 1-3. Throws what prepare_frame, conformal_disk_map and (with options.find_orientation)
// find_face throw, naming `name`.
// From the centroid of `prepared`'s vertices to the mean of its filled holes' centroids (zero
// without holes): eyes, mouth and nostrils lie on the face, which is how a whole head (no one
// facing) shows where its face is (find_face_facing's hint).
Vec3 filled_holes_facing(const PreparedFrame& prepared);

MappedFrame map_frame(const TriangleMesh& mesh, const std::string& name, const FrameLandmarks& landmarks,
                      const MapFrameOptions& options = {});

// Stage 4: the mapped surface at every node of G (interior nodes, then rim nodes).
std::vector<Vec3> sample_on_grid(const MappedFrame& frame, const DiskGrid& grid);

// Stages 5-6: the fields of a surface sampled on G, rounded to what a container stores (16 bits)
// unless `quantized` is false. `fixed_nodes`: see compute_fields.
GridFields keyframe_fields(const GridGeometry& geometry, const std::vector<Vec3>& sampled, Representation representation,
                           const std::vector<int32_t>& fixed_nodes = {}, bool quantized = true);

}  // namespace facemorph
