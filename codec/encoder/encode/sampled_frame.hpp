// What the encoder keeps of each frame once it is mapped (FrameSummary), and a frame as the staged
// encode's sample stage hands it to the assembling encoder (SampledFrame, SampledCapture; a part
// file's record, spec/part-file.md).
#pragma once

#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/landmarks/face_orientation.hpp"
#include "codec/encoder/prepare/frame.hpp"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {

// What the encoder keeps in memory of every frame once it is mapped (its map goes to the FrameStore):
// the counts and reasons the report gives, whether it has colour, and the landmarks it found.
struct FrameSummary {
  std::string name;
  int vertices = 0;  // of the prepared mesh
  int holes_filled = 0;
  std::string repair;          // RepairReport::summary()
  RepairTotals repair_totals;  // RepairReport::totals()
  ConformalMethod conformal_method = ConformalMethod::kQiem;
  std::string conformal_fallback_reason;
  bool has_uvs = false, has_colours = false;  // of the mapped surface
  std::optional<FaceOrientation> found;       // MappedFrame::found
  std::vector<Vec3> found_rim;                // MappedFrame::found_rim
};

// One frame of the capture as the staged encode's sample stage leaves it for assembling
// (staged_encode.hpp; a part file's record, spec/part-file.md): dropped, with why, or kept, with
// everything the steps after the selection's sampling read of it.
struct SampledFrame {
  int index = 0;     // in the capture as given
  std::string name;  // its mesh, as the capture names it
  double time = 0;
  std::vector<std::string> warnings;  // its landmarks ignored, each naming the frame
  // Why the frame was dropped; empty for a frame kept. A frame dropped at registration was mapped
  // first: `mapped` is set and its summary counts in the landmarks the report says were found.
  std::string dropped;
  bool mapped = false;
  FrameSummary summary;  // a frame mapped
  // A frame kept:
  std::filesystem::path texture;  // its texture image (absolute), if any
  std::vector<Vec3> landmarks;    // one per name of the part's landmark names
  std::vector<char> map;          // FrameStore::serialize
  // Or, where set, what gives those bytes when asked (map left empty): the assembling encoder reads
  // the map from there each time a step needs it rather than keeping a copy (a part file's record).
  std::function<std::vector<char>()> map_source;
  std::vector<char> registration;           // RegistrationStore::serialize
  bool without_interior_landmarks = false;  // registered without interior landmarks shared with the reference
  SelectionFrame selection;                 // its time, pose, diagonal and samples on the selection grid
};

// What the assembling encoder is told of the capture besides its frames (staged_encode.cpp).
struct SampledCapture {
  std::filesystem::path root;
  double fps = 0;
  std::string units = "m";
  double first_time = 0, last_time = 0;           // the capture's as given
  int frame_count = 0;                            // as given
  std::vector<std::string> landmark_names;        // the names the frames' landmarks follow (with those found added)
  std::vector<std::string> given_landmark_names;  // the capture's own
  int given_reference = 0;                        // EncodeOptions::reference_frame as given
  int reference = 0;                              // the frame registered to (capture index): given_reference unless that one was dropped
};

}  // namespace facemorph
