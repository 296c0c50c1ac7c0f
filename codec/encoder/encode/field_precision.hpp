// How finely a keyframe's fields are stored (spec/method.md §5.3): the quantisation steps chosen
// from the error they cause in the decoded surface, not from each field's own range. H, log λ, the
// tangential components, the band vectors and the boundary curve disturb the reconstruction very
// differently (a step in H is integrated twice; a step in the rim moves the surface directly), so
// each group of arrays gets the step that makes its share of the error equal.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/sequence/sequence.hpp"

#include <array>
#include <functional>
#include <optional>
#include <vector>

namespace facemorph {

class Reconstructor;
class StoredSequence;

// FieldPrecisionOptions::intra_period's "auto": an intra keyframe at least every 10 s of capture,
// as video encoders space theirs (x264's default keyint, 250 frames, is 10 s at 25 fps). A player
// seeking into a stream decodes at most that much; every chain of predicted keyframes is a tenth
// cheaper per keyframe than a new intra one (spec/method.md §5.3).
inline constexpr int kAutoIntraPeriod = 0;
inline constexpr double kAutoIntraSeconds = 10;

// FieldPrecisionOptions::inter_dead_zone's "auto", and the dead zones it tries: plain rounding and
// the zones that measured best where a zone pays (spec/method.md §5.3).
inline constexpr double kAutoDeadZone = 0;
inline constexpr std::array<double, 4> kDeadZoneCandidates = {0.5, 0.55, 0.6, 0.65};

// The worst region's target (issue 44, design §7): every decoded frame's 99th-percentile point
// error within 1% of the bounding box diagonal. The grid takes three quarters of it for its decoded
// floor (choose_grid.cpp), the rounding what the decoded floor leaves of it (spec/method.md §5.3).
inline constexpr double kWorstRegionTarget = 0.01;

struct FieldPrecisionOptions {
  // The RMS displacement of a keyframe's decoded surface that rounding may cause, as a fraction of
  // its bounding box diagonal (spread evenly over the groups of arrays). 1e-4 is a tenth of a
  // millimetre on a 25 cm head: far under the spline's error between keyframes.
  double target_error = 1e-4;
  int intra_period = kAutoIntraPeriod;  // FieldCoding::intra_period, or auto_intra_period's
  // Round per-node fields with error diffusion, pushing the rounding error to high frequencies the
  // reconstruction smooths away (see field_precision.cpp); false: each value to its nearest step.
  bool noise_shaping = true;
  // An inter keyframe's value keeps the previous keyframe's code unless it moved by more than this
  // many steps (the error diffused as always); 0.5 is plain rounding. A kept code is the file's
  // cheapest symbol, but the error a dead zone adds makes the steps finer, and which wins depends
  // on the capture: measured at equal keyframe error, 0.6-0.65 saved 10-14% on Medusa's tracked
  // mesh and cost 5-28% on a noisy fmsynth capture (spec/method.md §5.3). kAutoDeadZone (the
  // default) tries kDeadZoneCandidates and keeps the one whose file is smallest; else in [0.5, 1).
  double inter_dead_zone = kAutoDeadZone;
  // true (the default): every keyframe's surface decoded from its exact fields (and, given a
  // Sequence, its fields, hole level and texture while the steps are chosen) go to a temporary file
  // and are read back one at a time (keyframe_store.hpp); false: they stay in memory. The steps and
  // rounding are the same.
  bool spill = true;
  // The keyframes decoded at once while the steps are measured (0: one per core). The steps and
  // rounding are the same for any count.
  int threads = 0;
  // The worst region's bound on the rounding (spec/method.md §5.3): the decoded floor, the 99th
  // percentile point error of an unrounded keyframe's decode against the captured surface (fraction
  // of the diagonal; the grid's at its N, choose_grid.cpp). Set, the steps are also refined until
  // every keyframe's rounding p99 q (its rounded decode against its unrounded one, the same measure)
  // meets worst_floor + q ≤ worst_target (the two add nearly linearly at the worst points: measured,
  // spec/method.md §5.3, not in quadrature). Unset, or a floor at or over the target (no rounding
  // could meet it): only the RMS target binds.
  std::optional<double> worst_floor = std::nullopt;
  double worst_target = kWorstRegionTarget;
  // Each keyframe's own floor (its sampled surface on G against its captured frame, the resampled
  // 99th percentile; empty: worst_floor for every keyframe). With worst_floor set, keyframe k's
  // rounding is held to worst_target - max(worst_floor, keyframe_floors[k]): a keyframe farther from
  // its frame than the reference (another expression, a turned head) keeps less of the 1%; one at or
  // over the target is not bounded (no rounding could meet it; spec/method.md §5.3).
  std::vector<double> keyframe_floors = {};
};

struct FieldPrecisionReport {
  double target_error = 0;              // the target it was given
  std::vector<double> group_steps;      // per group: H, log λ, tangential, band, positions, rim (0: absent)
  std::vector<double> keyframe_errors;  // each keyframe's measured RMS displacement from rounding / diagonal
  int refinements = 0;                  // times the steps were rescaled after measuring every keyframe
  // The rounding's 99th-percentile budget worst_target − worst_floor / diagonal (0: not bounded),
  // each keyframe's rounding p99 at the chosen steps (an upper bound, its nodes' displacement, where
  // that is within the budget; empty: not bounded), and the scales the bound refused (0: it never bound).
  double rounding_p99_budget = 0;
  double worst_target = 0;  // the worst region's target the budget is left of (1%, raised where the capture's noise is above it)
  std::vector<double> keyframe_p99s;
  // Each keyframe's own budget where its own floor made it smaller (0: that keyframe's floor is at
  // or over the target, not bounded); empty: every keyframe had rounding_p99_budget.
  std::vector<double> keyframe_budgets;
  std::vector<double> keyframe_floors;  // each keyframe's own floor, where keyframe_budgets is not empty
  int worst_region_refusals = 0;
  double inter_dead_zone = 0;           // the dead zone the keyframes were rounded with (auto's choice)
  // The rounded keyframes' bytes in the file without textures (sequence_file_size with this coding
  // alone: representation_rate.hpp's geometry_bytes of the keyframes as rounded), where the auto
  // dead zone's choice measured them to compare its candidates; 0 where nothing was compared (a
  // dead zone given, or no predicted keyframe). The choice by bytes reads it rather than laying the
  // same file out again (spec/method.md §7.14).
  uint64_t geometry_bytes = 0;
  int peak_keyframes_in_memory = 0;     // the most decoded surfaces in memory at once (KeyframeStore)
  uint64_t spilled_bytes = 0;           // written to the temporary file (0 without options.spill)
};

// A keyframe's surface decoded from its exact fields as this stage decodes every keyframe it
// measures rounding against: from the harmonic surface (no warm start, so which reconstructor
// takes it changes nothing), to a tolerance of 1e-8 of the boundary's diameter in at most 400
// iterations. The grid's worst-region bound decodes the reference frame so (choose_grid.cpp).
// Throws what Reconstructor::reconstruct throws (kNotConverged, kNumerical, kInvalidArgument).
std::vector<Vec3> decode_keyframe_exactly(Reconstructor& reconstructor, const GridFields& fields);

// The intra period "auto" gives `sequence`: ⌊kAutoIntraSeconds / its mean keyframe interval⌋, at
// least 1 (K for a single keyframe). Assumes a sequence validate_sequence accepts.
int auto_intra_period(const Sequence& sequence);

// One group's calibrated step (spec/method.md §5.3): probes `error_at` (the decoded error of
// keyframe 0 with that group alone rounded at a step) up to five times, from spread / 4096, each
// next probe where the power law fitted through the readings above share / 8 meets `share`; returns
// the last fit's step, or the coarsest probed step whose error met the share where that is more
// than 4x coarser.
double calibrated_step(const std::function<double(double)>& error_at, double share, double spread);

// Chooses the steps on keyframe 0 (a probe step per group, decoded, scaled to the target: rounding
// error is proportional to the step), rounds every keyframe of `sequence` to them
// (round_to_field_steps; the keyframes the file may predict from the previous one through the dead
// zone), measures every keyframe's decoded error and rescales all steps until the
// worst keyframe lies within [0.8, 1.25] of the target (the coarsest that met it is kept; none:
// kNotConverged). The hole level's step is a sixteenth of G's spacing.
// With the dead zone auto, does that for each of kDeadZoneCandidates on the fields alone, encodes
// each result, and keeps the smallest (plain rounding where no keyframe is predicted).
// Throws kInvalidArgument for a target that is not positive and finite, a dead zone neither auto nor
// in [0.5, 1) or a negative intra period, and what reconstruction throws for fields it cannot decode.
FieldCoding choose_field_coding(Sequence& sequence, const FieldPrecisionOptions& options = {}, FieldPrecisionReport* report = nullptr);
// The same on keyframes in the encoder's store, read one at a time (each trial's file too, through
// the writer's source), with the rounded fields, hole levels and poses put back: what the search
// holds in memory does not grow with the keyframes (spec/method.md §7.15).
FieldCoding choose_field_coding(StoredSequence& keyframes, const FieldPrecisionOptions& options = {},
                                FieldPrecisionReport* report = nullptr);

// Rounds every keyframe's fields to `coding`'s steps as choose_field_coding does (error diffusion
// per options.noise_shaping; the keyframes the file may predict, those not a multiple of the intra
// period, through the dead zone), without choosing or checking anything else.
// Throws kInvalidArgument for a dead zone outside [0.5, 1) (auto among them: it is chosen, not
// applied) or a sequence that fails validation.
void round_keyframes(Sequence& sequence, const FieldCoding& coding, const FieldPrecisionOptions& options);

// Rounds the stored keyframes to `coding`'s steps and intra period as choose_field_coding rounds
// them to its own (options.inter_dead_zone applied, not chosen), putting the rounded fields, hole
// levels and poses back, and returns each keyframe's decoded error (RMS displacement / diagonal) at
// those steps. A segment of a long encode (spec/method.md §7.17) codes its keyframes so, with the
// steps its capture's segments settled together. Throws kInvalidArgument as round_keyframes.
std::vector<double> apply_field_coding(StoredSequence& keyframes, const FieldCoding& coding, const FieldPrecisionOptions& options);

}  // namespace facemorph
