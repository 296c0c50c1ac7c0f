// The density-equalised disk as a candidate of the choice by bytes at equal error (issue 44 part 2;
// spec/method.md §7.11, §7.14). Once choose_by_bytes kept a candidate, the same keyframes are built
// as positions through the density-equalising map D of the reference's disk (strength
// kCandidateDensityStrength, built as set_reference_geometry builds it): at the kept candidate's N,
// and at the coarsest N below it whose resampled floor through D meets the worst region's share.
// Each is rounded like the others and measured the same way; the rule (bytes · RMS², an RMS under two
// fifths of the tolerance read as that, a coarser N within the tolerance) keeps one. Kept, D stays the registrations' reparametrisation for
// every later stage (residuals, patches, holes, texture); the decoder never sees D.
#pragma once

#include "codec/encoder/density/density_equalising.hpp"
#include "codec/encoder/encode/encode_options.hpp"
#include "codec/encoder/encode/encode_report.hpp"
#include "codec/encoder/encode/representation_rate.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

namespace facemorph {

// The strength tried (spec/method.md §7.11's table: 0.5 against 0.25, 0.75 and 1 on ict24 and ict2k24).
inline constexpr double kCandidateDensityStrength = 0.5;

// Whether the candidate is tried: the representation and N are the encoder's to choose (neither
// --representation nor --grid given), no reparametrisation was asked for (--density-equalising,
// --radial-equalising) and none is on (the radial map of a whole head), and the choice by bytes
// measured its candidates.
bool density_candidate_open(const EncodeOptions& options, const EncodeReport& report);
// The same but for the last: whether the candidate will be tried once the choice by bytes has
// measured its candidates (SequenceEncoder::code makes D ahead where it may be).
bool density_candidate_possible(const EncodeOptions& options, const EncodeReport& report);

// The candidate's disk D: the reference frame's disk map density-equalised at
// kCandidateDensityStrength (as set_reference_geometry builds it for --density-equalising 0.5). It
// depends on that map alone.
DiskReparametrisation candidate_disk(const DiskMap& reference);

// The coarsest of `ns` strictly below `below` whose floor p99 (`floor_p99(n)`) is within
// `worst_target`, going down from the finest and stopping at the first that is not (the floor grows
// as N shrinks: on ict24 through D 193 met the 0.75% and 129 did not, two measures rather than
// eight); 0 where none is. What was measured goes to `measured`, coarsest first.
int coarsest_within(std::vector<int> ns, int below, double worst_target, const std::function<double(int)>& floor_p99,
                    std::vector<std::pair<int, double>>* measured);

// Among the `measured` (N, floor p99) strictly between `coarser` and `finer`, the one within
// `worst_target` nearest the geometric mean of the two (the middle in nodes, ~N²); 0 where none is
// or `coarser` is 0 (none within the target: nothing between either).
int rung_between(const std::vector<std::pair<int, double>>& measured, int coarser, int finer, double worst_target);

// D's best candidate so far, compared with the first (the conformal disk's fields at its N) and D's
// alone: not with the conformal disk's coarser step, which D has not been given yet; none where the
// first beats every D candidate.
std::optional<RateCandidate> best_density_equalised(const RepresentationRate& rate);

// The rung between `coarser` and `kept` (rung_between) where D at the coarsest N lost to D at the
// kept N on bytes x RMS² as the rule weighs it (its RMS grew more than its bytes fell: the middle may win, which a measured
// floor alone cannot tell; ict60 before the rungs, D 193 lost to 257); 0 where D's best is another
// (the coarsest won: ict24, D 193) or none is between.
int rung_to_try_between(const RepresentationRate& rate, const std::vector<std::pair<int, double>>& measured, int coarser, int kept,
                        double worst_target);

// Whether D, which won on geometry, is kept once the textures count: its file (geometry + texture
// bytes, each disk's texture at the texture stage's own qualities) is no larger than the conformal
// candidate's. D's texture costs 3-12% more bytes at the same per-pixel PSNR (spec/method.md §7.11),
// which on fast24 and the sample outweighed what D saved on geometry.
bool equalised_file_kept(uint64_t conformal_geometry, uint64_t conformal_texture, uint64_t equalised_geometry, uint64_t equalised_texture);

}  // namespace facemorph
