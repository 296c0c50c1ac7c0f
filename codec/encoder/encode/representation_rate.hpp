// The representation and N chosen by bytes at equal error (issue 44 part 5; spec/method.md §7.14):
// where the options leave the representation open and the blends did not already rule the fields
// out, the encoder codes the chosen keyframes both ways (hl+t and xyz, each rounded to the same
// target error), and where --grid auto's worst region alone allowed a coarser N, the cheaper of the
// two at that N too (coarser_candidates); it measures each one's geometry bytes as the file would hold them and its held-out error on
// a few decoded frames against their captured meshes (the keyframes themselves where no frame lies
// between them: rate_trial_frames), and keeps the one with the lowest
// bytes · error^k, an error under two fifths of the tolerance read as that (a coarser N only where its error stays within the tolerance;
// any candidate but the first only where its worst trial frame's 99th percentile is within the frame patches' bound or not much worse than
// the first's: admitted_worst_region; on the keyframes alone, none with more bytes than the first: buys_only_error_below_the_target).
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/geometry/mesh.hpp"
#include "codec/core/reconstruct/fields.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

namespace facemorph {

struct Capture;
class StoredSequence;

// One candidate as measured: its keyframes' bytes (the file without textures, residuals or patches:
// what differs between the representations) and the mean over the trial frames of the symmetric RMS
// point error of the decoded frame against its captured mesh, of that mesh's bounding-box diagonal
// (fmbench's held-out RMS, on a sample of the frames between keyframes; where none lies between them,
// its keyframe RMS on the keyframes: rate_trial_frames).
struct RateCandidate {
  Representation representation = Representation::kHLT;
  int grid = 0;         // N
  bool coarser = false;  // N coarser than --grid auto's, or a coarser field step: kept only within the tolerance
  uint64_t bytes = 0;
  double held_rms = 0;
  int frames = 0;          // trial frames measured
  double step_scale = 1;  // the field rounding's target error as a multiple of field_precision_options'
  // The largest over the trial frames of the symmetric 99th-percentile point error (fmbench's: both
  // meshes' vertices to the other surface, one percentile of the union), of the captured mesh's
  // diagonal: the worst region as the file shows it before residual frames and patches.
  double worst_p99 = 0;
  double density_equalising = 0;  // positions through the density-equalised disk of this strength (density_candidate.hpp); 0: conformal
};

// What the comparison measured, for the report (measured false: no comparison ran).
struct RepresentationRate {
  bool measured = false;
  std::vector<RateCandidate> candidates;  // hl+t and xyz at --grid auto's N, then at the coarser N where tried
  size_t chosen = 0;
  bool on_keyframes = false;  // measured on the keyframes themselves: no frame lies between them (rate_trial_frames)
  double tolerance = 0;  // the held-out RMS a coarser N must stay within (fraction of the diagonal)
  double worst_bound = 0;  // the worst trial p99 any candidate may reach whatever the first's (the patches' bound)
  double seconds = 0;    // the other candidates' builds and roundings, and every measure
};

// The exchange rate between bytes and held-out error: two candidates are compared by bytes · RMS^k,
// so a candidate may take (1 + e)^k times the bytes for an error 1 + e times lower. k = 2 is the
// elasticity −d ln B / d ln RMS of the encoder's own levers measured on ICT (more keyframes
// 1.7–2.3, a finer N 1.7–2.9; spec/method.md §7.14): the other candidate is valued as if the file
// had been moved along those levers to its error.
inline constexpr double kRateErrorExponent = 2.0;
// The field-step candidate's target error, a multiple of the one every other candidate is rounded to
// (coarser_step_candidate; spec/method.md §7.14).
inline constexpr double kCoarserStepScale = 2.0;
// At most this many frames between keyframes are decoded and measured for each candidate, spread
// evenly over them.
inline constexpr int kRateTrials = 8;

// Held-out error under this share of the tolerance is not bought: the rule reads a candidate's RMS
// as at least kUnboughtErrorShare × the tolerance (rate_cost). The exchange rate above holds where
// the spline's error between keyframes dominates, which a finer N or step barely moves; where the
// keyframes leave almost nothing to predict (a face nearly still, its keyframe budget the 10%), G's
// floor dominates and falls as 1/N² while the bytes grow as N², so bytes · RMS² fell at every finer
// N and kept N = 257 at a sixth of the tolerance: ICT from 10.0 s decimated to 2k vertices
// 61,743 B at 0.078% held-out RMS, six times the bytes a second of its speech at 0.2% costs
// (spec/method.md §7.14, "An error the tolerance does not ask for"). Two fifths, the share of the
// tolerance a frame nothing is predicted for is rounded to (§5.3; that rounding is capped at 0.2%,
// so past a 0.5% tolerance the floor is the larger): under it, no candidate is credited with an error
// the defaults would not hold a lone keyframe to.
inline constexpr double kUnboughtErrorShare = 0.4;

// bytes · max(held_rms, kUnboughtErrorShare × tolerance)^kRateErrorExponent (infinite when nothing
// was measured); a tolerance of 0 reads the RMS as measured.
double rate_cost(const RateCandidate& candidate, double tolerance = 0);
// The candidate the rule keeps: xyz only where its cost is strictly lower than hl+t's (a tie keeps
// the fields, which turn with a rotating head rather than cutting its chords: spec/method.md §5.2).
Representation cheaper_at_equal_error(const RateCandidate& fields, const RateCandidate& positions);
// How much further than the first candidate another may take the worst trial frame's p99 where the
// frame patches bring frames over their bound under it (spec/method.md §7.14): the candidates share
// their keyframes, so between them the p99 is mostly the blend's, which the patches remove either
// way. The largest rise measured where the kept candidate's file then had every frame brought under
// was 14.4% (ict2k24: xyz N = 129 13.8%, its coarser step 14.4% over hl+t at 257), the patches'
// bytes moving by at most 14% of the keyframes' saving. Without patches nothing brings a frame
// back: no rise at all.
inline constexpr double kWorstRegionRise = 1.25;

// Whether `candidate` may replace `first` for its worst region: its worst trial p99 within
// `worst_bound` (the frame patches' bound, spec/method.md §7.19: a frame under it is given no
// patch), or within kWorstRegionRise times the first's (with patches, worst_bound > 0; else no
// worse than the first's). Bytes · RMS² weigh the mean; a candidate that sends the worst frame far
// further over the bound leaves the patches more to bring under, in bytes the choice does not count.
bool admitted_worst_region(const RateCandidate& candidate, const RateCandidate& first, double worst_bound);
// Where the error is measured on the keyframes alone (`on_keyframes`: nothing predicted), every
// candidate was built to the same targets (the grid's 1/2 B, the rounding's two fifths of B, the
// p99 bound), so bytes beyond the first candidate's (the smallest file at the target) buy only
// error below what the user's tolerance set: such a candidate is not kept, whatever its cost
// (spec/method.md §7.14). Between keyframes the error is the prediction's, which no target bounds.
bool buys_only_error_below_the_target(const RateCandidate& candidate, const RateCandidate& first, bool on_keyframes);
// Whether candidates[i], where coarser (a coarser N or field step), may compete: its held-out RMS
// within `tolerance`, or no larger than the lowest of the candidates before it at --grid auto's N
// and step. The tolerance bounds the error coarsening adds; where the capture's own error (its
// noise) puts every candidate over it, a coarser one that adds none is not refused (fmsynth --noise
// 0.002: xyz at the field step x2, 7,024 B at 0.6594% against 11,065 B at 0.6611% at N, tolerance
// 0.5%). Only those before it: a candidate measured later never takes back an admission, so the
// one kept is the last kept or the newest (the encoders keep the sequence of the newest only where
// it becomes the cheapest). Not coarser: always true.
bool coarser_within_tolerance(const std::vector<RateCandidate>& candidates, size_t i, double tolerance);
// Of several (the first hl+t at --grid auto's N, the one kept where no other is cheaper): the index
// of the lowest cost, a coarser N's only where coarser_within_tolerance, any but the
// first only where admitted_worst_region, none that buys_only_error_below_the_target; ties keep the
// earlier.
size_t cheapest_at_equal_error(const std::vector<RateCandidate>& candidates, double tolerance, double worst_bound, bool on_keyframes);
// Adds a measured candidate to `rate` and says whether the rule (cheapest_at_equal_error, with rate's
// tolerance, worst bound and on_keyframes) now keeps it: both disks' candidates are added so.
bool add_candidate(RepresentationRate& rate, const RateCandidate& candidate);

// The coarsest N of --grid auto's floors (N, the resampled floor's 99th percentile) whose floor meets
// `worst_target` (the worst region's share), where it is coarser than `grid`; 0 where none is.
int worst_region_grid(const std::vector<std::pair<int, double>>& floor_p99s, double worst_target, int grid);

// The frames (capture indices) strictly between the first and last keyframes that are not keyframes,
// at most kRateTrials of them spread evenly (the first and the last kept); where there are none (a
// one-frame capture, or every frame a keyframe), the keyframes themselves, spread the same way: each
// candidate's error is then its decoded keyframes' against their captured frames.
std::vector<int> rate_trial_frames(const std::vector<int>& keyframes);

// The geometry bytes of `stored` as a file with `coding` would hold them (textures left out).
uint64_t geometry_bytes(const StoredSequence& stored, const FieldCoding& coding);

// The captured meshes at `frames` (capture indices), read once for every candidate by `threads`
// readers; nullopt where one is not at hand (a staged encode's parts) or no frame is given.
std::optional<std::vector<TriangleMesh>> trial_meshes(const Capture& capture, const std::vector<int>& frames, int threads);

// What held_out_error measures: the mean RMS and the worst 99th percentile (RateCandidate's).
struct HeldOutError {
  double rms = 0;
  double worst_p99 = 0;
};
// The held-out error of `stored` decoded at `frames`' times against `captured` (trial_meshes'), of
// each mesh's diagonal: the mean RMS and the largest p99 over the frames. `threads` decoders at most.
HeldOutError held_out_error(const Capture& capture, const StoredSequence& stored, const std::vector<int>& frames,
                            const std::vector<TriangleMesh>& captured, int threads);

// The coarser N's candidate (--grid auto's worst region, worst_region_grid): the representation
// `cheapest_at_equal_error` kept at --grid auto's N (`on_keyframes` as there), not both. On every capture where both were
// measured at a coarser N (ict2k24, the sample, fmsynth's 30° turning head), the coarser N's winner
// was the same representation as N's (spec/method.md §7.14), so the other one's build, rounding and
// measure changed nothing and cost a quarter of the choice. The fields there only where the reference
// rebuilt from them at that N (`coarser_fields_p99`, called only then: decoded_fields_floor) meets
// `worst_target`, as the resampled floor that allowed the N does not show what a decoder rebuilds
// (§7.6's whole head: 0.48% resampled, 3.79% decoded); else positions, which decode as sampled.
std::vector<std::pair<Representation, int>> coarser_candidates(const std::vector<RateCandidate>& at_grid, double tolerance,
                                                               double worst_bound, bool on_keyframes, int coarser,
                                                               const std::function<double()>& coarser_fields_p99, double worst_target);

// The candidate tried once more with its fields rounded to kCoarserStepScale times the target: the
// one `cheapest_at_equal_error` keeps of those measured (its representation and N; step_scale set).
// Kept in turn only by the same rule, within `tolerance` (a lossier rounding, as a coarser N is) and
// admitted for its worst region.
RateCandidate coarser_step_candidate(const std::vector<RateCandidate>& candidates, double tolerance, double worst_bound, bool on_keyframes);

}  // namespace facemorph
