// What an encode is asked to do (EncodeOptions): every stage's settings, from the frames' mapping to
// the keyframes' texture coding, with their defaults and why they are what they are. One struct for
// the one-process, staged (part files) and segmented encodes alike.
#pragma once

#include "codec/core/image/texture_codec.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/encoder/conformal/conformal.hpp"
#include "codec/encoder/density/density_equalising.hpp"
#include "codec/encoder/encode/field_precision.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/landmarks/landmark_tracking.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <functional>
#include <optional>
#include <string>

namespace facemorph {

inline constexpr int kAutoTextureQuality = -1;
// A texture size M asked for (0 is automatic): the texels per side an encode accepts.
inline constexpr int kMinTextureSize = 16, kMaxTextureSize = 16383;
// A texture quality asked for: the codec's 0-100, and 101 for lossless WebP.
inline constexpr int kMaxTextureQuality = 101;

struct EncodeOptions {
  double keyframe_fraction = 0.10;  // --keyframes 10%: the budget
  // The budget grows where it would leave the mean error predicted between keyframes above this
  // (fraction of the diagonal), or the worst above 3 times it: frames far apart or fast motion get
  // keyframes instead of a budget spread thin (SelectionOptions::error_bound; spec/method.md §7.5).
  // 0: the budget exactly (fmenc --keyframes P sets 0).
  double keyframe_error_bound = kDefaultKeyframeErrorBound;
  // > 0, with that bound: the budget also grows until every frame's predicted 99th-percentile point
  // error between keyframes is within this (SelectionOptions::p99_bound; fmenc --worst-region 0.75%
  // brings fast speech, ICT decimated to 2k and Medusa within issue 44's 1% decoded). Off by default:
  // it costs 3.2x (ICT-2k) to 15x (Medusa) the bytes, and ICT at full resolution still decodes at
  // 1.11% (spec/method.md §7.5).
  double keyframe_p99_bound = 0;
  // A capture whose frames lie on median more than this apart (seconds; below 4 frames a second)
  // keeps every frame as a keyframe (SelectionOptions::sparse_interval). 0: off (fmenc --keyframes P
  // sets 0, as for the bound).
  double sparse_frame_interval = 0.25;
  double max_error = 0;  // --max-error: > 0 replaces the budget by this tolerance (fraction of the diagonal)
  int grid = 0;          // N; 0 = automatic (spec/method.md §7.6)
  // What the keyframes store. Unset (the default; fmenc --representation auto): xyz where most
  // frames register to the reference without interior landmarks (none shared, none tracked) and the
  // keyframes' fields, blended at frames between them, come out farther from those frames than their
  // blended positions (by more than kFieldsBlendMargin): the fields of features that the normalised
  // maps leave apart do not blend into one surface; positions do. choose_representation
  // (sequence_encoder.hpp) decides that. Elsewhere the keyframes are coded as hl+t and as xyz, at N
  // and at a coarser N the worst region allows, and the lowest bytes x RMS^2 is kept, an RMS under
  // two fifths of the tolerance read as that (choose_by_bytes, representation_rate.hpp; spec/method.md §7.14).
  std::optional<Representation> representation;
  RegistrationOptions registration;
  SplineKind spline = SplineKind::kCatmullRom;
  // Residual frames (format 2.3, spec/method.md §7.18): the selection takes fewer keyframes where
  // residuals keep the frames within what the budget's left (SelectionOptions::residuals), and
  // there each frame between keyframes carries a correction of the spline's blend fitted to the
  // stored keyframes and kept where the frame decodes closer with it (fit_decoded_residuals). Where
  // the selection keeps the spline's own keyframes the residuals would be bytes added, so none is
  // fitted and the file is the one written without them (residuals_pay). On by default; fmenc
  // --no-residual-frames turns it off.
  bool residual_frames = true;
  // Frame patches (format 2.4, spec/method.md §7.19): every frame between keyframes whose decoded
  // 99th-percentile point error passes this fraction of its bbox diagonal carries a sparse lattice
  // displacement that brings it under (patch_fit.hpp); 0: none. On by default: a few bytes a frame.
  double patch_bound = 0.01;
  bool texture = true;
  int texture_size = 0;  // M: texels per side of the disk texture; 0 = automatic (as sharp as the capture's, at most 1024)
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
  bool keep_holes_filled = false;  // true: store no holes; the decoder shows the fill
  bool largest_component = false;  // keep each frame's largest surface, drop eyeballs, teeth (else an error)
  int reference_frame = 0;         // the frame every other is registered to
  int threads = 0;                 // 0: one per core
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
  // capture is clean or noisy; where none is predicted, two fifths of the error bound
  // (unpredicted_error_bound; spec/method.md §5.3); false: field_precision's target.
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

// Throws kInvalidArgument naming the first of `options` out of its range, for a capture of
// `frame_count` frames (the reference frame must be one of them).
void check_encode_options(const EncodeOptions& options, int frame_count);

}  // namespace facemorph
