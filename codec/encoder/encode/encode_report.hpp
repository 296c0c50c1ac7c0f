// What an encode did (EncodeReport): frame by frame, the frames it dropped, and what each stage
// chose and measured, for the tools' summaries, the file's settings and the bench.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/density/density_equalising.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/patch_fit.hpp"
#include "codec/encoder/encode/representation_choice.hpp"
#include "codec/encoder/encode/representation_rate.hpp"
#include "codec/encoder/encode/residual_fit.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace facemorph {

// What the encoder did, frame by frame: for the tools' summaries and the bench.
struct EncodedFrameReport {
  std::string name;
  double time = 0;
  int vertices = 0;
  int holes_filled = 0;
  std::string repair;          // what preparation changed ("valid as captured", "dropped 2 other components (812 faces)", ...)
  RepairTotals repair_totals;  // faces and vertices it changed, how far the surface moved
  bool keyframe = false;
  RegistrationFallback fallback = RegistrationFallback::kNone;
  std::string fallback_reason;
  std::string conformal_fallback_reason;                      // non-empty when QIEM failed and the frame took another map...
  ConformalMethod conformal_method = ConformalMethod::kQiem;  // ...this one
  double energy_moebius = 0, energy = 0;                      // E_D of the OMT and of the registration (disk units²)
  double predicted_error = 0;                                 // the selection's predicted error (fraction of the diagonal)
  double predicted_p99 = 0;                                   // and its 99th-percentile point (KeyframeSelection::predicted_p99)
  double diagonal = 0;                                        // of the captured frame
};

// A frame the encoder left out (EncodeOptions::strict is false), with the error that would have
// ended the encode.
struct DroppedFrame {
  int index = 0;  // in the capture as given
  std::string name;
  double time = 0;
  std::string reason;
};

struct EncodeReport {
  std::vector<EncodedFrameReport> frames;  // the frames encoded (without the dropped ones)
  std::vector<DroppedFrame> dropped;       // in capture order
  std::vector<std::string> warnings;       // landmarks ignored, a reference frame moved; each names its frame
  // Why the keyframes are stored as positions though hl+t was chosen: the keyframe whose fields'
  // reconstruction did not converge, and how far it was (encode_sampled); empty when none.
  std::string representation_fallback;
  int reference_frame = 0;         // the frame registered to, in the capture as given
  int orientation_found = 0;       // frames whose nose tip and up were found from the geometry
  double weakest_up_evidence = 1;  // the least clear of their up readings (FaceOrientation::up_evidence)
  int up_from_hint = 0;            // of them, frames whose surface did not say and another frame's up was taken
  double worst_mirror_error = 0;   // the least symmetric of them (FaceOrientation::mirror_error)
  // How they were found (FaceFindingMethod: whole surface, texture, face region), frames each, and
  // the least sure finding (FaceOrientation::confidence). A staged encode's part files do not carry
  // these: frames read from them count as found on the whole surface with confidence 0.
  std::array<int, 3> orientation_methods = {0, 0, 0};
  double lowest_face_confidence = 1;
  // The method that found the most frames ("whole surface", "texture", "face region").
  const char* main_orientation_method() const;
  bool rim_markers_found = false;  // rim markers placed on the rims (the capture had none)
  // Tracking (EncodeOptions::track_landmarks), over the frames that took tracked points (the
  // reference excluded): how many, the reference's grid, the points kept per frame (mean, fewest),
  // the median and 90th percentile of their round-trip errors (disk units; the disk's radius is 1).
  int tracked_frames = 0;
  int tracking_grid_points = 0;
  double tracked_points_mean = 0;
  int tracked_points_fewest = 0;
  double tracked_round_trip_median = 0, tracked_round_trip_p90 = 0;
  double seconds_tracking = 0;
  // Frames registered without interior landmarks shared with the reference (the reference excluded),
  // and the representation the keyframes store (EncodeOptions::representation, or what auto chose).
  int frames_without_interior_landmarks = 0;
  Representation representation = Representation::kHLT;
  BlendComparison blend;  // what choose_representation measured (trials 0: nothing measured)
  RepresentationRate representation_rate;  // what the choice by bytes at equal error measured (SequenceEncoder::choose_by_bytes)
  std::vector<int> keyframes;
  std::vector<std::pair<int, double>> selection_history;  // (keyframes, worst predicted error)
  int keyframe_budget = 0;                                // what the budget alone gave (0 with max_error)
  bool sparse = false;                                    // every frame a keyframe: frames sparser than sparse_frame_interval
  double median_frame_interval = 0;                       // seconds
  double budget_mean_error = 0, budget_worst_error = 0;   // the predicted errors it left (fraction of the diagonal)
  double budget_worst_p99 = 0;                            // and the worst frame's predicted 99th percentile
  int grid = 0;
  int texture_size = 0;                                 // M chosen (0: no texture)
  std::vector<std::pair<int, double>> grid_floors;      // (N, resampling floor RMS / diagonal) tried by --grid auto
  std::vector<std::pair<int, double>> grid_floor_p99s;  // (N, the floor's 99th-percentile point error / diagonal), the same N
  // The reference decoded from its fields at the N measured (from where the RMS terms were done):
  // RMS and 99th percentile / diagonal; where they did not reconstruct, the resampled floor (the
  // keyframes then stored as positions) or infinite (the fields asked for).
  struct DecodedFloor {
    int n = 0;
    double rms = 0;
    double p99 = 0;
    bool reconstructed = true;
  };
  std::vector<DecodedFloor> grid_decoded_floors;
  int grid_density_cap = 0;                             // the largest N the RMS terms could ask for (the captured mesh's density)
  double grid_worst_target = 0;                         // the floor's 99th percentile --grid auto asked for / diagonal
  double grid_vertex_area = 0;                          // the reference's lower-quartile vertex area on the disk (0: not measured)
  double median_noise = 0;                              // frames' median noise estimate / diagonal (--grid auto)
  double grid_target = 0;                               // the floor --grid auto asked for / diagonal
  std::string grid_term;                                // which term set it: "floor", "noise", "interpolation", "density" or "worst region"
  int registration_fallbacks = 0;
  DensityEqualisingReport density_equalising;
  double radial_equalising = 0;         // the radial reparametrisation's strength used (0: none; spec/method.md §7.11)
  // The density-equalised disk tried by bytes at equal error (density_candidate.hpp): its strength
  // (0: not tried), its resampled floor's 99th percentile at the Ns measured (coarsest first), kept or not.
  struct DensityCandidate {
    double strength = 0;
    std::vector<std::pair<int, double>> floor_p99s;
    bool kept = false;
    // Where D won on geometry and the capture is textured: each disk's file as fmenc stores it,
    // geometry (the choice's bytes) and texture (the texture stage's qualities and sharing), compared
    // (equalised_file_kept); the texture stage then ran and is not run again (textures_coded).
    bool textures_coded = false;
    uint64_t conformal_geometry_bytes = 0, conformal_texture_bytes = 0;
    uint64_t equalised_geometry_bytes = 0, equalised_texture_bytes = 0;
  };
  DensityCandidate density_candidate;
  std::vector<int32_t> keyframe_folds;  // the nodes where the keyframes built (a segment's own) fold: G's interior, ascending
  FieldCoding field_coding;             // what the file must store (SequenceFileMetadata::field_coding)
  FieldPrecisionReport field_precision;
  // Per keyframe, the quality of its texture in options().texture_codec (SequenceFileMetadata::keyframe_texture_qualities;
  // empty without texture); with auto quality, per interval between keyframes the PSNR of the texture
  // blend at the frame midway (0 where no frame lies between).
  std::vector<int> texture_qualities;
  std::vector<double> texture_interpolation_psnr;
  // Per keyframe (share_textures): the earlier keyframe whose texture it shows, or -1 for its own;
  // where shown, that texture's PSNR against its own over the disk (0 elsewhere).
  std::vector<int> texture_shared_with;
  std::vector<double> texture_share_psnr;
  // The most frames' maps in memory at once (FrameStore::peak_held: the reference's, and those
  // being mapped, registered or sampled), and the bytes of the maps written to the temporary file.
  int peak_frames_in_memory = 0;
  uint64_t spilled_bytes = 0;
  // The same for the keyframes' arrays (KeyframeStore: surfaces on G in build and the fit, decoded
  // surfaces in the field precision's search): the most in memory at once in either step; and the
  // bytes written, with those of the output's fields, hole levels and textures (StoredSequence, whose
  // own peak_held() counts what the later steps and the writer read back of them).
  int peak_keyframes_in_memory = 0;
  uint64_t keyframes_spilled_bytes = 0;
  // The same for the selection's samples (SelectionStore, with options.spill_frames): the most
  // frames' samples in memory at once (its cache's and those in use), and the bytes written.
  int peak_selection_samples_in_memory = 0;
  uint64_t selection_spilled_bytes = 0;
  double seconds_mapping = 0, seconds_registration = 0, seconds_selection = 0, seconds_representation = 0, seconds_keyframes = 0,
         seconds_precision = 0, seconds_texture = 0;
  // The staged encode's assemble stage (staged_encode.hpp): the parts read and checked. Its
  // seconds_mapping, _registration and _selection are then the parts' own, summed.
  double seconds_reading_parts = 0;
  double seconds_grid = 0;      // choose_grid (--grid auto): the floors measured
  double seconds_planning = 0;  // SequenceEncoder::plan: the keyframes, N and representation chosen
  int parts = 0;
  ResidualFitReport residual_fit;  // options.residual_frames: the residuals fitted to the stored keyframes
  PatchFitReport patch_fit;        // options.patch_bound > 0: the frame patches fitted to what the decoder shows
};

}  // namespace facemorph
