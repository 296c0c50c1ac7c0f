// The decoder that plays a sequence back at any time t (spec/method.md §7): it blends the keyframes
// along a spline, reconstructs the face, cuts the holes and places it by the blended pose.
#pragma once

#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/sequence/sequence.hpp"

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace facemorph {

struct DecodeOptions {
  bool cut_holes = true;  // false: keep the fill (--keep-holes-filled)
  bool texture = true;    // blend the texture
  // Extrapolation past the sane range (KeyframeSpline::sane_range) is an error (kOutOfRange)
  // unless this is set: then t is clamped to the range.
  bool clamp_to_sane_range = false;
  // Extrapolate as far as asked, continuing the end pieces (for measuring how extrapolation
  // degrades; a player should not).
  bool ignore_sane_range = false;
  ReconstructOptions reconstruct;  // `start` is set by the decoder
  // When the reconstruction does not converge, show the spline of the keyframes' own surfaces
  // (the reconstruction's start; DecodedFrame::fell_back says so) instead of failing
  // (reconstruct.throw_on_failure) or showing the last iterate. A player wants a frame.
  bool fall_back_to_start = true;
  // Start the reconstruction from that spline plus the correction (decoded − spline) of the last
  // two frames continued to t, when they lie within two capture frame periods of t: a clip then
  // takes fewer steps. The result then depends on the frames decoded before it, within the
  // reconstruction's tolerance; false makes every frame a function of t alone.
  bool continue_correction = true;
  // What this call may do, in work units (WorkMeter, spec/container.md §10.3); unset: the source's
  // limit (DecoderLimits::max_work of an opened file, none for a sequence in memory), 0: no bound.
  // Past it the call throws kLimit naming max_work, and keeps what it finished — keyframes decoded,
  // surfaces reconstructed, the reconstruction it stopped in — so that calling again goes on.
  std::optional<uint64_t> max_work = std::nullopt;
};

struct DecodedFrame {
  double time = 0;                   // the time decoded (after any clamp)
  std::vector<Vec3> grid_positions;  // every node of G, in capture coordinates
  TriangleMesh mesh;                 // G's faces (holes cut unless asked not to), UV = (w + 1) / 2
  Image texture;                     // blended, clamped to 0..255; empty without texture
  std::vector<double> hole_level;    // the blended level set per node of G (< 0 inside a hole); empty without holes
  RigidPose pose;
  SplineWeights weights;   // the keyframes that made it and their weights (with the residuals' correction)
  int iterations = 0;      // reconstruction steps
  bool converged = true;   // false only when the caller asked for the best effort
  double change = 0;       // the reconstruction's last step, relative to the rim's diameter
  bool fell_back = false;  // not converged: the frame is the spline of the keyframes' surfaces
};

// Plays a sequence back. Keeps the multigrid solver of G's Laplacian and, lazily, the keyframes' own
// decoded surfaces (at most the source's surfaces_kept(), the least recently used dropped first): a
// frame starts from the spline of those surfaces (exact fixed points of their fields), so it is
// close from the first step wherever t jumps. Not thread-safe: one decoder per thread; several
// decoders may share one source.
class SequenceDecoder {
 public:
  // Validates the sequence (kInvalidArgument).
  explicit SequenceDecoder(std::shared_ptr<const Sequence> sequence);
  explicit SequenceDecoder(std::shared_ptr<const KeyframeSource> source);

  const SequenceOutline& outline() const { return source_->outline(); }
  const std::shared_ptr<const KeyframeSource>& source() const { return source_; }
  const KeyframeSpline& spline() const { return spline_; }
  const GridGeometry& geometry() const { return reconstructor_.geometry(); }
  // Keyframe surfaces held now (at most source().surfaces_kept()).
  size_t surfaces_held() const { return surface_order_.size(); }
  // Why keyframe k could not be reconstructed, remembered so that every later frame that needs it
  // fails at once (empty: it could, or has not been tried).
  const std::string& keyframe_failure(size_t k) const { return keyframe_failures_.at(k); }
  // Keyframe surfaces reconstructed so far, tried and failed ones and ones made again after being
  // dropped included: what the surface cache saves.
  size_t keyframe_reconstructions() const { return keyframe_reconstructions_; }

  // The frame at time t (seconds from the capture's first frame). Throws kOutOfRange beyond the
  // sane range unless clamping, kNotConverged / kNumerical as Reconstructor::reconstruct, and what
  // the source throws for a keyframe it cannot give.
  DecodedFrame decode(double t, const DecodeOptions& options = {});

 private:
  DecodedFrame decode_metered(double t, const DecodeOptions& options, WorkMeter& work);
  std::shared_ptr<const std::vector<Vec3>> keyframe_surface(size_t k, const GridFields& fields, const ReconstructOptions& options,
                                                            WorkMeter& work);
  // The frame's reconstruction, going on from where the work limit stopped the last call at t.
  ReconstructResult reconstruct_frame(double t, const GridFields& fields, ReconstructOptions options, WorkMeter& work);
  // The suspension for keyframe k's surface (keyframe) or the frame at t: the pending one where it
  // is that reconstruction's with the same options, else emptied for it.
  ReconstructSuspension& suspension_for(bool keyframe, size_t k, double t, const ReconstructOptions& options);
  // The start for t from the spline `start` and the corrections of the last frames (empty: none).
  std::vector<Vec3> predicted_start(double t, const std::vector<Vec3>& start, const DecodeOptions& options) const;
  void remember_correction(double t, const ReconstructResult& result, const std::vector<Vec3>& start);

  std::shared_ptr<const KeyframeSource> source_;
  KeyframeSpline spline_;
  Reconstructor reconstructor_;
  std::vector<Vec3> rotation_vectors_;  // unwrap_rotations(outline().poses), once
  // Keyframe surfaces in the face frame (null until first used, or after being dropped), and the
  // keyframes holding one, most recently used first.
  std::vector<std::shared_ptr<const std::vector<Vec3>>> keyframe_surfaces_;
  std::vector<size_t> surface_order_;
  // Why keyframe k could not be reconstructed (empty: it could, or was not tried): a keyframe that
  // fails once fails at once ever after, instead of running its iteration again on every call.
  std::vector<std::string> keyframe_failures_;
  size_t keyframe_reconstructions_ = 0;
  // A reconstruction the work limit stopped (at most one: a call stops at its first refusal, and the
  // next call that needs it meets it first), with what it reconstructs.
  struct Pending {
    bool keyframe = false;
    size_t k = 0;
    double t = 0;
    int max_iterations = 0, anderson_depth = 0, stall_iterations = 0;
    double tolerance = 0, damping = 0;
    ReconstructSuspension state;
  } pending_;
  // The last frames' corrections (reconstruction − spline start, face frame), newest first.
  struct History {
    int count = 0;
    double time[2] = {0, 0};
    std::vector<Vec3> correction[2];
  } history_;
};

}  // namespace facemorph
