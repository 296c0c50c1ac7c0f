// The build stage (the keyframes on G) as the driver runs it: its own settings, derived once from
// the encode options (stage_settings.hpp), and the state units it reads (BuildFrames), so that it
// takes neither the encoder nor its options.
#pragma once

#include "codec/core/sequence/sequence.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/frame_maps.hpp"
#include "codec/encoder/encode/frame_registrations.hpp"
#include "codec/encoder/encode/selection_samples.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {

// One segment of a long capture's keyframes, coded apart from the others (fmenc --stage measure,
// --stage assemble --segment S/N; spec/method.md §7.17). Positions are in the capture's list of
// keyframes (KeyframeSelection::keyframes).
struct KeyframeSegment {
  size_t first = 0, end = 0;          // the keyframes it codes: whole groups of the intra period
  size_t fit_first = 0, fit_end = 0;  // those the keyframe fit solves over: the segment and a margin each side
  // The fixed nodes of the whole capture (every segment's folds); none: the segment's own folds.
  std::optional<std::vector<int32_t>> fixed_nodes;
  bool textures = true;  // false: none sampled (a stage that writes no file)
};

// Exactly what the build stage reads of the encode options (build_settings).
struct BuildSettings {
  SplineKind spline = SplineKind::kCatmullRom;
  bool keep_holes_filled = false;  // store no holes
  bool texture = true;             // store the keyframes' textures where the frames have colour
  int texture_size = 0;            // M; 0: automatic
  bool keyframe_fit = true;        // the keyframes fitted to every frame (EncodeOptions::keyframe_fit)
  double keyframe_fit_weight = 1.0, keyframe_fit_noise = 3.0;
  bool spill_keyframes = true;  // the keyframes' arrays to the temporary file as they are made
  int threads = 0;
  std::function<void(const std::string&, int, int)> progress;  // "keyframes", done, total
};

// What the build stage reads of the encode's state after sample_frames (holds references into it).
struct BuildFrames {
  const Capture& capture;                   // the frames kept (their times), fps and units
  const SelectionSamples& selection;        // sample_frames's: the frames' poses and noise
  const FrameMaps& maps;                    // map_frames's: maps, summaries, texture paths
  const FrameRegistrations& registrations;  // register_frames's
  Representation representation;            // what the keyframes store
  double first_time = 0, last_time = 0;     // the capture's as given
  Vec3 pose_centre = Vec3::Zero();          // the face's centroid in the face frame
};

// A build's surfaces before their fields: each keyframe's registered (and fitted) surface on G in
// the face frame, and the fixed nodes its fields were made with. What another representation's
// fields are made from without sampling every frame again (candidate_builds.hpp).
struct KeyframeSurfaces {
  std::shared_ptr<const SurfaceStore> surfaces;  // item k: keyframe k's
  std::vector<int32_t> fixed;
};

// 6. The keyframes on G of size `grid`: fields (in frames.representation), poses, holes, textures,
// each array put in the store as it is made (settings.spill_keyframes); with settings.keyframe_fit,
// fitted to every frame. With `segment`: only its keyframes, fitted over its fit range of
// `keyframes` (spec/method.md §7.17), with its fixed nodes where given. Fills report.texture_size,
// keyframe_folds and seconds_keyframes. kInvalidArgument for no keyframes or a segment outside
// them; kMissingTexture where some keyframes have colour and another has not. With `kept` (no
// segment): the surfaces the fields were made from, kept there. With `textures_from` (no segment):
// the textures of the same keyframes sampled through the same disk at another N, copied rather
// than sampled again (a texture does not depend on N; candidate_builds.hpp); ignored where its
// keyframes are not these (their number or times differ).
std::unique_ptr<StoredSequence> build_keyframes(const BuildSettings& settings, const BuildFrames& frames, const std::vector<int>& keyframes,
                                                int grid, const KeyframeSegment* segment, EncodeReport& report,
                                                KeyframeSurfaces* kept = nullptr, const StoredSequence* textures_from = nullptr);

// The holes of a prepared, mapped frame as a level set at disk points (the frame's disk): minus the
// distance to the nearest hole outline inside a filled hole, plus it outside capped at
// kHoleLevelBand; kHoleLevelBand everywhere without holes.
std::vector<double> hole_level(const PreparedFrame& prepared, const DiskMap& map, const std::vector<Vec2>& points);

}  // namespace facemorph
