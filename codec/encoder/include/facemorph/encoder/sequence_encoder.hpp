// The encoder: a capture in, a Sequence (facemorph/sequence.hpp) out (spec/method.md §7).
//
//   every frame: prepare, conformal map, normalise (frame_pipeline.hpp)        parallel
//   every frame: landmarks on the disk, registered to the reference frame        parallel
//   every frame: its registered surface on a coarse grid, its rigid head pose    parallel
//   keyframes: chosen by the predicted error of the spline (keyframes.hpp)
//   grid size N: from the capture (--grid auto)
//   every keyframe: the registered surface on G in the face's own frame, its fields, its holes as
//   a level set, its texture on the disk                                          parallel
#pragma once

#include "facemorph/encoder/capture.hpp"
#include "facemorph/encoder/conformal.hpp"
#include "facemorph/encoder/density_equalising.hpp"
#include "facemorph/encoder/field_precision.hpp"
#include "facemorph/encoder/frame_pipeline.hpp"
#include "facemorph/encoder/frame_store.hpp"
#include "facemorph/encoder/keyframe_store.hpp"
#include "facemorph/encoder/keyframes.hpp"
#include "facemorph/encoder/landmark_tracking.hpp"
#include "facemorph/encoder/registration.hpp"
#include "facemorph/encoder/registration_store.hpp"
#include "facemorph/encoder/representation_choice.hpp"
#include "facemorph/encoder/residual_fit.hpp"
#include "facemorph/encoder/selection_store.hpp"
#include "facemorph/encoder/stored_sequence.hpp"
#include "facemorph/encoder/texture_quality.hpp"
#include "facemorph/error.hpp"
#include "facemorph/sequence.hpp"

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <array>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

inline constexpr int kAutoTextureQuality = -1;
// The representation's automatic choice (EncodeOptions::representation unset): xyz only where the
// blended fields miss the frames between keyframes by more than this times the blended positions
// (a margin for the measurement's noise: hl+t keeps its head-rotation behaviour and, on the captures
// measured, fewer bytes at equal error wherever both blends are alike; spec/method.md §7.14), over
// at most kBlendTrials frames.
inline constexpr double kFieldsBlendMargin = 1.1;
inline constexpr int kBlendTrials = 12;

// The pairs of neighbouring keyframes (k: keyframes[k] and keyframes[k + 1], frame indices) with a
// frame between them, kBlendTrials of them at most, spread evenly over those pairs (the first and the
// last kept): where choose_representation blends.
std::vector<size_t> blend_trial_pairs(const std::vector<int>& keyframes);
// What an unset representation becomes after `blend` was measured: xyz where the fields came out
// farther than kFieldsBlendMargin times the positions (a diverged blend is infinitely far), else hl+t.
Representation representation_for(const BlendComparison& blend);

struct EncodeOptions {
  double keyframe_fraction = 0.10;  // --keyframes 10%: the budget
  // The budget grows where it would leave the mean error predicted between keyframes above this
  // (fraction of the diagonal), or the worst above 3 times it: frames far apart or fast motion get
  // keyframes instead of a budget spread thin (SelectionOptions::error_bound; spec/method.md §7.5).
  // 0: the budget exactly (fmenc --keyframes P sets 0).
  double keyframe_error_bound = 0.005;
  // A capture whose frames lie on median more than this apart (seconds; below 4 frames a second)
  // keeps every frame as a keyframe (SelectionOptions::sparse_interval). 0: off (fmenc --keyframes P
  // sets 0, as for the bound).
  double sparse_frame_interval = 0.25;
  double max_error = 0;             // --max-error: > 0 replaces the budget by this tolerance (fraction of the diagonal)
  int grid = 0;                     // N; 0 = automatic (spec/method.md §7.6)
  // What the keyframes store. Unset (the default; fmenc --representation auto): hl+t, except where
  // most frames register to the reference without interior landmarks (none shared, none tracked)
  // and the keyframes' fields, blended at frames between them, come out farther from those frames
  // than their blended positions (by more than kFieldsBlendMargin): there xyz. The fields of
  // features that the normalised maps leave apart do not blend into one surface; positions do
  // (spec/method.md §7.14). SequenceEncoder::choose_representation decides.
  std::optional<Representation> representation;
  RegistrationOptions registration;
  SplineKind spline = SplineKind::kCatmullRom;
  // Residual frames (format 2.3, spec/method.md §7.18): the selection takes fewer keyframes where
  // residuals keep the frames within what the budget's left (SelectionOptions::residuals), and each
  // frame between keyframes carries a correction of the spline's blend fitted to the stored
  // keyframes and kept where the frame decodes closer with it (fit_decoded_residuals). Off by
  // default (fmenc --residual-frames turns it on): it lowers the error on every capture measured and
  // the bytes on fast speech, the 60-frame sample and ICT, but on Medusa adds 1.7% of bytes (its
  // budget keeps its keyframes), and the fit decodes every frame between keyframes twice.
  bool residual_frames = false;
  bool texture = true;
  int texture_size = 0;             // M: texels per side of the disk texture; 0 = automatic (as sharp as the capture's, at most 1024)
  // --texture-codec: how keyframe textures are stored (AVIF: ~30% smaller than WebP at equal PSNR).
  TextureCodec texture_codec = TextureCodec::kAvif;
  // --quality: every keyframe's texture at this quality of the codec (0..100, above 100 lossless WebP), or
  // kAutoTextureQuality (the default): each keyframe's from the interpolation error beside it
  // (texture_quality.hpp, spec/method.md §7.12).
  int texture_quality = kAutoTextureQuality;
  TextureQualityOptions texture_coding;
  // Keyframes painted from one captured image (the same file, or the same pixels) show one texture,
  // stored once, where it stays within texture_coding.min_psnr of each one's own (share_textures,
  // spec/method.md §7.16). fmenc --no-texture-sharing turns it off.
  bool share_textures = true;
  bool keep_holes_filled = false;   // true: store no holes; the decoder shows the fill
  bool largest_component = false;   // keep each frame's largest surface, drop eyeballs, teeth (else an error)
  int reference_frame = 0;          // the frame every other is registered to
  int threads = 0;                  // 0: one per core
  ConformalOptions conformal;
  // --density-equalising: how far G's nodes spread over the reference's surface by area instead of
  // conformally (density_equalising.hpp); strength 0 (the default) keeps the conformal disk: measured,
  // equalising lowers the floor at equal N but costs elsewhere (spec/method.md §7.11).
  DensityEqualisingOptions density_equalising{.strength = 0};
  // --field-error: the RMS displacement of a decoded keyframe that rounding its fields may cause
  // (fraction of the diagonal; field_precision.hpp). predicted_fields false (--field-error 0): no
  // search, each array at a 65535th of its range (16-bit precision, spec/container.md §7.1).
  FieldPrecisionOptions field_precision;
  bool predicted_fields = true;
  // --field-error auto (the default): the target is two fifths of the mean error the spline is
  // predicted to make between keyframes, within [0.005%, 0.2%] of the diagonal, where rounding
  // error and more keyframes buy held-out error at about the same price in bytes, whether the
  // capture is clean or noisy (spec/method.md §5.3); false: field_precision's target.
  bool auto_field_error = true;
  // --keyframe-fit: store at each keyframe the values whose spline best matches every frame of the
  // capture (least squares over all frames, in the face frame of the pose the decoder blends),
  // instead of the keyframe's own frame: a noisy capture's noise is averaged away instead of
  // interpolated (spec/method.md §7.5). keyframe_fit_weight μ is the extra weight of a keyframe's
  // own frame (it already counts once). keyframe_fit_noise κ: a keyframe moves at most κ times its
  // frame's estimated noise (RMS), so a clean capture's keyframes stay its frames.
  bool keyframe_fit = true;
  double keyframe_fit_weight = 1.0;
  double keyframe_fit_noise = 3.0;
  // A frame without nose_tip and nose_bridge (or between_eyes): find them from its geometry
  // (find_face_orientation) instead of dropping it; and where the capture has no rim_* markers at
  // all, place rim_0..rim_5 on each frame's rim at fixed angles of its normalised disk
  // (spec/method.md §7.14). false: such a frame is dropped (or, strict, ends the encode).
  bool find_landmarks = true;
  // A frame that shares fewer than 3 interior landmarks with the reference (every frame of a capture
  // without landmarks, or with --landmarks auto): a grid of the reference's disk points tracked onto
  // it by optical flow on disk images of the geometry, the reliable ones added to its landmarks
  // (landmark_tracking.hpp, spec/method.md §7.14). Off by default (fmenc --track-landmarks): it
  // lowers the held-out error (two ICT clips: 1.37–1.42× → 1.16–1.17× the landmarked encode's) but
  // costs 14–18% more bytes and ~0.2 s a frame, not yet "alike rates". false: the interior follows
  // the normalised maps.
  bool track_landmarks = false;
  TrackingOptions tracking;
  // --strict: a frame that cannot be read, prepared or mapped, or a landmark farther from its frame
  // than landmark_tolerance, ends the encode with its error. Otherwise (the default) such a frame is
  // dropped and named in the report, a far landmark is ignored and named, and the spline covers the
  // dropped frame's time.
  bool strict = false;
  // How far from its frame's surface a landmark may lie, as a fraction of the frame's bounding-box
  // diagonal (2%: 4-6 mm on a face). A landmark from a detector or a hand lies on the surface up
  // to its noise; one farther off is a mistake (another frame's, another unit), and snapping it to
  // the closest point would pass the mistake on to the registration.
  double landmark_tolerance = 0.02;
  // true (the default): each frame's map goes to a temporary file (TMPDIR) once it is made and is
  // read back by the stages that need it, so memory holds only the frames being worked on (about
  // one per thread) whatever the capture's length (frame_store.hpp). false: every map stays in
  // memory, ~4 MB a frame of a 10k-vertex capture; the output is the same.
  bool spill_frames = true;
  // true (the default): the keyframes' surfaces on G while they are fitted, and the field
  // precision's exact fields and decoded surfaces, go to a temporary file too and are read back one
  // a thread (keyframe_store.hpp). false: they stay in memory, ~3 MB a keyframe at N = 257 (as
  // the encoder did before); the output is the same.
  bool spill_keyframes = true;
  // Progress: (stage, done, total); stages "mapping", "registering", "keyframes".
  std::function<void(const std::string&, int, int)> progress;
};

// What the encoder did, frame by frame: for the tools' summaries and the bench.
struct EncodedFrameReport {
  std::string name;
  double time = 0;
  int vertices = 0;
  int holes_filled = 0;
  std::string repair;  // what preparation changed ("valid as captured", "dropped 2 other components (812 faces)", ...)
  RepairTotals repair_totals;  // faces and vertices it changed, how far the surface moved
  bool keyframe = false;
  RegistrationFallback fallback = RegistrationFallback::kNone;
  std::string fallback_reason;
  std::string conformal_fallback_reason;  // non-empty when QIEM failed and the frame took another map...
  ConformalMethod conformal_method = ConformalMethod::kQiem;  // ...this one
  double energy_moebius = 0, energy = 0;  // E_D of the OMT and of the registration (disk units²)
  double predicted_error = 0;             // the selection's predicted error (fraction of the diagonal)
  double diagonal = 0;                    // of the captured frame
};

// A frame the encoder left out (EncodeOptions::strict is false), with the error that would have
// ended the encode.
struct DroppedFrame {
  int index = 0;  // in the capture as given
  std::string name;
  double time = 0;
  std::string reason;
};

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

struct EncodeReport {
  std::vector<EncodedFrameReport> frames;  // the frames encoded (without the dropped ones)
  std::vector<DroppedFrame> dropped;       // in capture order
  std::vector<std::string> warnings;       // landmarks ignored, a reference frame moved; each names its frame
  int reference_frame = 0;                 // the frame registered to, in the capture as given
  int orientation_found = 0;               // frames whose nose tip and up were found from the geometry
  double weakest_up_evidence = 1;          // the least clear of their up readings (FaceOrientation::up_evidence)
  int up_from_hint = 0;                    // of them, frames whose surface did not say and another frame's up was taken
  double worst_mirror_error = 0;           // the least symmetric of them (FaceOrientation::mirror_error)
  // How they were found (FaceFindingMethod: whole surface, texture, face region), frames each, and
  // the least sure finding (FaceOrientation::confidence). A staged encode's part files do not carry
  // these: frames read from them count as found on the whole surface with confidence 0.
  std::array<int, 3> orientation_methods = {0, 0, 0};
  double lowest_face_confidence = 1;
  // The method that found the most frames ("whole surface", "texture", "face region").
  const char* main_orientation_method() const;
  bool rim_markers_found = false;          // rim markers placed on the rims (the capture had none)
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
  std::vector<int> keyframes;
  std::vector<std::pair<int, double>> selection_history;  // (keyframes, worst predicted error)
  int keyframe_budget = 0;                                // what the budget alone gave (0 with max_error)
  bool sparse = false;                                    // every frame a keyframe: frames sparser than sparse_frame_interval
  double median_frame_interval = 0;                       // seconds
  double budget_mean_error = 0, budget_worst_error = 0;   // the predicted errors it left (fraction of the diagonal)
  int grid = 0;
  int texture_size = 0;                                   // M chosen (0: no texture)
  std::vector<std::pair<int, double>> grid_floors;        // (N, resampling floor RMS / diagonal) tried by --grid auto
  double median_noise = 0;                                // frames' median noise estimate / diagonal (--grid auto)
  double grid_target = 0;                                 // the floor --grid auto asked for / diagonal
  std::string grid_term;                                  // which term set it: "floor", "noise" or "interpolation"
  int registration_fallbacks = 0;
  DensityEqualisingReport density_equalising;
  double radial_equalising = 0;  // the radial reparametrisation's strength used (0: none; spec/method.md §7.11)
  std::vector<int32_t> keyframe_folds;  // the nodes where the keyframes built (a segment's own) fold: G's interior, ascending
  FieldCoding field_coding;          // what the file must store (SequenceFileMetadata::field_coding)
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
  double seconds_mapping = 0, seconds_registration = 0, seconds_selection = 0, seconds_representation = 0, seconds_keyframes = 0, seconds_precision = 0,
         seconds_texture = 0;
  // The staged encode's assemble stage (staged_encode.hpp): the parts read and checked. Its
  // seconds_mapping, _registration and _selection are then the parts' own, summed.
  double seconds_reading_parts = 0;
  double seconds_planning = 0;  // plan_keyframes: the keyframes, N and representation chosen
  int parts = 0;
  ResidualFitReport residual_fit;  // options.residual_frames: the residuals fitted to the stored keyframes
};

// Encodes `capture`. Every frame needs the landmarks nose_tip and nose_bridge (or between_eyes)
// and at least three landmarks shared with the reference frame; rim_* markers give the boundary
// correspondence. A frame that lacks them, or cannot be read, prepared or mapped, is dropped and
// named in the report (EncodeOptions::strict: the encode ends with its error instead). Throws
// facemorph::Error for bad options, when no frame is left, and in strict mode what the frame's
// stage threw, naming the frame (kInvalidArgument for missing landmarks; what prepare_frame,
// conformal_disk_map and the image reader throw, e.g. kNotADisk or kMissingTexture).
Sequence encode_capture(const Capture& capture, const EncodeOptions& options = {}, EncodeReport* report = nullptr);
// The same, the keyframes left where the encoder keeps them (in its temporary file, with
// options.spill_keyframes): a KeyframeSource the file writer reads a keyframe at a time
// (write_sequence_file(path, *stored, metadata)), so that encoding to a file holds each keyframe's
// time and pose rather than its arrays (spec/method.md §7.15). The temporary file goes with it.
// The encoder keeps its own capture: moved in, a long capture's paths and landmarks are not held twice.
std::unique_ptr<StoredSequence> encode_capture_stored(Capture capture, const EncodeOptions& options = {}, EncodeReport* report = nullptr);

// What the encoder keeps in memory of every frame once it is mapped (its map goes to the FrameStore):
// the counts and reasons the report gives, whether it has colour, and the landmarks it found.
struct FrameSummary {
  std::string name;
  int vertices = 0;      // of the prepared mesh
  int holes_filled = 0;
  std::string repair;    // RepairReport::summary()
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
  std::filesystem::path texture;              // its texture image (absolute), if any
  std::vector<Vec3> landmarks;                // one per name of the part's landmark names
  std::vector<char> map;                      // FrameStore::serialize
  // Or, where set, what gives those bytes when asked (map left empty): the assembling encoder reads
  // the map from there each time a step needs it rather than keeping a copy (a part file's record).
  std::function<std::vector<char>()> map_source;
  std::vector<char> registration;             // RegistrationStore::serialize
  bool without_interior_landmarks = false;    // registered without interior landmarks shared with the reference
  SelectionFrame selection;                   // its time, pose, diagonal and samples on the selection grid
};

// What the assembling encoder is told of the capture besides its frames (staged_encode.cpp).
struct SampledCapture {
  std::filesystem::path root;
  double fps = 0;
  std::string units = "m";
  double first_time = 0, last_time = 0;      // the capture's as given
  int frame_count = 0;                       // as given
  std::vector<std::string> landmark_names;   // the names the frames' landmarks follow (with those found added)
  std::vector<std::string> given_landmark_names;  // the capture's own
  int given_reference = 0;                   // EncodeOptions::reference_frame as given
  int reference = 0;                         // the frame registered to (capture index): given_reference unless that one was dropped
};

// The same, stage by stage, keeping every frame's map (in its FrameStore) and registration: what
// encode_capture runs, and what the bench uses to try several registrations or keyframe sets on one
// mapping. Stages run in order; a later stage may be re-run with other options (registering again
// redoes the selection samples). Each stage goes through the frames a few at a time (one per
// thread), reading each map back from the store and releasing it when done.
class SequenceEncoder {
 public:
  // Keeps its own `capture` (paths and landmarks; meshes are read as the stages need them).
  SequenceEncoder(Capture capture, EncodeOptions options);
  // The staged encode's assembling encoder: `capture`'s frames come through add_sampled_frame, in
  // capture order, each frame once; finish_sampled_frames then leaves the encoder as
  // map_frames, register_frames and sample_frames would have on the whole capture (spec/part-file.md).
  SequenceEncoder(const SampledCapture& capture, EncodeOptions options);
  void add_sampled_frame(SampledFrame&& frame);
  void finish_sampled_frames();
  // After sample_frames: every frame of this encoder's capture as given, kept or dropped, in order,
  // handed to `take` (numbered as set_source_indices says).
  void for_each_sampled_frame(const std::function<void(SampledFrame&&)>& take) const;
  // Numbers this encoder's frames as frames `indices` (increasing) of a larger capture, in its
  // report, its messages and for_each_sampled_frame: a part's encoder holds some of the capture's
  // frames. Before map_frames.
  void set_source_indices(std::vector<int> indices);
  // The up direction map_frames gives frames whose surfaces do not say (find_vertical_hint): settled
  // by the caller instead of found from this encoder's frames (a part's frames are not the capture's).
  void set_vertical_hint(std::optional<Vec3> hint) { vertical_hint_ = hint, vertical_hint_set_ = true; }
  // N of the grid every frame is sampled on for the keyframe selection (SampledFrame::selection).
  static int selection_grid() { return kSelectionGrid; }

  // 1. prepare, conformal map, normalise every frame. Frames that fail are dropped (unless
  // options().strict): from here on the encoder's capture() and frame indices are those of the
  // frames kept, and report().dropped names the others.
  void map_frames();
  // 2. register every frame to the reference (options().registration); method kFrame first builds
  // the reference's geodesic frame from its disk and landmarks, once, and registers through it.
  void register_frames();
  void sample_frames();     // 3. registered surfaces on the selection grid, head poses
  KeyframeSelection select_keyframes() const;  // 4. by predicted error
  // `chosen`'s residual frames (none without options().residual_frames) at the times a file holds
  // (residuals_on_file_times): what the sequence built on its keyframes carries.
  std::vector<ResidualFrame> residual_frames(const KeyframeSelection& chosen) const;
  Vec3 pose_centre() const;  // the face's centroid in the face frame (after sample_frames)
  // 5. N (options().grid, or automatic: spec/method.md §7.6), the floor's target from the capture's
  // noise and, given the keyframes `chosen`, the error the spline makes between them.
  int choose_grid(const KeyframeSelection* chosen = nullptr);
  // 5½ (encode_capture, once the keyframes and N are chosen): frees the selection's samples of every
  // frame (its local, world and normal vectors on the 65² grid, 230 KB a frame), which the later
  // steps do not read, keeping what they do: each frame's time, pose and diagonal, the reference's
  // local vectors (pose_centre) and the fit's noise estimate at `keyframes`. build may then be given
  // those keyframes only; select_keyframes and choose_grid throw kInternal until sample_frames runs
  // again.
  void release_selection_samples(const std::vector<int>& keyframes);
  // 4-5½ as an earlier stage of this encode chose them (a segment's measure, segmented_encode.hpp):
  // the representation and what choose_representation measured taken as given, and the
  // selection's samples released but for `keyframes`.
  void adopt_representation(Representation representation, const BlendComparison& blend);
  // 6. the keyframes on G: fields, poses, holes, textures, each array put in the store as it is
  // made (options().spill_keyframes). build: the same, read back as a Sequence.
  // With `segment`: only its keyframes, fitted over its fit range of `keyframes` (spec/method.md
  // §7.17), with its fixed nodes where given.
  std::unique_ptr<StoredSequence> build_stored(const std::vector<int>& keyframes, int grid, const KeyframeSegment* segment = nullptr);
  Sequence build(const std::vector<int>& keyframes, int grid);
  // 7. the fields rounded as the file will store them (options().field_precision, or with
  // auto_field_error two fifths of `chosen`'s mean predicted error): what a file written with the
  // returned coding (SequenceFileMetadata::field_coding) holds. Fills report().field_precision.
  FieldCoding round_fields(StoredSequence& keyframes, const KeyframeSelection& chosen);
  // The field precision's options round_fields uses: options().field_precision with the encoder's
  // spill and threads, and with auto_field_error the target `chosen` gives.
  FieldPrecisionOptions field_precision(const KeyframeSelection& chosen) const;
  FieldCoding round_fields(Sequence& sequence, const KeyframeSelection& chosen);
  // 8. each keyframe's texture quality (options().texture_quality, or auto: the texture blend's error
  // at the frame midway to each neighbouring keyframe, measured, and texture_quality.hpp's rule):
  // what a file's SequenceFileMetadata::keyframe_texture_qualities holds. `keyframes` as given to
  // build. Fills report().texture_qualities; empty for a sequence without texture.
  std::vector<int> choose_texture_qualities(const StoredSequence& stored, const std::vector<int>& keyframes);
  std::vector<int> choose_texture_qualities(const Sequence& sequence, const std::vector<int>& keyframes);
  // 9. keyframes whose textures are painted from one captured image (the same file, or the same
  // pixels) share one (options().share_textures): keyframe k takes the nearest earlier such
  // keyframe's texture where the two are within options().texture_coding.min_psnr of each other
  // over the disk (spec/method.md §7.16). A file stores a shared texture once (format 2.2). Fills
  // report().texture_shared_with and texture_share_psnr.
  void share_textures(StoredSequence& stored, const std::vector<int>& keyframes);
  void share_textures(Sequence& sequence, const std::vector<int>& keyframes);

  // 5½ (for an unset options().representation; encode_capture runs it once N is chosen): where
  // most frames were registered without interior landmarks, the hl+t fields and the positions of
  // `chosen`'s keyframes blended at the frames midway between up to kBlendTrials pairs of them, on
  // G of `grid` (compare_blends: the fine features are what blend apart, and a coarser grid does
  // not show them); xyz where the fields come out farther by more than kFieldsBlendMargin. Fills
  // report().blend and report().representation.
  void choose_representation(const KeyframeSelection& chosen, int grid);
  // What build stores: options().representation, or (unset) what choose_representation chose (hl+t
  // before it runs).
  Representation representation() const { return options_.representation.value_or(auto_representation_); }
  EncodeOptions& options() { return options_; }
  // The frames kept (all until map_frames drops any), their landmarks' names, without their
  // landmarks: those are in the encoder's store (landmarks(i)).
  const Capture& capture() const { return capture_; }
  // Frame i's landmarks, one per name of capture().landmark_names (NaN where it lacks one), as the
  // encoder uses them: those farther than the tolerance ignored, those map_frames found added. The
  // encoder keeps them in a store (with options().spill_frames, its temporary file: 1.8 kB a frame
  // for ICT's 74, a capture's length in memory otherwise), not in capture().
  std::vector<Vec3> landmarks(int i) const;
  // Frame i's landmarks and the reference's on their disks (disk_landmarks), after map_frames.
  DiskLandmarks frame_disk_landmarks(int i) const;
  int source_index(int i) const { return source_index_[static_cast<size_t>(i)]; }  // frame i in the capture as given
  int frame_count() const { return static_cast<int>(capture_.frames.size()); }
  // Frame i's map, read back from the store (options().spill_frames; its prepared mesh left empty,
  // see FrameStore::put) and held in memory as long as the pointer is. After map_frames.
  std::shared_ptr<const MappedFrame> frame(int i) const;
  const FrameSummary& frame_summary(int i) const { return summaries_[static_cast<size_t>(i)]; }
  const FrameStore& frame_store() const { return *store_; }
  // Frame i's registration, read back from its store (options().spill_frames) and held as long as
  // the pointer is. After register_frames.
  std::shared_ptr<const DiskRegistration> registration(int i) const;
  // The reference's geodesic frame of the last register_frames with method kFrame; null otherwise.
  const GeodesicFrame* geodesic_frame() const { return geodesic_frame_.get(); }
  // Where frame i is sampled for disk points of G (or of the disk texture): the reference's
  // reparametrisation, then the frame's registration (after register_frames). A sampler holds the
  // registration it read back; sample_points reads it for one call.
  class Sampler {
   public:
    Sampler(const DiskReparametrisation& reparametrisation, std::shared_ptr<const DiskRegistration> registration)
        : reparametrisation_(reparametrisation), registration_(std::move(registration)) {}
    Vec2 operator()(const Vec2& node) const { return (*registration_)(reparametrisation_(node)); }

   private:
    const DiskReparametrisation& reparametrisation_;
    std::shared_ptr<const DiskRegistration> registration_;
  };
  Sampler sampler(int i) const { return Sampler(reparametrisation_, registration(i)); }
  std::vector<Vec2> sample_points(int i, std::span<const Vec2> nodes) const;
  // Frame i's surface at those points (capture frame): what G, the selection grid and the fit sample.
  std::vector<Vec3> sample_surface(int i, std::span<const Vec2> nodes) const;
  // Replaces the keyframes' registered surfaces in the face frame (item k of `local`, frame
  // keyframes[k], sampled at G's nodes) by the least-squares fit of the spline to every frame
  // (options().keyframe_fit). Reads each surface back twice and stores the fitted one in its place.
  void fit_keyframes(const std::vector<int>& keyframes, const GridGeometry& geometry, SurfaceStore& local) const;
  const DiskReparametrisation& reparametrisation() const { return reparametrisation_; }
  // Every frame's time, pose and diagonal on the selection grid (after sample_frames; the vectors
  // are left empty, but for the reference's local ones); selection_frame(i): frame i with its
  // samples, read back from the store (kInternal once release_selection_samples has run).
  const std::vector<SelectionFrame>& selection_frames() const { return selection_; }
  std::shared_ptr<const SelectionFrame> selection_frame(int i) const;
  const std::vector<double>& selection_weights() const { return node_weights_; }
  const std::filesystem::path& texture_path(int i) const { return textures_[static_cast<size_t>(i)]; }
  // Whether frame i has colour to store: a texture image with UVs, or vertex colours (spec/capture.md).
  bool has_texture(int i) const;
  // Frame i's own colour on the size x size disk texture, sampled through its registration as a
  // keyframe's is (after register_frames): the image resampled, or the vertex colours painted. What
  // texture PSNR is measured against. Throws kMissingTexture when the frame has no colour.
  Image frame_texture(int i, int size) const;
  EncodeReport& report() { return report_; }

 private:
  // The coarse copy of G the keyframe selection predicts on: 65² is ~3.3k nodes, enough to rank
  // frames by error at a fraction of the cost of G itself.
  static constexpr int kSelectionGrid = 65;
  // What the selection's cache of spilled samples may hold: ~830 frames of 79 kB, more than the frames
  // its refinement predicts around one keyframe (six gaps between keyframes) at 10% keyframes.
  static constexpr uint64_t kSelectionCacheBytes = uint64_t{64} << 20;
  // The selection grid's node weights (its interior nodes' areas) into node_weights_; the grid.
  GridGeometry set_selection_weights();
  // The selection's samples into the report: their store's peak and bytes (release_selection_samples).
  void note_selection_samples();
  struct FrameFailure {  // why a frame failed; code kOk while it has not
    ErrorCode code = ErrorCode::kOk;
    std::string reason;
  };
  static FrameFailure failure_of(const Error& e, const std::string& name);
  void progress(const std::string& stage, int done, int total) const;
  // Sets those of frame `index`'s landmarks `points` that lie farther from `mesh` than
  // options().landmark_tolerance to NaN, with a warning each (strict: throws kInvalidArgument); says
  // whether it set any.
  bool ignore_far_landmarks(const TriangleMesh& mesh, size_t index, std::vector<Vec3>& points, std::vector<std::string>& warnings) const;
  // Leaves out the frames whose failure is set (FrameFailure per frame), into report().dropped;
  // moves the reference to the nearest frame kept. Throws the first failure when none is kept.
  void drop_frames(const std::vector<FrameFailure>& failures);
  // Writes the landmarks map_frames found (FaceOrientation, rim markers) into the encoder's capture,
  // under nose_tip, nose_bridge and rim_0.., for the registration; counts them in the report.
  void adopt_found_landmarks();
  // Frame i's map and colour, given its map (loaded once by the caller).
  std::vector<Vec3> sample_surface(const MappedFrame& frame, int i, std::span<const Vec2> nodes) const;
  Image frame_texture(const MappedFrame& frame, int i, int size) const;
  // The reference's map, kept in memory while it is the reference: every stage uses it.
  std::shared_ptr<const MappedFrame> pin_reference();
  // Throws kInvalidArgument for options out of their ranges (`count`: the capture's frames).
  void check_options(int count) const;
  std::unique_ptr<SpilledItems<std::vector<Vec3>>> make_landmark_store() const;
  // A sampled frame's registration (add_sampled_frame), through the reference's partition where it
  // has one; kCorrupt naming the frame where the bytes are not one.
  DiskRegistration read_sampled_registration(const std::string& name, const std::vector<char>& bytes) const;
  // What every stage after mapping reads of the reference (its map and landmarks `points`): its disk
  // reparametrised (options().density_equalising) and, for kFrame, its geodesic frame.
  void set_reference_geometry(const MappedFrame& reference, const std::vector<Vec3>& points);
  // Adds a mapped frame's found nose tip, up and rim markers to the report's counts.
  void count_found_landmarks(const FrameSummary& frame, bool given_rim);
  // The reference's grid tracked onto every frame (options().tracking) when some frame needs tracked
  // points (needs_tracked_points), with the report's tracking counts; empty otherwise.
  std::vector<TrackedPoints> track_frames();

  bool vertical_hint_set_ = false;
  std::optional<Vec3> vertical_hint_;
  // Per frame of the capture as given, the landmarks ignored on it; and the summaries of frames
  // mapped and dropped at registration: what for_each_sampled_frame hands on of dropped frames.
  std::map<int, std::vector<std::string>> warnings_by_frame_;
  std::map<int, FrameSummary> dropped_summaries_;
  std::vector<char> without_interior_;  // per frame kept: registered without interior landmarks shared with the reference
  int given_reference_ = 0;  // as options().reference_frame came, in the capture as given
  // The assembling encoder (add_sampled_frame): the reference in the capture as given, whether the
  // capture gave rim markers, the next frame due, and the registrations that came before the
  // reference's frame (with kFrame they need its geodesic frame's partition to be read).
  int sampled_reference_ = -1;
  bool given_rim_ = false;
  int next_sampled_ = 0;
  std::vector<std::pair<size_t, std::vector<char>>> pending_registrations_;
  Capture capture_;  // without its landmarks, which are in landmarks_
  std::unique_ptr<SpilledItems<std::vector<Vec3>>> landmarks_;
  std::vector<int> source_index_;
  double first_time_ = 0, last_time_ = 0;  // the capture's as given: dropping its ends does not shorten it
  EncodeOptions options_;
  std::unique_ptr<FrameStore> store_;
  std::vector<FrameSummary> summaries_;
  int pinned_index_ = -1;  // the frame pinned_ holds (-1: none)
  std::shared_ptr<const MappedFrame> pinned_;
  std::vector<std::filesystem::path> textures_;
  std::unique_ptr<RegistrationStore> registrations_;
  std::shared_ptr<const GeodesicFrame> geodesic_frame_;
  Representation auto_representation_ = Representation::kHLT;  // choose_representation's choice for an unset representation
  DiskReparametrisation reparametrisation_;
  std::vector<SelectionFrame> selection_;
  std::unique_ptr<SelectionStore> samples_;  // their samples (sample_frames until release_selection_samples)
  // After release_selection_samples: frame index -> frame_noise at that frame (the fit's keyframes).
  bool samples_released_ = false;
  std::map<int, double> released_noise_;
  // frame_noise at frame k, from the samples or, once they are released, as kept for a keyframe.
  double noise_at(int k) const;
  std::vector<double> node_weights_;
  EncodeReport report_;
};

// The up direction of the first frame of `capture` from `reference` on (cyclically) that lacks its
// pose landmarks and whose surface says which way is up (find_face_orientation); none when none
// does. `landmarks(i)`: frame i's points, one per name of capture.landmark_names. What map_frames
// gives frames whose surfaces do not say.
std::optional<Vec3> find_vertical_hint(const Capture& capture, int reference, bool largest_component,
                                       const std::function<std::vector<Vec3>(size_t)>& landmarks);

// The steps after the selection's sampling: keyframes, N, representation, the keyframes on G,
// field precision, texture qualities and sharing, and the report's per-frame lines. What
// encode_capture_stored runs once `encoder` has mapped, registered and sampled every frame, and the
// staged encode's assemble stage once its frames came from the parts (staged_encode.hpp).
std::unique_ptr<StoredSequence> encode_sampled(SequenceEncoder& encoder, EncodeReport* report = nullptr);
// encode_sampled's first and last steps, for an encode that builds and codes its keyframes another
// way (a segment: segmented_encode.hpp). plan_keyframes: the keyframes, N and the representation
// chosen (the report's lines for them filled), the selection's samples released. finish_report:
// the report's per-frame lines and memory figures, moved to `report` where given.
KeyframeSelection plan_keyframes(SequenceEncoder& encoder);
// plan_keyframes's choices made by an earlier stage of the same encode, taken as they are: the
// report's lines for them filled, the representation adopted, the selection's samples released.
// kInvalidArgument where `chosen` is not a selection of this encoder's frames (keyframes
// increasing from the first frame to the last, a predicted error a frame).
void adopt_keyframe_plan(SequenceEncoder& encoder, const KeyframeSelection& chosen, int grid, Representation representation, const BlendComparison& blend);
void finish_report(SequenceEncoder& encoder, const KeyframeSelection& chosen, const StoredSequence& sequence, EncodeReport* report);

// ---- The pieces, for tests and the bench ----

// Where the capture's landmarks of one frame lie on its disk, paired with the reference's: the
// registration's input. Landmarks missing in either frame are left out; rim_* markers are flagged
// and put exactly on the circle.
DiskLandmarks disk_landmarks(const Capture& capture, size_t reference, const DiskMap& reference_map, size_t frame,
                             const DiskMap& frame_map);
// The same for two frames' points, one per name of `names` (NaN where a frame lacks it).
DiskLandmarks disk_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const DiskMap& reference_map,
                             const std::vector<Vec3>& frame, const DiskMap& frame_map);

// The holes of a prepared, mapped frame as a level set at disk points (the frame's disk): minus the
// distance to the nearest hole outline inside a filled hole, plus it outside capped at
// kHoleLevelBand; kHoleLevelBand everywhere without holes.
std::vector<double> hole_level(const PreparedFrame& prepared, const DiskMap& map, const std::vector<Vec2>& points);

}  // namespace facemorph
