// The encoder: a capture in, a Sequence (codec/core/sequence/sequence.hpp) out (spec/method.md §7).
//
//   every frame: prepare, conformal map, normalise (frame_pipeline.hpp)        parallel
//   every frame: landmarks on the disk, registered to the reference frame        parallel
//   every frame: its registered surface on a coarse grid, its rigid head pose    parallel
//   keyframes: chosen by the predicted error of the spline (keyframes.hpp)
//   grid size N: from the capture (--grid auto)
//   every keyframe: the registered surface on G in the face's own frame, its fields, its holes as
//   a level set, its texture on the disk                                          parallel
#pragma once

#include "codec/core/sequence/sequence.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/density/density_equalising.hpp"
#include "codec/encoder/encode/build_stage.hpp"
#include "codec/encoder/encode/candidate_builds.hpp"
#include "codec/encoder/encode/encode_options.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/frame_maps.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/frame_registrations.hpp"
#include "codec/encoder/encode/frame_sampler.hpp"
#include "codec/encoder/encode/keyframe_store.hpp"
#include "codec/encoder/encode/plan_keyframes.hpp"
#include "codec/encoder/encode/representation_choice.hpp"
#include "codec/encoder/encode/residual_fit.hpp"
#include "codec/encoder/encode/sampled_frame.hpp"
#include "codec/encoder/encode/selection_samples.hpp"
#include "codec/encoder/encode/stage_settings.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/encoder/encode/texture_stage.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/landmarks/landmark_tracking.hpp"
#include "codec/encoder/registration/registration.hpp"
#include "format/error.hpp"

#include <filesystem>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace facemorph {

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

// Why a frame failed a stage (map, register): code kOk while it has not.
struct FrameFailure {
  ErrorCode code = ErrorCode::kOk;
  std::string reason;
};
// The failure `e` of the frame `name`, its reason without the name where the stage put it first.
FrameFailure frame_failure(const Error& e, const std::string& name);

// The encode's state, stage by stage: the capture's frames (paths, landmarks in their store, their
// numbers in the capture as given), each stage's own state unit (the maps: FrameMaps; the
// registrations: FrameRegistrations; the selection samples: SelectionSamples) and the report.
// The stages are free functions: map, register and sample over it (map_frames, register_frames,
// sample_frames); the stages after them (plan, build, precision, texture) over their own settings
// and views of its state units, which its driver members (encode_sampled, plan, code, ...) derive
// once per run from options() (stage_settings.hpp) and hand them. The one-process encode
// (encode_capture_stored), the staged and the segmented encodes all run through these members, and
// the bench re-runs a later stage with other options (registering again redoes the selection
// samples). Each stage goes through the frames a few at a time (one per thread), reading each map
// back from the store and releasing it when done.
class SequenceEncoder {
 public:
  // Keeps its own `capture` (paths and landmarks; meshes are read as the stages need them).
  SequenceEncoder(Capture capture, EncodeOptions options);
  // The staged encode's assembling encoder: `capture`'s frames, frame(k) for k = 0 .. frame_count - 1
  // in capture order, leave it as map_frames, register_frames and sample_frames would have on the
  // whole capture (spec/part-file.md). A frame that does not fit (out of order, the wrong number of
  // landmarks or samples, a registration that is no registration) throws, named by where(k).
  static std::unique_ptr<SequenceEncoder> of_sampled_frames(const SampledCapture& capture, EncodeOptions options,
                                                            const std::function<SampledFrame(int)>& frame,
                                                            const std::function<std::string(int)>& where);
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
  // The hint set_vertical_hint gave; none where it was not called.
  std::optional<std::optional<Vec3>> given_vertical_hint() const {
    return vertical_hint_set_ ? std::optional<std::optional<Vec3>>(vertical_hint_) : std::nullopt;
  }

  // The map stage's state (map_frames): every frame's map, summary and texture path.
  const FrameMaps& maps() const { return maps_; }
  FrameMaps& maps() { return maps_; }
  // The register stage's state (register_frames): every frame's registration, the reference's geometry.
  const FrameRegistrations& registrations() const { return registrations_; }
  FrameRegistrations& registrations() { return registrations_; }
  // The sample stage's state: every frame on the selection grid (selection_samples.hpp).
  const SelectionSamples& selection() const { return selection_; }
  SelectionSamples& selection() { return selection_; }
  Vec3 pose_centre() const { return selection_.centre(options_.reference_frame); }  // the face's centroid in the face frame
  // What the keyframes store from here on where options().representation leaves it open: what
  // choose_representation chose, an earlier stage of this encode chose (a segment's measure,
  // segmented_encode.hpp), or the fallback to positions (store_as_positions); `blend`: what the
  // choice measured. Fills report().blend and report().representation.
  void adopt_representation(Representation representation, const BlendComparison& blend);
  // The automatic representation back to hl+t until choose_representation measures otherwise
  // (register_frames: a new registration, a new choice).
  void reset_representation() {
    auto_representation_ = Representation::kHLT;
    report_.representation = representation();
  }
  // What build_keyframes stores: options().representation, or (unset) what adopt_representation
  // was given (hl+t before it is).
  Representation representation() const { return options_.representation.value_or(auto_representation_); }
  EncodeOptions& options() { return options_; }
  const EncodeOptions& options() const { return options_; }
  // The frames kept (all until map_frames drops any), their landmarks' names, without their
  // landmarks: those are in the encoder's store (landmarks(i)).
  const Capture& capture() const { return capture_; }
  // Frame i's landmarks, one per name of capture().landmark_names (NaN where it lacks one), as the
  // encoder uses them: those farther than the tolerance ignored, those map_frames found added. The
  // encoder keeps them in a store (with options().spill_frames, its temporary file: 1.8 kB a frame
  // for ICT's 74, a capture's length in memory otherwise), not in capture().
  std::vector<Vec3> landmarks(int i) const;
  // Frame i's landmarks replaced by `points` (one per name of capture().landmark_names), in the store.
  void put_landmarks(int i, std::vector<Vec3> points);
  // The place of the landmark `name` among capture().landmark_names, added at the end where missing
  // (the landmarks map_frames finds on the frames).
  size_t landmark_name_index(const std::string& name);
  // The warnings a stage gives frame i (such as landmarks ignored on it): into report().warnings,
  // and kept for for_each_sampled_frame under the frame's number in the capture as given.
  void add_frame_warnings(int i, std::vector<std::string> warnings);
  // Leaves out the frames whose failure is set (one per frame) from every stage's state, into
  // report().dropped; moves the reference to the nearest frame kept (warned). Throws the first
  // failure when none is kept.
  void drop_frames(const std::vector<FrameFailure>& failures);
  // The reference's map, kept in memory while it is the reference: every stage uses it.
  std::shared_ptr<const MappedFrame> pin_reference() { return maps_.pin(options_.reference_frame); }
  // Frame i's landmarks and the reference's on their disks (disk_landmarks), after map_frames.
  DiskLandmarks frame_disk_landmarks(int i) const;
  int source_index(int i) const { return source_index_[static_cast<size_t>(i)]; }  // frame i in the capture as given
  int frame_count() const { return static_cast<int>(capture_.frames.size()); }
  // Frame i's map, read back from the store (options().spill_frames; its prepared mesh left empty,
  // see FrameStore::put) and held in memory as long as the pointer is. After map_frames.
  std::shared_ptr<const MappedFrame> frame(int i) const { return maps_.frame(i); }
  const FrameSummary& frame_summary(int i) const { return maps_.summaries[static_cast<size_t>(i)]; }
  const FrameStore& frame_store() const { return maps_.store(); }
  // Frame i's registration, read back from its store (options().spill_frames) and held as long as
  // the pointer is. After register_frames.
  std::shared_ptr<const DiskRegistration> registration(int i) const { return registrations_.registration(i); }
  // The reference's geodesic frame of the last register_frames with method kFrame; null otherwise.
  const GeodesicFrame* geodesic_frame() const { return registrations_.geodesic_frame(); }
  // Where frame i is sampled (FrameSampler::sampler), after register_frames.
  using Sampler = RegistrationSampler;
  Sampler sampler(int i) const { return frame_sampler().sampler(i); }
  // The frames' registered surfaces and colours, over the map and register stages' state (frame_sampler.hpp).
  FrameSampler frame_sampler() const { return FrameSampler(maps_, registrations_); }
  const DiskReparametrisation& reparametrisation() const { return registrations_.reparametrisation(); }
  // The capture's first and last frame times as given (seconds): dropping its end frames does not
  // shorten it.
  double first_time() const { return first_time_; }
  double last_time() const { return last_time_; }
  const std::filesystem::path& texture_path(int i) const { return maps_.textures[static_cast<size_t>(i)]; }
  // Whether frame i has colour to store: a texture image with UVs, or vertex colours (spec/capture.md).
  bool has_texture(int i) const { return maps_.has_texture(i); }
  EncodeReport& report() { return report_; }
  // Tells options().progress (where set) that `done` of `total` frames went through `stage`.
  void progress(const std::string& stage, int done, int total) const {
    if (options_.progress) options_.progress(stage, done, total);
  }

  // ---- The driver: the steps after the selection's sampling, each stage on its own settings ----

  // Keyframes, N, representation, the keyframes on G, field precision, residual frames, patches,
  // texture qualities and sharing, and the report's per-frame lines, every stage's settings derived
  // once from options() (stage_settings). What encode_capture_stored runs once this encoder has
  // mapped, registered and sampled every frame, and the staged encode's assemble stage once its
  // frames came from the parts (staged_encode.hpp). The report moved to `report` where given.
  std::unique_ptr<StoredSequence> encode_sampled(EncodeReport* report = nullptr);
  // The plan stage: the keyframes, N and the representation chosen (the report's lines for them
  // filled), the selection's samples released.
  KeyframeSelection plan(const PlanSettings& settings);
  // plan's choices made by an earlier stage of the same encode, taken as they are: the report's
  // lines for them filled, the representation adopted, the selection's samples released.
  // kInvalidArgument where `chosen` is not a selection of this encoder's frames (keyframes
  // increasing from the first frame to the last, a predicted error a frame).
  void adopt_plan(const KeyframeSelection& chosen, int grid, Representation representation, const BlendComparison& blend);
  // The build stage (build_keyframes) on this encoder's frames, in representation(); with `kept`
  // (no segment), the surfaces the fields were made from kept there; with `textures_from`, another
  // N's build of the same keyframes on the current disk, whose textures are copied.
  std::unique_ptr<StoredSequence> build(const BuildSettings& settings, const std::vector<int>& keyframes, int grid,
                                        const KeyframeSegment* segment = nullptr, KeyframeSurfaces* kept = nullptr,
                                        const StoredSequence* textures_from = nullptr);
  // The keyframes built (build: all of `keyframes`, or `segment`'s) and `measure_fields` run on
  // them (the field precision: round_fields, or a segment's measure); where the representation is
  // the encoder's own choice (options().representation unset) and not already xyz, and measuring
  // throws kNotConverged (a keyframe's fields do not reconstruct), store_as_positions and the
  // keyframes built and measured again, with the report's warning. What every encode (one process,
  // staged, a segment's measure) builds its keyframes through: a capture never fails for a keyframe
  // that does not reconstruct. Anything else measuring throws, and kNotConverged where hl+t was asked
  // for, is thrown.
  // With `kept` (no segment): the surfaces of the keyframes measured last (build's).
  std::unique_ptr<StoredSequence> build_reconstructable(const BuildSettings& settings, const std::vector<int>& keyframes, int grid,
                                                        const KeyframeSegment* segment,
                                                        const std::function<void(StoredSequence&)>& measure_fields,
                                                        KeyframeSurfaces* kept = nullptr);
  // encode_sampled's middle, once the plan is made: `chosen`'s keyframes built on G of `grid`,
  // their fields rounded (settings.predicted_fields; report().field_coding, else left uncoded), the
  // residual frames fitted to them as stored (settings.residual_frames, fit_decoded_residuals;
  // report().residual_fit), the frame patches and the texture stage (code_textures): what a file
  // written with the report's field coding and texture qualities holds. The bench runs it for each
  // keyframe set and representation it measures, so that it measures what fmenc writes.
  std::unique_ptr<StoredSequence> code(const StageSettings& settings, const KeyframeSelection& chosen, int grid);
  // The field precision options for `chosen`'s keyframes on G of size `grid`: with --grid auto (the
  // worst region bounded), each keyframe's own floor there (keyframe_floor_p99s, measured once per
  // size), so that round_fields holds a keyframe farther from its frame than the reference to what
  // its own floor leaves of the 1% (spec/method.md §5.3).
  FieldPrecisionOptions keyframe_precision(const StageSettings& settings, const KeyframeSelection& chosen, int grid);
  // code's choice of the representation by bytes at equal error (representation_rate.hpp), given
  // the keyframes built and rounded as hl+t: where the options leave the representation open and the
  // fields were kept so far, the same keyframes built and rounded as xyz too, and the one of lower
  // bytes · held-out RMS² kept (an RMS under two fifths of the tolerance read as that) and adopted (report().representation_rate says what
  // was measured); elsewhere `fields` as given. `captured`: the trial frames' captured meshes (rate_trial_frames, trial_meshes; none: no
  // comparison); `builds`: the conformal disk's builds, where code kept `fields` unrounded (candidate_builds.hpp), so that no candidate at
  // an N built before is built again.
  std::unique_ptr<StoredSequence> choose_by_bytes(const StageSettings& settings, const KeyframeSelection& chosen, int grid,
                                                  std::unique_ptr<StoredSequence> fields,
                                                  const std::optional<std::vector<TriangleMesh>>& captured, CandidateBuilds& builds);
  // After choose_by_bytes: the density-equalised disk's candidates (density_candidate.hpp) measured
  // against the one it kept, on the same trial frames (`captured`), added to
  // report().representation_rate; where one is kept, the registrations sample through its map from
  // here on. Elsewhere `kept` as given. D is `made_ahead`'s where that holds it (candidate_disk of
  // the reference frame's map), else made here.
  std::unique_ptr<StoredSequence> choose_density_equalised(const StageSettings& settings, const KeyframeSelection& chosen,
                                                           std::unique_ptr<StoredSequence> kept,
                                                           const std::optional<std::vector<TriangleMesh>>& captured,
                                                           std::future<DiskReparametrisation>* made_ahead = nullptr);
  // One candidate of the choice by bytes at equal error (choose_by_bytes' and
  // choose_density_equalised's): `candidate`'s representation at its N from `builds`, its fields
  // rounded to `precision` (settings.predicted_fields) under the report as the caller set it, then
  // `after_rounding`; its bytes and held-out error on `chosen`'s trial frames (rate_trial_frames,
  // `captured` their meshes) measured into it, and it added to `rate`. Its keyframes, with
  // report().grid its N, where the rule now keeps it; null where not, or where its fields do not
  // reconstruct (kNotConverged: not a candidate, nothing added).
  std::unique_ptr<StoredSequence> measure_candidate(const StageSettings& settings, const KeyframeSelection& chosen, CandidateBuilds& builds,
                                                    const FieldPrecisionOptions& precision, RateCandidate candidate,
                                                    const std::vector<TriangleMesh>& captured, RepresentationRate& rate,
                                                    const std::function<void()>& after_rounding = {});
  // Whether choose_by_bytes compares candidates: the representation is the encoder's to choose and
  // the fields are still in the running (the blends or a radial disk did not already choose
  // positions, the fields converged).
  bool choosing_by_bytes(const StageSettings& settings) const;
  // Every keyframe stored as positions (xyz) from here on, because `why` (which keyframe did not
  // reconstruct, and how far it got): the representation adopted, report().representation_fallback
  // set (a file's settings say it). A segment's assemble takes the fallback a measure made so
  // (segmented_encode.hpp).
  void store_as_positions(const std::string& why);
  // The report's per-frame lines and memory figures, moved to `report` where given.
  void finish_report(const KeyframeSelection& chosen, const StoredSequence& sequence, EncodeReport* report);

 private:
  // of_sampled_frames's steps: the encoder of no frames yet, each frame added, the reference's
  // stores settled once all came.
  SequenceEncoder(const SampledCapture& capture, EncodeOptions options);
  void add_sampled_frame(SampledFrame&& frame);
  void finish_sampled_frames();

  bool vertical_hint_set_ = false;
  // keyframe_precision's, by G's size and the keyframes (fmbench's budgets code several sets with one encoder)
  std::map<std::pair<int, std::vector<int>>, std::vector<double>> keyframe_floors_;
  std::optional<Vec3> vertical_hint_;
  // Per frame of the capture as given, the landmarks ignored on it; and the summaries of frames
  // mapped and dropped at registration: what for_each_sampled_frame hands on of dropped frames.
  std::map<int, std::vector<std::string>> warnings_by_frame_;
  std::map<int, FrameSummary> dropped_summaries_;
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
  FrameMaps maps_;                                             // map_frames's
  FrameRegistrations registrations_;                           // register_frames's
  Representation auto_representation_ = Representation::kHLT;  // choose_representation's choice for an unset representation
  SelectionSamples selection_;                                 // sample_frames's
  EncodeReport report_;
};

// The up direction of the first frame of `capture` from `reference` on (cyclically) that lacks its
// pose landmarks and whose surface says which way is up (find_face_orientation); none when none
// does. `landmarks(i)`: frame i's points, one per name of capture.landmark_names. What map_frames
// gives frames whose surfaces do not say. `progress`: (regions read, regions to read) of the frame
// being read (find_face's, FaceFindingOptions::progress).
std::optional<Vec3> find_vertical_hint(const Capture& capture, int reference, bool largest_component,
                                       const std::function<std::vector<Vec3>(size_t)>& landmarks,
                                       const std::function<void(int, int)>& progress = {});

// ---- The stages (stages/map_frames.cpp, register_frames.cpp, sample_frames.cpp, choose_grid.cpp,
// choose_representation.cpp; the build stage: build_stage.hpp): each reads the encoder's frames as
// map, register and sample left them ----

// 1. Every frame prepared, conformally mapped and normalised (options().conformal, largest_component,
// find_landmarks, landmark_tolerance), its map into encoder.maps(); the landmarks found on the
// frames adopted under their names (nose_tip, nose_bridge, rim_*) and counted in the report. Frames
// that fail are dropped (unless options().strict): from here on the encoder's capture() and frame
// indices are those of the frames kept, and report().dropped names the others.
void map_frames(SequenceEncoder& encoder);
// 2. Every frame registered to the reference (options().registration, tracking), into
// encoder.registrations(); method kFrame first builds the reference's geodesic frame from its disk
// and landmarks, once, and registers through it. Frames that fail are dropped as map_frames drops them.
void register_frames(SequenceEncoder& encoder);
// What every stage after mapping reads of the reference (its map and landmarks `points`, one per
// name of `names`): its disk reparametrised (`equalising`) and, for `method` kFrame, its geodesic
// frame: into `registrations`, with the equalising's figures into `report`. Throws what
// make_geodesic_frame throws, naming the reference.
void set_reference_geometry(FrameRegistrations& registrations, const MappedFrame& reference, const std::vector<std::string>& names,
                            const std::vector<Vec3>& points, const DensityEqualisingOptions& equalising, RegistrationMethod method,
                            EncodeReport& report);
// Adds a mapped frame's found nose tip, up and rim markers to `report`'s counts (`given_rim`: the
// capture gave rim markers of its own, so the frame's found ones are not taken).
void count_found_landmarks(EncodeReport& report, const FrameSummary& frame, bool given_rim);
// 3. Every registered frame on the selection grid (SelectionSamples::kGrid), in the face frame, with
// its rigid head pose: into encoder.selection(), the samples of an earlier sampling replaced.
void sample_frames(SequenceEncoder& encoder);
// 4, 5, 5½: select, N and the representation, over their settings and PlanFrames (encode/plan_keyframes.hpp).
// The plan stage's view of `encoder`'s state after sample_frames (holds references into it).
PlanFrames plan_frames(const SequenceEncoder& encoder);
// choose_representation on `encoder`'s frames, its decision adopted (SequenceEncoder::adopt_representation);
// the settings from the encoder's options where not given.
void adopt_chosen_representation(SequenceEncoder& encoder, const PlanSettings& settings, const KeyframeSelection& chosen, int grid);
void adopt_chosen_representation(SequenceEncoder& encoder, const KeyframeSelection& chosen, int grid);

// The build stage on `encoder`'s frames with its settings from encoder.options(), read back as a
// Sequence (the tests and the bench).
Sequence build_sequence(SequenceEncoder& encoder, const std::vector<int>& keyframes, int grid);

// ---- The stages after the keyframes are built (stages/round_fields.cpp, stages/texture_coding.cpp) ----

// The fields rounded to `precision` (field_precision_options) as the file will store them: what a
// file written with the returned coding (SequenceFileMetadata::field_coding) holds. Fills
// report.field_precision and seconds_precision.
FieldCoding round_fields(const FieldPrecisionOptions& precision, StoredSequence& keyframes, EncodeReport& report);
FieldCoding round_fields(const FieldPrecisionOptions& precision, Sequence& sequence, EncodeReport& report);
// 8, 9: the texture stage over its settings (encode/texture_stage.hpp, stage_settings.hpp);
// texture_frames: its view of `encoder`'s frames (holds references into it).
TextureFrameSource texture_frames(const SequenceEncoder& encoder);
// What the residual fit reads of the frames (residual_fit.hpp): their times, diagonals (the
// selection's) and registered surfaces (`sampler`'s). Holds references into `selection`'s and
// `sampler`'s stores; the second form: `encoder`'s, after sample_frames.
RegisteredFrames registered_frames(const std::vector<CaptureFrame>& frames, const SelectionSamples& selection, FrameSampler sampler);
RegisteredFrames registered_frames(const SequenceEncoder& encoder);

// A segment's encode stores positions because a measure did (SequenceEncoder::store_as_positions):
// the summary's warning for it.
void warn_stored_as_positions(EncodeReport& report);

// ---- The pieces, for tests and the bench ----

// Where the encoder keeps the frames' landmarks (one vector of points a frame), spilled to its
// temporary file or in memory as `mode` says: 1.8 kB a frame of ICT's 74, which kept in the
// capture grew with it for the whole encode.
std::unique_ptr<SpilledItems<std::vector<Vec3>>> make_landmark_store(SpillMode mode);

// Where the capture's landmarks of one frame lie on its disk, paired with the reference's: the
// registration's input. Landmarks missing in either frame are left out; rim_* markers are flagged
// and put exactly on the circle.
DiskLandmarks disk_landmarks(const Capture& capture, size_t reference, const DiskMap& reference_map, size_t frame,
                             const DiskMap& frame_map);
// The same for two frames' points, one per name of `names` (NaN where a frame lacks it).
DiskLandmarks disk_landmarks(const std::vector<std::string>& names, const std::vector<Vec3>& reference, const DiskMap& reference_map,
                             const std::vector<Vec3>& frame, const DiskMap& frame_map);

}  // namespace facemorph
