// Fitting a frame patch (spec/method.md §7.19): the sparse lattice displacement that brings a decoded
// frame's worst region back onto its captured frame, fitted against what the decoder shows (the
// decoded frame from the stored, rounded keyframes) and rounded as the file stores it.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/core/sequence/pose.hpp"

#include <optional>
#include <vector>

namespace facemorph {

struct DecodeOptions;

// What the decoder shows at a captured frame's time: G's nodes in capture coordinates, the blended
// hole level (empty without holes) and the pose that placed them.
struct ShownFrame {
  std::vector<Vec3> positions;
  std::vector<double> hole_level;
  RigidPose pose;
};

struct PatchFitOptions {
  int lattice = 33;        // C
  double bound = 0.01;     // the 99th-percentile point error a frame should reach, of the diagonal
  double step_units = 0;   // the rounding step of a displacement component, capture units (> 0)
  double smoothing = 0.1;  // weight of the lattice's differences against the samples' misfit
};

struct PatchFit {
  FramePatch patch;       // time and C set; empty `nodes`: no patch helps
  double p99_before = 0;  // the shown frame's 99th-percentile point error, of the diagonal
  double p99_after = 0;   // with the rounded patch
  double threshold = 0;   // the offset (of the diagonal) above which samples chose the moving nodes
  // Patches the search's approximate p99 put under the bound, measured exactly, and of them those the
  // exact p99 put over it (passed over for the next try).
  int exact_checks = 0;
  int approximate_misses = 0;
};

// How the encoder's measures decode a frame (the fit here, the representation's trials): geometry
// alone, each frame a function of t alone (no correction carried from the previous frame), a
// reconstruction that fails returned rather than thrown.
DecodeOptions shown_decode();

// The mesh the decoder shows for these node positions (holes cut where `hole_level` is not empty).
TriangleMesh shown_mesh(const DiskGrid& grid, const std::vector<Vec3>& positions, const std::vector<double>& hole_level);

// `shown` with the patch's displacement (face frame, rotated by the shown pose) added at every node.
std::vector<Vec3> patched_positions(const DiskGrid& grid, const ShownFrame& shown, const FramePatch& patch);

// The patch for `captured` (capture coordinates) at time t: moves only lattice nodes near samples
// (captured vertices and shown nodes, each to the other surface) whose offset exceeds a threshold,
// lowered from the bound (1.0, 0.9 … 0.3 × bound) until the rounded patch brings the frame's p99
// under bound · kPatchBoundMargin (or to the lowest threshold tried); displacements rounded to
// multiples of step_units, kept whole: the nodes that lower the frame's RMS but not its p99 are
// cheaper held-out RMS than any other choice (spec/method.md §7.19, "Thinning withdrawn"). `grid`
// is the shown frame's G.
PatchFit fit_frame_patch(const DiskGrid& grid, const ShownFrame& shown, const TriangleMesh& captured, double t,
                         const PatchFitOptions& options);

// What fit_frame_patches did, for the encoder's report (99th-percentile point errors of the decoded
// frames against their captured meshes, symmetric as fmbench measures them, of each frame's diagonal).
struct PatchFitReport {
  int frames_over = 0;      // frames between keyframes whose decoded p99 passed the bound
  int frames_patched = 0;   // patches with moving nodes
  int frames_pinned = 0;    // empty patches: frames beside patched ones held at the blend (their own p99)
  int frames_unmet = 0;     // frames over the bound no patch brought under it (kept at the best one found)
  size_t nodes = 0;         // moving lattice nodes, every patch together
  int exact_checks = 0;        // of the fits of the chosen patches (PatchFit): patches measured exactly
  int approximate_misses = 0;  // and of them, those over the bound the approximate measure put under it
  double worst_before = 0;  // over the frames between keyframes, without patches
  double worst_after = 0;   // with them
  double seconds = 0;
};

class StoredSequence;
struct Capture;

// The lattice sizes a patch tries, coarsest first (it takes the first that brings the frame under
// the bound): C = 17 measured fewest bytes on every capture (spec/method.md §7.19).
inline constexpr int kPatchLattices[] = {17, 33, 65};
// The rounding step of a displacement: the power of two at or below this fraction of the bound, of
// the smallest captured diagonal. 0.8 (0.8% of the diagonal at the default 1%): the fit checks the
// rounded patch against the bound, and a coarse step codes in fewer bytes what meets it (Medusa's
// patches ~2.9 kB at a step of 0.2% of the diagonal, ~2.5 kB at 0.4%, ~1.9 kB at 0.8%; a step above
// the bound could not meet it; spec/method.md §7.19).
inline constexpr double kPatchStepShare = 0.8;
// A frame the step above cannot bring under the bound tries steps of 1/2 and 1/4 of it.
inline constexpr int kPatchFinerSteps = 3;
// Patches are fitted to this share of the bound, so that the decoder's frame, which may differ from
// the encoder's within the reconstruction's tolerance, stays under it.
inline constexpr double kPatchBoundMargin = 0.98;
// fit_frame_patches decodes and measures each frame between keyframes once and keeps it (its nodes,
// hole levels and distances to its captured mesh: 40 bytes a node, 12 a captured vertex) for the
// pinning rounds while the frames take no more than this; a longer capture's frames are decoded and
// measured again by each round that measures them (the same patches). As small as
// SelectionSamples' cache, so that the encode's memory stays flat in the capture's length
// (spec/method.md §7.15): 64 MB keeps ~23 frames at N = 257, every frame of the captures measured.
inline constexpr size_t kShownFramesMemory = size_t{64} << 20;

// The frame patches for `stored` (its keyframes and residual frames as the file holds them, no
// patches yet), capture frames `keyframes` of `capture`: every captured frame strictly between two
// keyframes decoded from `stored` (at its time on the file's lattice) and measured against its
// captured mesh; each one whose p99 passes `bound` gets the patch of fit_frame_patch (the first
// lattice of kPatchLattices that meets bound · kPatchBoundMargin, else the best) where it lowers the
// p99; then every other frame between keyframes is measured with the patches interpolated, and one
// made worse than both the bound and its own p99 gets an empty patch (the decoder then shows it
// unpatched). No frame decodes worse than without patches. None where the captured meshes are not
// on disk (a staged encode's parts assembled elsewhere). Leaves `stored`'s patches empty. Runs on
// up to `threads` threads (0: one per core), one decoder each; the patches are the same for any count,
// and for any `kept_frames_memory` (kShownFramesMemory's).
std::vector<FramePatch> fit_frame_patches(const Capture& capture, StoredSequence& stored, const std::vector<int>& keyframes, double bound,
                                          PatchFitReport* report = nullptr, int threads = 1,
                                          size_t kept_frames_memory = kShownFramesMemory);

// Of the frames at `times` that hold no patch, those whose patches interpolated in t
// (frame_patch_displacements) the empty patches just inserted at `pins` change: each pin is a new neighbour of the frames of its
// interval with no other patch of `patches` (sorted by time, the pins among them) between it and
// them. A pinning round measures these again; the other frames show what the round before measured.
std::vector<char> frames_beside_pins(const std::vector<double>& key_times, const std::vector<FramePatch>& patches,
                                     const std::vector<double>& pins, const std::vector<double>& times);

// The bytes a patch takes in a file before compression (its node gaps and rounded displacements as
// varints), for the step `step_units` (capture units).
std::vector<uint8_t> patch_payload(const FramePatch& patch, double step_units);

}  // namespace facemorph
