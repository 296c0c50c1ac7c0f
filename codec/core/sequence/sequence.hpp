// A capture as the codec keeps it (spec/method.md §7): keyframes on the shared disk grid G — the
// fields of the face in its own frame, the rigid head pose, the holes as a level set, the texture on
// the disk. The decoder plays it back (codec/decoder/sequence/sequence_decoder.hpp); the encoder
// makes one.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/residual_weights.hpp"
#include "codec/core/sequence/spline.hpp"

#include <string>
#include <vector>

namespace facemorph {

struct Keyframe {
  double time = 0;    // seconds from the capture's first frame
  GridFields fields;  // the face in its own frame (the pose taken out)
  RigidPose pose;     // face frame -> capture frame
  // Per node of G: < 0 inside a filled hole (eyes, mouth), > 0 outside; empty when the sequence
  // keeps no holes. A distance-like level set in disk units, capped at +kHoleLevelBand outside
  // (not inside: a hole opening between keyframes then grows from its deepest point).
  std::vector<double> hole_level;
  Image texture;  // the frame's texture on the disk (texel (x, y) at UV (x + ½, y + ½) / M); empty: none
};

inline constexpr double kHoleLevelBand = 0.1;

struct Sequence {
  int grid_n = 0;
  Representation representation = Representation::kHLT;
  SplineKind spline = SplineKind::kCatmullRom;
  double fps = 0;         // the capture's nominal frame rate
  double first_time = 0;  // the capture's first and last frame times (seconds)
  double last_time = 0;
  std::string units = "m";
  // The point (face frame) whose path the pose blend follows (blend_poses): the face's centroid,
  // so a head turning about itself turns in place between keyframes.
  Vec3 pose_centre = Vec3::Zero();
  std::vector<Keyframe> keyframes;  // strictly increasing times
  // Residual frames (format 2.3, residual_weights.hpp): corrections of the blend between keyframes,
  // increasing, each strictly between two keyframes; none: the spline alone, as before 2.3.
  std::vector<ResidualFrame> residuals;
  // Frame patches (format 2.4, frame_patch.hpp): displacements of the decoded surface between
  // keyframes, increasing, each strictly between two keyframes; none: the blend alone, as before 2.4.
  std::vector<FramePatch> patches;

  bool has_holes() const { return !keyframes.empty() && !keyframes.front().hole_level.empty(); }
  bool has_texture() const { return !keyframes.empty() && !keyframes.front().texture.empty(); }
  std::vector<double> keyframe_times() const;
};

// Checks what the decoder relies on: at least one keyframe, strictly increasing finite times, every
// keyframe's fields valid for the sequence's grid and representation and sharing their fixed nodes,
// poses finite and proper, hole levels all present or all absent with one value per node, textures
// all present or all absent with one size and three channels. Throws kInvalidArgument naming the
// keyframe and the defect (the container reader reports kCorrupt).
void validate_sequence(const Sequence& sequence);

// The texture a frame shows: Σ w_k · texture of key k (SequenceDecoder's blend, also what the
// encoder measures its texture quality against), rounded to the nearest byte and clamped to 0..255.
// Requires a sequence with texture and weights of its keyframes.
Image blend_textures(const Sequence& sequence, const SplineWeights& w);
// The same over images of one size: Σ weights[i] · images[i].
Image blend_images(const std::vector<const Image*>& images, const std::vector<double>& weights);

}  // namespace facemorph
