// fmenc: encodes a capture into a .fmv file (spec/container.md): every frame made a disk and mapped
// conformally, registered to the reference frame, keyframes chosen by the spline's predicted error,
// each keyframe's fields, pose, holes and texture written. The file is written under a temporary
// name and renamed into place, so a failed encode leaves any earlier file untouched. Given a .fmv
// file instead of a capture, it re-codes it: the same keyframes, fields rounded to --field-error (auto:
// the file's own steps kept).
#include "codec/core/container/file_layout.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/encoder/encode/encode_settings.hpp"
#include "codec/encoder/encode/options_json.hpp"
#include "codec/encoder/encode/segment_join.hpp"
#include "codec/encoder/encode/segmented_encode.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/staged_encode.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tools/tool_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <optional>

namespace {

using namespace facemorph;

// A fault in the file being re-coded, met while the writer reads it: carried past the writer, which
// names its own output on every facemorph::Error, so the error names the input alone.
struct InputFault {
  std::exception_ptr error;
};

// What `read` returns, any facemorph::Error it throws carried as an InputFault.
template <typename Read>
auto reading_input(const Read& read) {
  try {
    return read();
  } catch (const Error&) {
    throw InputFault{std::current_exception()};
  }
}

// The opened input as the writer reads it, each of its errors turned into an InputFault.
class InputSource final : public KeyframeSource {
 public:
  explicit InputSource(std::shared_ptr<const KeyframeSource> file) : file_(std::move(file)) {}
  const SequenceOutline& outline() const override { return file_->outline(); }
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override {
    return reading_input([&] { return file_->keyframe(k); });
  }
  std::shared_ptr<const Image> texture(size_t k) const override {
    return reading_input([&] { return file_->texture(k); });
  }
  size_t texture_owner(size_t k) const override { return file_->texture_owner(k); }
  size_t surfaces_kept() const override { return file_->surfaces_kept(); }
  uint64_t bytes_held() const override { return file_->bytes_held(); }
  std::string name() const override { return file_->name(); }

 private:
  std::shared_ptr<const KeyframeSource> file_;
};

// Re-codes an existing file: keyframes, grid, poses and holes kept; the fields' rounding chosen
// again from a given --field-error (from the file's values, so never finer than what it held), or
// with auto kept as the file states them (a 16-bit file's too: its header states the 65535ths of
// each array's range the writer took, spec/container.md §5); textures
// re-encoded at `quality` (auto: the fallback quality, as there are no frames between keyframes to
// measure the blend against).
void recode(const std::filesystem::path& input, const std::filesystem::path& output, const EncodeOptions& options, int quality,
            TextureCoding texture_coding, bool quiet) {
  if (quality == kAutoTextureQuality) quality = options.texture_coding.fallback_quality;
  SequenceFileInfo info;
  const bool keep = options.auto_field_error;
  // Keeping the file's steps needs nothing of the fields at once: the writer reads the file's
  // keyframes one at a time through a source whose cache the decoder's budget bounds, as a player
  // reads it, where the whole sequence decoded held every keyframe's texture (K x 3 M^2 bytes) and
  // refused a file whose keyframes together pass the budget (spec/method.md §7.12). Rounding again
  // measures every keyframe, so that reads the whole sequence.
  std::shared_ptr<const KeyframeSource> source;
  Sequence sequence;
  if (keep) {
    source = std::make_shared<InputSource>(open_sequence_source(input, kDefaultDecoderLimits, &info));
  } else {
    sequence = read_sequence_file(input, &info);
  }
  SequenceFileMetadata metadata = info.metadata;
  metadata.encoder.clear();
  metadata.texture_quality = quality;
  metadata.texture_codec = options.texture_codec;
  metadata.texture_coding = texture_coding;
  metadata.field_coding = {};
  FieldPrecisionReport precision;
  // --field-error auto keeps the file's steps (every file states them, a 16-bit file its 65535ths):
  // its values are whole multiples of those steps, so the codes and bytes stay, where rounding
  // them again (0.01%, as a file holds nothing to measure a floor on) added bytes and error: one ICT
  // frame, +43% at 0.01%, +21% at its own target (spec/method.md §5.3).
  if (keep) {
    metadata.field_coding = info.metadata.field_coding;
    // A given --intra-period regroups the same codes (how they are predicted, not how they are
    // rounded): honoured, as before the steps were kept; auto keeps the file's groups.
    if (options.field_precision.intra_period != kAutoIntraPeriod) metadata.field_coding.intra_period = options.field_precision.intra_period;
  } else if (options.predicted_fields) {
    metadata.field_coding = choose_field_coding(sequence, options.field_precision, &precision);
  }
  if (source) {
    try {
      write_sequence_file(output, *source, metadata);
    } catch (const InputFault& fault) {
      std::rethrow_exception(fault.error);
    }
  } else {
    write_sequence_file(output, sequence, metadata);
  }
  if (quiet) return;
  std::printf("fmenc: %s re-coded to %s: %llu bytes (was %llu)\n", input.c_str(), output.c_str(),
              static_cast<unsigned long long>(std::filesystem::file_size(output)), static_cast<unsigned long long>(info.file_bytes));
  if (keep) std::printf("  fields kept at the file's steps (--field-error auto; a number rounds them again)\n");
  if (!precision.keyframe_errors.empty()) {
    std::printf("  fields rounded to %.3g%% of the diagonal (RMS; worst keyframe %.3g%%)\n", 100 * options.field_precision.target_error,
                100 * *std::max_element(precision.keyframe_errors.begin(), precision.keyframe_errors.end()));
  }
}

std::string dead_zone_candidates() {
  std::string out;
  for (double zone : kDeadZoneCandidates) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", zone);
    out += (out.empty() ? "" : ", ") + std::string(text);
  }
  return out;
}

double parse_dead_zone(const std::string& text) {
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used != text.size() || !(value >= 0.5 && value < 1)) throw std::out_of_range(text);
    return value;
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, "--inter-dead-zone '" + text + "' is neither auto nor a number in [0.5, 1)");
  }
}

double parse_radial(const std::string& text) {
  if (text == "auto") return kAutoRadial;
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used != text.size() || !(value >= 0 && value <= 1)) throw std::out_of_range(text);
    return value;
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, "--radial-equalising '" + text + "' is neither auto nor a number in [0, 1]");
  }
}

// What fminfo shows of the frames the encoder dropped or mapped another way (spec/container.md §8).
// --frames A:B: frames A to B-1 of the capture (0-based, B excluded; B may be past its end).
FrameRange parse_frames(const std::string& text, int count) {
  const size_t colon = text.find(':');
  try {
    if (colon == std::string::npos) throw std::invalid_argument(text);
    size_t used_a = 0, used_b = 0;
    const long a = std::stol(text.substr(0, colon), &used_a), b = std::stol(text.substr(colon + 1), &used_b);
    if (used_a != colon || used_b != text.size() - colon - 1 || a < 0 || b <= a) throw std::out_of_range(text);
    if (a >= count) {
      throw Error(ErrorCode::kInvalidArgument,
                  "--frames " + text + ": the capture has " + std::to_string(count) + " frames (0:" + std::to_string(count) + ")");
    }
    return {static_cast<int>(a), static_cast<int>(std::min<long>(b, count))};
  } catch (const std::logic_error&) {
    throw Error(ErrorCode::kInvalidArgument, "--frames '" + text + "' is not A:B, frames A to B-1 (0-based, A < B)");
  }
}

// --stage check: each part read whole, every record checked (and, with --frames, holding those
// frames); one line each.
void check_parts(const std::vector<std::string>& parts, const std::string& frames, const Capture* capture, const EncodeOptions& options,
                 bool quiet) {
  const std::string fingerprint = capture ? capture_fingerprint(*capture) : "";
  for (const std::string& path : parts) {
    const PartReader reader(path);
    reader.verify();
    if (capture &&
        (reader.header().capture_id != fingerprint || reader.header().capture.root != std::filesystem::absolute(capture->root))) {
      throw Error(ErrorCode::kInvalidArgument, path + ": was sampled from another capture than " + capture->root.string());
    }
    if (capture) check_part_settings(reader, options);
    if (!frames.empty()) {
      const FrameRange want = parse_frames(frames, reader.header().capture.frame_count);
      const FrameRange have = reader.header().range;
      if (have.first != want.first || have.end != want.end) {
        throw Error(ErrorCode::kInvalidArgument,
                    path + ": holds frames " + std::to_string(have.first) + ":" + std::to_string(have.end) + ", not " + frames);
      }
    }
    if (quiet) continue;
    const PartHeader& h = reader.header();
    std::printf("%s: part %u.%u of capture %s (%s): frames %d:%d of %d, reference frame %d, %llu bytes, written by %s\n", path.c_str(),
                kPartMajorVersion, h.minor_version, h.capture_id.c_str(), h.capture.root.c_str(), h.range.first, h.range.end,
                h.capture.frame_count, h.capture.reference, static_cast<unsigned long long>(reader.file_bytes()), h.encoder.c_str());
  }
}

// Where a segment stage's time went: what every segment repeats (the parts read, the choices made
// from all of them) and its own share.
void print_segment_seconds(const EncodeReport& r, bool measure) {
  if (measure) {
    std::printf(
        "  reading the parts %.1f s and choosing the keyframes, N and representation %.1f s (every measure); the keyframes on G and "
        "their fit %.1f s, field precision %.1f s (this segment's)\n",
        r.seconds_reading_parts, r.seconds_planning, r.seconds_keyframes, r.seconds_precision);
  } else {
    std::printf(
        "  reading the parts %.1f s (every segment; the keyframes, N and representation are the measures'); the keyframes on G and their "
        "fit %.1f s, rounding to the settled steps %.1f s (this segment's)\n",
        r.seconds_reading_parts, r.seconds_keyframes, r.seconds_precision);
  }
}

// fmenc's command line as given: read into these by declare_options, checked and turned into the
// encoder's options by encode_options and check_stage.
struct Arguments {
  std::vector<std::string> inputs;
  std::string output, stage = "all", frames, check_capture, keyframes = "10%", max_error, worst_region = "0", patch_bound = "1%",
                      grid = "auto", registration = "gmf", spline = "catmull-rom", representation = "auto", landmarks;
  double fps = 0;
  std::string field_error = "auto", field_rounding = "shaped", keyframe_fit = "on";
  std::string texture_size = "auto", quality_text = "auto", texture_codec = "avif", texture_coding = "sequence";
  int threads = 0, reference = 0, frames_per_part = 200;
  std::string segment;
  std::vector<std::string> measures;
  std::string intra_period = "auto";
  std::string inter_dead_zone = "auto";
  double density_equalising = EncodeOptions{}.density_equalising.strength;
  std::string radial_equalising = "auto";
  bool no_texture = false, no_texture_sharing = false, track_landmarks = false, largest_component = false, keep_holes_filled = false,
       quiet = false, strict = false, residual_frames = true;
};

void declare_options(CLI::App& app, Arguments& a) {
  app.add_option("capture", a.inputs,
                 "Capture folder (capture.json), a plain folder of OBJ/PLY frames (with --fps, --landmarks), or a .fmv file to re-code; "
                 "with --stage assemble or check, the part files")
      ->required();
  app.add_option("-o,--output", a.output, "The .fmv file to write (with --stage sample, the part file)");
  app.add_option(
         "--stage", a.stage,
         "all | sample | assemble | measure | check | ranges. sample: map, register and sample --frames A:B into a part file (.fms); "
         "assemble: the "
         "parts covering the capture into the .fmv, given the options the parts were sampled with (with --segment S/N and --measures, "
         "segment S's file); measure: what segment --segment S/N settles with the others (a measure file); check: read and check part "
         "files (spec/part-file.md)")
      ->capture_default_str();
  app.add_option(
      "--segment", a.segment,
      "S/N: with --stage measure, measure segment S of N (0-based) of the keyframes' groups; with --stage assemble and --measures, "
      "code segment S into a segment file that fmcat joins with the others (spec/method.md 7.17)");
  app.add_option("--measures", a.measures, "With --stage assemble --segment: every segment's measure file (comma-separated)")
      ->delimiter(',');
  app.add_option("--frames", a.frames,
                 "With --stage sample: frames A to B-1 of the capture (A:B, 0-based; B may be past the end); with --stage check: the "
                 "frames the part must hold");
  app.add_option("--capture", a.check_capture, "With --stage check: the capture the parts must come from, sampled with these options");
  app.add_option("--frames-per-part", a.frames_per_part,
                 "With --stage ranges: print the ranges A:B of this many frames the capture splits into")
      ->capture_default_str();
  app.add_option("--fps", a.fps, "Frame rate of a plain folder of meshes");
  app.add_option("--landmarks", a.landmarks,
                 "Landmarks CSV of a plain folder (frame,name,x,y,z), or auto: ignore the capture's landmarks and find the nose tip, "
                 "the face's up direction and rim markers from the geometry (frames without landmarks get them found anyway)");
  app.add_option("--keyframes", a.keyframes, "Keyframe budget, a fraction of the frames (10% or 0.1)")->capture_default_str();
  app.add_option("--max-error", a.max_error,
                 "Instead of a budget: as many keyframes as keep the predicted error below this (of the bbox diagonal, e.g. 0.5%)");
  app.add_option("--worst-region", a.worst_region,
                 "With the default budget: more keyframes until every frame's predicted 99th-percentile point error between keyframes "
                 "is within this (of the bbox diagonal, e.g. 0.75%; 0: no such bound, the default)")
      ->capture_default_str();
  app.add_option("--patch-bound", a.patch_bound,
                 "Frames between keyframes whose decoded 99th-percentile point error passes this (of the bbox diagonal) carry a patch, a "
                 "sparse lattice displacement that brings them under it (format 2.4's PTCH, range-coded since 2.5; spec/method.md §7.19; 0: none)")
      ->capture_default_str();
  app.add_option("--grid", a.grid,
                 "Grid size N of the disk grid, or auto: the smallest whose resampling floor (RMS) is within the largest of 0.02%, the "
                 "frame noise and half the error between keyframes (half the error bound where none is predicted: one frame, every frame "
                 "a keyframe; 0.5% by default, or --max-error), capped by the mesh's density, then raised until the reference's worst "
                 "region (99th percentile, resampled and decoded) is within 0.75%; the fields' rounding then keeps it within 1%")
      ->capture_default_str();
  app.add_option("--texture", a.texture_size, "Texels per side of the disk texture, or auto (as sharp as the capture's, at most 1024)")
      ->capture_default_str();
  app.add_option("--quality", a.quality_text,
                 "Texture quality (of --texture-codec, 0-100; above 100 lossless WebP), or auto: each keyframe's from the texture blend's "
                 "error beside it")
      ->capture_default_str();
  app.add_option("--texture-codec", a.texture_codec,
                 "avif | webp: how keyframe textures are stored (AVIF takes ~30% fewer bytes at equal PSNR)")
      ->capture_default_str();
  app.add_option("--texture-coding", a.texture_coding,
                 "sequence | stills: lossy AVIF textures as one AV1 image sequence per group of keyframes (format 2.1; 1.8-5x fewer bytes) "
                 "or one still each (format 2.0's); WebP and lossless textures are stills")
      ->capture_default_str();
  app.add_flag(
      "--residual-frames,!--no-residual-frames", a.residual_frames,
      "on by default: where the selection can take fewer keyframes for them, frames between keyframes carry a correction of the "
      "spline's blend, fitted to the stored keyframes and kept where the frame decodes closer with it (format 2.3's RSDW); elsewhere "
      "none is written and the file is the one --no-residual-frames writes (spec/method.md §7.18)");
  app.add_flag(
      "--no-texture-sharing", a.no_texture_sharing,
      "keep every keyframe's own texture: by default keyframes painted from one captured image show one texture, stored once (format 2.2), "
      "where it stays within the texture coding's coarsest PSNR (30 dB) of their own");
  app.add_option("--registration", a.registration, "moebius | gmf | frame")->capture_default_str();
  app.add_option("--spline", a.spline, "catmull-rom | local | not-a-knot | linear")->capture_default_str();
  app.add_option("--representation", a.representation,
                 "auto | hl+t | hl | xyz. auto: where most frames share no interior landmarks with the reference frame (none "
                 "given, none tracked), the keyframes are blended both ways at up to 12 frames between them and xyz is stored where the "
                 "fields come out more than 1.1x farther than the positions; otherwise hl+t and xyz are coded at N, then the one with "
                 "the lower bytes x held-out RMS^2 (on up to 8 frames between keyframes) also at the coarsest N whose worst region is "
                 "within 0.75% (--grid auto), and the lowest kept, a coarser N only within the error bound. A representation named "
                 "is stored without that choice: xyz is the faster encode, for larger files (README, Encoding your own capture)")
      ->capture_default_str();
  app.add_option("--density-equalising", a.density_equalising,
                 "How far the disk grid spreads over the face by area rather than conformally, 0 to 1 (0: the conformal disk)")
      ->capture_default_str();
  app.add_option("--radial-equalising", a.radial_equalising,
                 "auto, or 0 to 1: how far the disk grid spreads over the surface by area along the disk's radius (auto: fully where the "
                 "conformal disk holds half the surface within a quarter of its radius, as a whole head whose rim is the neck; else not)")
      ->capture_default_str();
  app.add_option("--keyframe-fit", a.keyframe_fit,
                 "on | off: keyframes store the spline's least-squares fit to every frame (on: a capture's per-frame noise is averaged "
                 "out) or their own frames")
      ->capture_default_str();
  app.add_option("--reference", a.reference, "The frame every other is registered to")->capture_default_str();
  app.add_option("--field-error", a.field_error,
                 "RMS displacement of a decoded keyframe its fields' rounding may cause (of the bbox diagonal); auto: two fifths of the "
                 "predicted error between keyframes (of the error bound where none is predicted: one frame, every frame a keyframe; "
                 "0.5% by default, or --max-error), within [0.005%, 0.2%]; re-coding a .fmv, auto keeps its steps; 0: 16-bit precision, no search")
      ->capture_default_str();
  app.add_option("--field-rounding", a.field_rounding,
                 "shaped (the default: error diffusion on the fields the decoder integrates, hl and hl+t's; positions, xyz, each to "
                 "its nearest step, as diffusion only adds to their error) | nearest (every value to its nearest step)")
      ->capture_default_str();
  app.add_option("--inter-dead-zone", a.inter_dead_zone,
                 "Steps a value of a predicted keyframe must move before its code leaves the previous keyframe's (0.5: plain rounding; "
                 "below 1), or auto (the one of " +
                     dead_zone_candidates() + " that makes the smallest file)")
      ->capture_default_str();
  app.add_option("--intra-period", a.intra_period,
                 "Every P-th keyframe coded without the previous one (random access), or auto (one at least every 10 s of capture)")
      ->capture_default_str();
  app.add_flag("--no-texture", a.no_texture, "Geometry only");
  app.add_flag("--track-landmarks", a.track_landmarks,
               "Frames without interior landmarks (--landmarks auto, or none given) also take points of the reference tracked onto them "
               "by optical flow: lower error, larger files, slower (spec/method.md 7.14)");
  app.add_flag("--largest-component", a.largest_component, "Keep each frame's largest surface, drop others (eyeballs, teeth) and say so");
  app.add_flag("--keep-holes-filled", a.keep_holes_filled, "Store no holes: eyes and mouth decode as the fill");
  app.add_option("--threads", a.threads, "Worker threads (0: one per core)")->capture_default_str();
  app.add_flag("--strict", a.strict,
               "End the encode at the first frame that cannot be read or mapped, or a landmark off its frame's surface (default: drop "
               "the frame or ignore the landmark, and say so)");
  app.add_flag("-q,--quiet", a.quiet, "No progress display or summary");
}

// The encoder's options from the command line; kInvalidArgument naming the option for a value
// that does not parse. `keyframes_given`: --keyframes was on the command line.
EncodeOptions encode_options(const Arguments& a, bool keyframes_given) {
  EncodeOptions options;
  if (!a.max_error.empty()) {
    options.max_error = tools::parse_fraction(a.max_error, "--max-error");
  } else {
    options.keyframe_fraction = tools::parse_fraction(a.keyframes, "--keyframes");
    // A budget given is a budget kept; the default one grows where a.frames are far apart or fast.
    if (keyframes_given) options.keyframe_error_bound = options.sparse_frame_interval = 0;
  }
  options.keyframe_p99_bound =
      a.worst_region == "0" || a.worst_region == "0%" ? 0.0 : tools::parse_fraction(a.worst_region, "--worst-region");
  if (a.grid != "auto") options.grid = tools::parse_whole_number(a.grid, "--grid", kMinGridSize, kMaxGridSize);
  options.texture_quality =
      a.quality_text == "auto" ? kAutoTextureQuality : tools::parse_whole_number(a.quality_text, "--quality", 0, kMaxTextureQuality);
  options.texture_codec = parse_texture_codec(a.texture_codec);
  options.texture = !a.no_texture;
  options.share_textures = !a.no_texture_sharing;
  options.track_landmarks = a.track_landmarks;
  if (a.texture_size != "auto") options.texture_size = tools::parse_whole_number(a.texture_size, "--texture", kMinTextureSize, kMaxTextureSize);
  options.registration.method = parse_registration_method(a.registration);
  options.spline = parse_spline_kind(a.spline);
  if (a.representation != "auto") options.representation = parse_representation(a.representation);
  options.keep_holes_filled = a.keep_holes_filled;
  options.largest_component = a.largest_component;
  options.threads = a.threads;
  options.strict = a.strict;
  options.reference_frame = a.reference;
  options.density_equalising.strength = a.density_equalising;
  options.density_equalising.radial = parse_radial(a.radial_equalising);
  if (a.keyframe_fit != "on" && a.keyframe_fit != "off")
    throw Error(ErrorCode::kInvalidArgument, "--keyframe-fit '" + a.keyframe_fit + "' is neither on nor off");
  options.keyframe_fit = a.keyframe_fit == "on";
  options.residual_frames = a.residual_frames;
  options.patch_bound = a.patch_bound == "0" || a.patch_bound == "0%" ? 0.0 : tools::parse_fraction(a.patch_bound, "--patch-bound");
  options.predicted_fields = a.field_error != "0";
  options.auto_field_error = a.field_error == "auto";
  if (options.predicted_fields && !options.auto_field_error)
    options.field_precision.target_error = tools::parse_fraction(a.field_error, "--field-error");
  options.field_precision.intra_period = a.intra_period == "auto" ? kAutoIntraPeriod : tools::parse_whole_number(a.intra_period, "--intra-period", 1, file_layout::kMaxIntraPeriod);
  if (a.field_rounding != "shaped" && a.field_rounding != "nearest") {
    throw Error(ErrorCode::kInvalidArgument, "--field-rounding '" + a.field_rounding + "' is neither shaped nor nearest");
  }
  options.field_precision.noise_shaping = a.field_rounding == "shaped";
  options.field_precision.inter_dead_zone = a.inter_dead_zone == "auto" ? kAutoDeadZone : parse_dead_zone(a.inter_dead_zone);
  return options;
}

// The stage and the options that only some stages take, checked against each other.
void check_stage(const Arguments& a) {
  if (a.stage != "all" && a.stage != "sample" && a.stage != "assemble" && a.stage != "measure" && a.stage != "check" &&
      a.stage != "ranges") {
    throw Error(ErrorCode::kInvalidArgument, "--stage '" + a.stage + "' is none of all, sample, assemble, measure, check, ranges");
  }
  if (!a.segment.empty() && a.stage != "assemble" && a.stage != "measure")
    throw Error(ErrorCode::kInvalidArgument, "--segment is for --stage measure and assemble");
  if (a.stage == "measure" && a.segment.empty()) throw Error(ErrorCode::kInvalidArgument, "--stage measure needs --segment S/N");
  if (!a.segment.empty() && a.stage == "assemble" && a.measures.empty()) {
    throw Error(ErrorCode::kInvalidArgument, "--stage assemble --segment needs --measures: every segment's measure file (--stage measure)");
  }
  if (!a.measures.empty() && (a.stage != "assemble" || a.segment.empty()))
    throw Error(ErrorCode::kInvalidArgument, "--measures is for --stage assemble --segment");
}

// The capture as the encode reads it (--landmarks auto: without the capture's landmarks).
Capture open_for_encode(const Arguments& a, const std::string& path) {
  Capture capture = open_capture(path, a.fps, a.landmarks == "auto" ? "" : a.landmarks);
  if (a.landmarks == "auto") {
    capture.landmark_names.clear();
    capture.landmarks.assign(capture.frames.size(), {});
  }
  return capture;
}

// --stage check: the parts, and with --capture the capture they must come from.
int run_check(const Arguments& a, const EncodeOptions& options) {
  std::optional<Capture> capture;
  if (!a.check_capture.empty()) capture = open_for_encode(a, a.check_capture);
  check_parts(a.inputs, a.frames, capture ? &*capture : nullptr, options, a.quiet);
  return 0;
}

// --stage ranges: what a cluster encode splits the capture into (tools/slurm/fmenc-slurm): the
// capture read as the encode reads it.
int run_ranges(const Arguments& a) {
  if (a.inputs.size() != 1) throw Error(ErrorCode::kInvalidArgument, "--stage ranges reads one capture");
  const Capture capture = open_capture(a.inputs.front(), a.fps, a.landmarks == "auto" ? "" : a.landmarks);
  for (const FrameRange& r : part_ranges(static_cast<int>(capture.frames.size()), a.frames_per_part))
    std::printf("%d:%d\n", r.first, r.end);
  return 0;
}

// One progress line per step of the encode, each finished when the next begins.
class StageProgress {
 public:
  explicit StageProgress(bool quiet) : quiet_(quiet) {}
  void update(const std::string& step, int done, int total) {
    if (step != current_ && stages_.count(current_)) stages_[current_]->finish();
    current_ = step;
    auto& bar = stages_[step];
    if (!bar) bar = std::make_unique<tools::Progress>("fmenc " + step, quiet_);
    bar->update(done, total);
  }
  void finish() {
    if (stages_.count(current_)) stages_[current_]->finish();
  }

 private:
  bool quiet_;
  std::map<std::string, std::unique_ptr<tools::Progress>> stages_;
  std::string current_;
};

// --stage measure: what segment --segment S/N settles with the others, into a measure file.
int run_measure(const Arguments& a, const EncodeOptions& options, StageProgress& progress, std::chrono::steady_clock::time_point start) {
  EncodeReport report;
  const std::vector<std::filesystem::path> parts(a.inputs.begin(), a.inputs.end());
  const SegmentMeasure measure = measure_segment(parts, options, parse_segment(a.segment), &report);
  write_segment_measure(a.output, measure);
  progress.finish();
  if (!a.quiet && measure.first == measure.end) {
    std::printf("fmenc: %s: segment %s is empty: the capture's %d keyframes make fewer groups of %d\n", a.output.c_str(), a.segment.c_str(),
                measure.keyframes, measure.intra_period);
  } else if (!a.quiet) {
    std::printf(
        "fmenc: %s: segment %s, keyframes %d:%d of %d (intra period %d), %zu folds, worst keyframe %.3g%% at its own steps, %.1f s\n",
        a.output.c_str(), a.segment.c_str(), measure.first, measure.end, measure.keyframes, measure.intra_period, measure.folds.size(),
        100 * *std::max_element(measure.keyframe_errors.begin(), measure.keyframe_errors.end()), tools::seconds_since(start));
  }
  if (!a.quiet && !measure.representation_fallback.empty()) {
    std::printf("fmenc: %s: segment %s measured as positions (xyz), which every segment will store: %s\n", a.output.c_str(),
                a.segment.c_str(), measure.representation_fallback.c_str());
  }
  if (!a.quiet) print_segment_seconds(report, true);
  return 0;
}

// What was encoded, and what the summary needs of the capture (the encoder takes the capture
// itself). The keyframes stay in the encoder's temporary file until the writer reads them, one at
// a time.
struct Encoded {
  EncodeReport report;
  std::vector<std::string> landmark_names;
  double duration = 0;
  size_t frame_count = 0;
  std::unique_ptr<StoredSequence> sequence;
  std::optional<SegmentPlacement> placement;
};

// --stage assemble: the parts into the whole file, or with --segment into segment S's file. No
// sequence: the segment is empty (said unless quiet), nothing to write.
Encoded run_assemble(const Arguments& a, const EncodeOptions& options) {
  Encoded e;
  const std::vector<std::filesystem::path> parts(a.inputs.begin(), a.inputs.end());
  PartHeader header;
  if (!a.segment.empty()) {
    std::vector<SegmentMeasure> read;
    for (const std::string& m : a.measures) read.push_back(read_segment_measure(m));
    e.placement.emplace();
    e.sequence = assemble_segment(parts, options, parse_segment(a.segment), read, &*e.placement, &e.report, &header);
    if (!e.sequence) {
      if (!a.quiet)
        std::printf("fmenc: segment %s is empty (the capture has fewer groups of keyframes): no file written\n", a.segment.c_str());
      return e;
    }
    if (!a.quiet) print_segment_seconds(e.report, false);
  } else {
    e.sequence = assemble_parts(parts, options, &e.report, &header);
  }
  e.landmark_names = header.capture.given_landmark_names;
  e.duration = header.capture.last_time - header.capture.first_time + 1.0 / header.capture.fps;
  e.frame_count = static_cast<size_t>(header.capture.frame_count);
  return e;
}

// --stage all: the capture encoded in one process.
Encoded run_encode(Capture capture, const EncodeOptions& options) {
  Encoded e;
  e.landmark_names = capture.landmark_names;
  e.duration = capture.duration() + 1.0 / capture.fps;
  e.frame_count = capture.frames.size();
  e.sequence = encode_capture_stored(std::move(capture), options, &e.report);
  return e;
}

// --stage sample: frames --frames A:B of the capture mapped, registered and sampled into a part file.
int run_sample(const Arguments& a, Capture& capture, const EncodeOptions& options, StageProgress& progress,
               std::chrono::steady_clock::time_point start) {
  const FrameRange range = parse_frames(a.frames, static_cast<int>(capture.frames.size()));
  const PartHeader header = encode_part(capture, options, range, a.output);
  progress.finish();
  if (!a.quiet) {
    std::printf("fmenc: %s: frames %d:%d of %zu sampled (reference frame %d), %llu bytes, %.1f s\n", a.output.c_str(), range.first,
                range.end, capture.frames.size(), header.capture.reference,
                static_cast<unsigned long long>(std::filesystem::file_size(a.output)), tools::seconds_since(start));
  }
  return 0;
}

// Writes the file (or the segment's file); returns the seconds it took.
double write_output(const Arguments& a, const EncodeOptions& options, const Encoded& e, SequenceFileMetadata& metadata) {
  metadata.settings = encode_settings_json(options, e.report);
  metadata.landmark_names = e.landmark_names;
  metadata.keyframe_texture_qualities = e.report.texture_qualities;
  metadata.texture_codec = options.texture_codec;
  metadata.texture_coding = parse_texture_coding(a.texture_coding);
  metadata.field_coding = e.report.field_coding;
  const auto write_start = std::chrono::steady_clock::now();
  if (e.placement) {
    write_segment_file(a.output, *e.sequence, metadata, *e.placement);
  } else {
    write_sequence_file(a.output, *e.sequence, metadata, &e.sequence->coded_texture_groups());
  }
  return tools::seconds_since(write_start);
}

// What the summary after an encode reads.
struct Summary {
  const EncodeOptions& options;
  const EncodeReport& report;
  const StoredSequence* sequence;
  const SequenceFileMetadata& metadata;
  std::string output;
  size_t frame_count;
  double duration, seconds, seconds_writing;
  uintmax_t bytes;
};

// The file, its keyframes, grid and representation, and why the keyframes are as many as they are.
void print_keyframes(const Summary& s) {
  std::printf("fmenc: %s: %zu frames, %zu keyframes at", s.output.c_str(), s.frame_count - s.report.dropped.size(),
              s.sequence->shape().keyframes.size());
  for (const Keyframe& key : s.sequence->shape().keyframes) std::printf(" %.3f", key.time);
  std::printf(" s\n");
  if (s.options.residual_frames && s.report.residual_fit.keyframes_saved == 0) {
    std::printf("  residual frames: none (the selection took no fewer keyframes for them: bytes they would add; spec/method.md §7.18)\n");
  } else if (s.options.residual_frames) {
    const ResidualFitReport& r = s.report.residual_fit;
    std::printf(
        "  residual frames: %zu for %d keyframes fewer (fitted to the stored keyframes on %d frames between them: %d decode %.0f%% better "
        "or more, %d no "
        "better; "
        "their decoded error mean %.4f%% -> %.4f%%, worst %.4f%% -> %.4f%% of the diagonal; %.1f s)\n",
        s.sequence->shape().residuals.size(), r.keyframes_saved, r.frames_fitted, r.frames_improved, 100 * kDecodedResidualMinGain,
        r.frames_worse, 100 * r.mean_before, 100 * r.mean_after, 100 * r.worst_before, 100 * r.worst_after, r.seconds);
  }
  if (s.options.patch_bound > 0) {
    const PatchFitReport& r = s.report.patch_fit;
    std::printf(
        "  frame patches: %d frames decoded over %.2f%% (p99 of the diagonal), %d patched (%zu lattice nodes), %d pinned beside them, %d "
        "not brought under; worst p99 between keyframes %.3f%% -> %.3f%%; %.1f s (%d of %d approximate p99s under the bound "
        "were over it exactly)\n",
        r.frames_over, 100 * s.options.patch_bound, r.frames_patched, r.nodes, r.frames_pinned, r.frames_unmet, 100 * r.worst_before,
        100 * r.worst_after, r.seconds, r.approximate_misses, r.exact_checks);
  }
  std::printf("  grid N = %d, %s, %s registration, %s spline%s%s\n", s.sequence->shape().grid_n,
              representation_name(s.sequence->shape().representation), registration_method_name(s.options.registration.method),
              spline_kind_name(s.sequence->shape().spline),
              s.sequence->outline().has_texture()
                  ? (", " + std::to_string(s.report.texture_size) + "x" + std::to_string(s.report.texture_size) + " texture").c_str()
                  : ", no texture",
              s.sequence->outline().has_holes ? ", holes cut on decode" : "");
  if (s.report.blend.trials > 0) {
    std::printf(
        "  representation %s (auto): %d of %zu frames share no interior landmarks with the reference; blended at %d frames "
        "between keyframes, the fields come out %.3f%% from them, the positions %.3f%%%s\n",
        representation_name(s.report.representation), s.report.frames_without_interior_landmarks,
        s.frame_count - s.report.dropped.size() - 1, s.report.blend.trials, 100 * s.report.blend.fields_error,
        100 * s.report.blend.positions_error,
        s.report.representation == Representation::kXYZ ? " (--representation hl+t stores the fields)" : "");
  }
  if (s.report.representation_rate.measured) {
    const RepresentationRate& r = s.report.representation_rate;
    std::printf(
        "  representation and N by bytes at equal error (keyframes' bytes; %s RMS / worst 99th percentile of the diagonal on %d %s; "
        "bytes x max(RMS, %.2g%%)^%g the lowest%s, a coarser N within %.2g%%, the worst 99th percentile within %.2g%% or %gx the first's):",
        r.on_keyframes ? "decoded keyframes'" : "held-out", r.candidates.front().frames,
        r.on_keyframes ? "keyframes (no frame between them)" : "frames", 100 * kUnboughtErrorShare * r.tolerance, kRateErrorExponent,
        r.on_keyframes ? ", none with more bytes than the first (all built to the same targets)" : "", 100 * r.tolerance,
        100 * r.worst_bound, r.worst_bound > 0 ? kWorstRegionRise : 1.0);
    for (size_t i = 0; i < r.candidates.size(); ++i) {
      const RateCandidate& c = r.candidates[i];
      char step[32] = "";
      if (c.step_scale != 1) std::snprintf(step, sizeof step, " field step x%g", c.step_scale);
      const char* mark = i == r.chosen                                                         ? " (kept)"
                         : !admitted_worst_region(c, r.candidates.front(), r.worst_bound) ? " (worst region refused)"
                                                                                              : "";
      std::printf("%s %s%s N = %d%s %llu B at %.4f / %.4f%%%s", i ? ";" : "", representation_name(c.representation),
                  c.density_equalising > 0 ? " on the density-equalised disk" : "", c.grid, step,
                  static_cast<unsigned long long>(c.bytes), 100 * c.held_rms, 100 * c.worst_p99, mark);
    }
    std::printf("; %.1f s\n", r.seconds);
    const EncodeReport::DensityCandidate& d = s.report.density_candidate;
    if (d.strength > 0) {
      std::printf("  density-equalised disk (strength %g) %s; its resampled floor's 99th percentile", d.strength,
                  d.kept ? "kept: every frame sampled through it" : "not kept");
      for (const auto& [n, p99] : d.floor_p99s) std::printf(" %d: %.3f%%", n, 100 * p99);
      // Where D won on geometry and the capture is textured, what decided: each disk's file.
      if (d.textures_coded) {
        std::printf("; the file with texture: D %llu + %llu B against the conformal disk's %llu + %llu B (geometry + texture)",
                    static_cast<unsigned long long>(d.equalised_geometry_bytes), static_cast<unsigned long long>(d.equalised_texture_bytes),
                    static_cast<unsigned long long>(d.conformal_geometry_bytes), static_cast<unsigned long long>(d.conformal_texture_bytes));
      }
      std::printf("\n");
    }
  }
  if (!s.report.sparse && s.report.keyframe_budget > 0 &&
      static_cast<int>(s.sequence->shape().keyframes.size()) > s.report.keyframe_budget) {
    std::printf(
        "  keyframes: the %g%% budget (%d) left %.3f%% mean / %.3f%% worst / %.3f%% worst 99th percentile predicted between keyframes, "
        "above the %.2g%% / %.2g%% / %.2g%% bound for frames far apart or fast: %zu keyframes (--keyframes P keeps a budget exactly)\n",
        100 * s.options.keyframe_fraction, s.report.keyframe_budget, 100 * s.report.budget_mean_error, 100 * s.report.budget_worst_error,
        100 * s.report.budget_worst_p99, 100 * s.options.keyframe_error_bound, 300 * s.options.keyframe_error_bound,
        100 * s.options.keyframe_p99_bound, s.sequence->shape().keyframes.size());
  }
  if (s.report.sparse) {
    std::printf(
        "  keyframes: every frame, as the frames lie %.3f s apart (median), sparser than one every %.2f s: the spline has nothing "
        "between "
        "them to be checked against, so each is stored, not predicted (--keyframes P keeps a budget exactly)\n",
        s.report.median_frame_interval, s.options.sparse_frame_interval);
  }
}

// --grid auto: the floors it compared and the term that chose N.
void print_grid_choice(const Summary& s) {
  if (!s.report.grid_floors.empty()) {
    std::printf("  --grid auto: resampling floor (RMS of the diagonal)");
    for (const auto& [n, floor] : s.report.grid_floors) std::printf(" %d: %.3f%%", n, 100 * floor);
    std::printf("; 99th percentile");
    for (const auto& [n, p99] : s.report.grid_floor_p99s) std::printf(" %d: %.3f%%", n, 100 * p99);
    if (!s.report.grid_decoded_floors.empty()) {
      std::printf("; decoded from the fields (RMS / 99th percentile)");
      for (const auto& d : s.report.grid_decoded_floors) {
        if (d.reconstructed) {
          std::printf(" %d: %.3f / %.3f%%", d.n, 100 * d.rms, 100 * d.p99);
        } else if (std::isfinite(d.p99)) {
          std::printf(" %d: not reconstructed (as positions %.3f / %.3f%%)", d.n, 100 * d.rms, 100 * d.p99);
        } else {
          std::printf(" %d: not reconstructed", d.n);
        }
      }
    }
    std::printf(
        "; the capture's median frame noise %.3f%%; density cap N = %d (a vertex of the denser quarter holds %.3g of the disk: %.2f "
        "nodes at N = %d)\n",
        100 * s.report.median_noise, s.report.grid_density_cap, s.report.grid_vertex_area,
        s.report.grid_vertex_area * (s.sequence->shape().grid_n - 1) * (s.sequence->shape().grid_n - 1) / 4.0, s.sequence->shape().grid_n);
    const char* why = s.report.grid_term == "interpolation" ? "half the mean error predicted between keyframes"
                      : s.report.grid_term == "error bound" ? "half the error bound, as nothing between keyframes is predicted"
                      : s.report.grid_term == "noise"       ? "the median frame noise"
                                                            : "the fixed floor";
    // The N these terms chose: where the choice by bytes at equal error kept a coarser one, the
    // first candidate's (the file's N is then not "the smallest within" the target, and says so).
    const RepresentationRate& rate = s.report.representation_rate;
    const int planned = rate.measured ? rate.candidates.front().grid : s.sequence->shape().grid_n;
    if (s.report.grid_term == "density") {
      std::printf(
          "  --grid auto: N = %d, as fine as the captured mesh's density asks (at most 3 nodes in the area of a vertex of its denser "
          "quarter)\n",
          planned);
    } else if (s.report.grid_term == "worst region") {
      std::printf("  --grid auto: N = %d, the smallest whose 99th percentile is within %.3f%% (the worst region)\n", planned,
                  100 * s.report.grid_worst_target);
    } else {
      std::printf("  --grid auto: N = %d, the smallest within %.3f%% (%s)\n", planned, 100 * s.report.grid_target, why);
    }
    if (planned != s.sequence->shape().grid_n) {
      std::printf("  --grid auto: N = %d stored, coarser: its resampled 99th percentile within %.3f%%, kept by bytes at equal error\n",
                  s.sequence->shape().grid_n, 100 * s.report.grid_worst_target);
    }
  }
}

// A whole head (spec/method.md §7.11): the reparametrisation and what it cost.
void print_radial_equalising(const Summary& s) {
  if (s.report.radial_equalising > 0) {
    // A whole head (spec/method.md §7.11): the reparametrisation, the representation it forces and
    // what a keyframe then differs from its frame by (G's resampling floor, then the rounding).
    double floor = -1;
    for (const auto& [n, f] : s.report.grid_floors) {
      if (n == s.sequence->shape().grid_n) floor = f;
    }
    const std::vector<double>& rounding = s.report.field_precision.keyframe_errors;
    const double rounded = rounding.empty() ? 0 : *std::max_element(rounding.begin(), rounding.end());
    // "whole head" only where the rule found one; a strength asked for on a face says so.
    const bool crowded = s.report.density_equalising.half_area_radius_before < kCrowdedHalfAreaRadius;
    std::printf(
        "  %s: the conformal disk held half the surface within %.3f of its centre (%s); spread "
        "radially (strength %.2g) to %.3f; keyframes stored as positions (%s)",
        crowded ? "whole head" : "radial equalising", s.report.density_equalising.half_area_radius_before,
        crowded ? "the neck rim crowds the face" : "not crowded: asked for", s.report.radial_equalising,
        s.report.density_equalising.half_area_radius_after,
        s.sequence->shape().representation == Representation::kXYZ ? "hl+t does not converge on the spread disk"
                                                                   : "as asked: hl+t may not converge");
    if (floor >= 0) {
      std::printf("; keyframe error %.3f%% RMS of the diagonal (resampling at N = %d %.3f%%, rounding %.3f%% worst)",
                  100 * std::hypot(floor, rounded), s.sequence->shape().grid_n, 100 * floor, 100 * rounded);
    }
    std::printf("\n");
  }
}

// Bytes, the predicted error and the fields' rounding.
void print_rate_and_fields(const Summary& s) {
  std::printf("  %llu bytes: %.0f bytes per second of capture (%.1f kbit/s)\n", static_cast<unsigned long long>(s.bytes),
              static_cast<double>(s.bytes) / s.duration, static_cast<double>(s.bytes) * 8 / s.duration / 1000);
  double worst = 0, worst_p99 = 0;
  for (const EncodedFrameReport& f : s.report.frames) {
    worst = std::max(worst, f.predicted_error);
    worst_p99 = std::max(worst_p99, f.predicted_p99);
  }
  std::printf("  predicted worst error between keyframes: %.3f%% of the bbox diagonal (RMS), %.3f%% (99th percentile)\n", 100 * worst,
              100 * worst_p99);
  if (s.report.field_coding.predicted()) {
    const std::vector<double>& e = s.report.field_precision.keyframe_errors;
    std::printf(
        "  fields rounded to %.3g%% of the diagonal%s (RMS; worst keyframe %.3g%%), intra every %d keyframes, dead zone %.2f steps\n",
        100 * s.report.field_precision.target_error,
        !s.options.auto_field_error ? ""
        : worst == 0 ? " (auto: two fifths of the error bound, as nothing between keyframes is predicted)"
                                                : " (auto)",
        100 * *std::max_element(e.begin(), e.end()), s.report.field_coding.intra_period, s.report.field_precision.inter_dead_zone);
    const FieldPrecisionReport& p = s.report.field_precision;
    if (p.rounding_p99_budget > 0 && !p.keyframe_p99s.empty()) {
      std::printf("  worst region: the rounding's 99th percentile within %.3f%% (%.3g%% less the floor), worst "
                  "keyframe %s%.3f%%; %s\n",
                  100 * p.rounding_p99_budget, 100 * p.worst_target, p.worst_region_refusals > 0 ? "" : "at most ",
                  100 * *std::max_element(p.keyframe_p99s.begin(), p.keyframe_p99s.end()),
                  p.worst_region_refusals > 0 ? ("it refused " + std::to_string(p.worst_region_refusals) + " coarser steps").c_str()
                                              : "it did not bind");
      // Keyframes whose own floor is larger than the reference's: held to what it leaves of the 1%,
      // or, at or over it, not bounded (no rounding can help).
      const std::vector<int>& frames = s.report.keyframes;
      for (size_t k = 0; k < p.keyframe_budgets.size() && k < p.keyframe_floors.size(); ++k) {
        if (p.keyframe_budgets[k] == p.rounding_p99_budget) continue;
        const int frame = k < frames.size() ? frames[k] : -1;
        if (p.keyframe_budgets[k] > 0) {
          std::printf("    keyframe %zu (frame %d): its own floor %.3f%%, its rounding within %.3f%%, at %.3f%%\n", k, frame,
                      100 * p.keyframe_floors[k], 100 * p.keyframe_budgets[k], 100 * p.keyframe_p99s[k]);
        } else {
          std::printf("    keyframe %zu (frame %d): its own floor %.3f%% is at or over the %.3g%%: no rounding can bring it under (not bounded)\n",
                      k, frame, 100 * p.keyframe_floors[k], 100 * p.worst_target);
        }
      }
    }
  }
}

// The textures: qualities, bytes and PSNR as decoded, sharing.
void print_textures(const Summary& s) {
  if (!s.report.texture_qualities.empty()) {
    const auto [lo, hi] = std::minmax_element(s.report.texture_qualities.begin(), s.report.texture_qualities.end());
    const bool lossless = *lo > 100;
    std::printf("  textures: %s", lossless ? "lossless WebP"
                                           : (std::string(s.options.texture_codec == TextureCodec::kAvif ? "AVIF" : "WebP") + " quality " +
                                              std::to_string(*lo) + " to " + std::to_string(*hi))
                                                 .c_str());
    std::vector<double> measured;
    for (double db : s.report.texture_interpolation_psnr) {
      if (db > 0) measured.push_back(db);
    }
    if (!measured.empty()) {
      const auto [low_db, high_db] = std::minmax_element(measured.begin(), measured.end());
      std::printf(" (auto: the blend between keyframes is at %.1f to %.1f dB)", *low_db, *high_db);
    }
    std::printf("\n");
    // What the file's textures decode to, against the keyframes' own (on the disk): one keyframe's
    // at a time, through a source whose cache the decoder's limits bound (the whole file decoded
    // at once held every keyframe twice over, the encode's largest allocation on a long capture).
    SequenceFileInfo written;
    const std::shared_ptr<const KeyframeSource> decoded = open_sequence_source(s.output, kDefaultDecoderLimits, &written);
    double sum_db = 0, low_db = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < s.sequence->shape().keyframes.size(); ++k) {
      const double db = psnr_of_mse(disk_texture_mse(*s.sequence->texture(k), *decoded->texture(k)));
      sum_db += db;
      low_db = std::min(low_db, db);
    }
    uint64_t texture_bytes = 0;
    for (const auto& c : written.chunks) texture_bytes += c.type == "TEXR" || c.type == "TGOP" ? c.stored_bytes : 0;
    const std::string layout = written.metadata.texture_coding == TextureCoding::kSequence ? "one AV1 sequence per group"
                               : written.distinct_textures < s.sequence->shape().keyframes.size()
                                   ? std::to_string(written.distinct_textures) + (written.distinct_textures == 1 ? " still" : " stills") +
                                         std::string(" for ") + std::to_string(s.sequence->shape().keyframes.size()) + " keyframes"
                                   : "stills";
    std::printf("  textures as decoded: %llu bytes (%s), PSNR on the disk %.2f dB mean, %.2f dB lowest\n",
                static_cast<unsigned long long>(texture_bytes), layout.c_str(),
                sum_db / static_cast<double>(s.sequence->shape().keyframes.size()), low_db);
    // Keyframes showing an earlier keyframe's texture: what that costs against their own.
    int shared = 0;
    double lowest_share_db = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < s.report.texture_shared_with.size(); ++k) {
      if (s.report.texture_shared_with[k] < 0) continue;
      ++shared;
      lowest_share_db = std::min(lowest_share_db, s.report.texture_share_psnr[k]);
    }
    if (shared > 0) {
      std::printf(
          "  textures shared: %d of %zu keyframes show an earlier keyframe's, painted from the same captured image (against their own: "
          "%.1f dB lowest)\n",
          shared, s.sequence->shape().keyframes.size(), lowest_share_db);
    }
  }
}

// Where the time and the memory went.
void print_costs(const Summary& s) {
  if (s.report.parts > 0) {
    std::printf(
        "  %d parts: mapping %.1f s, registration %.1f s, selection %.1f s in the sample stage (summed over the parts); here %.1f s, "
        "%.3f s per "
        "frame (reading the parts %.1f s, representation %.1f s, keyframes %.1f s, field precision %.1f s, texture quality %.1f s, "
        "writing %.1f s)\n",
        s.report.parts, s.report.seconds_mapping, s.report.seconds_registration, s.report.seconds_selection, s.seconds,
        s.seconds / static_cast<double>(s.frame_count), s.report.seconds_reading_parts, s.report.seconds_representation,
        s.report.seconds_keyframes, s.report.seconds_precision, s.report.seconds_texture, s.seconds_writing);
  } else {
    std::printf(
        "  %.1f s, %.2f s per frame (mapping %.1f s, registration %.1f s, selection %.1f s, grid %.1f s, representation %.1f s, keyframes "
        "%.1f s, field precision %.1f s, texture quality %.1f s, writing %.1f s)\n",
        s.seconds, s.seconds / static_cast<double>(s.frame_count), s.report.seconds_mapping, s.report.seconds_registration,
        s.report.seconds_selection, s.report.seconds_grid, s.report.seconds_representation, s.report.seconds_keyframes, s.report.seconds_precision,
        s.report.seconds_texture, s.seconds_writing);
  }
  if (s.report.spilled_bytes > 0) {
    std::printf("  frames' maps: %.0f MB in a temporary file, at most %d in memory at once\n",
                static_cast<double>(s.report.spilled_bytes) / 1e6, s.report.peak_frames_in_memory);
  }
  if (s.report.selection_spilled_bytes > 0 || s.report.keyframes_spilled_bytes > 0) {
    std::printf(
        "  the selection's samples: %.0f MB, at most %d frames' in memory; the keyframes' arrays: %.0f MB, at most %d a step in memory\n",
        static_cast<double>(s.report.selection_spilled_bytes) / 1e6, s.report.peak_selection_samples_in_memory,
        static_cast<double>(s.report.keyframes_spilled_bytes) / 1e6, s.report.peak_keyframes_in_memory);
  }
}

// Frames that fell back, were dropped or warned about, and what the landmarks took.
void print_frame_notes(const Summary& s) {
  if (s.report.registration_fallbacks > 0) {
    std::printf("  %d frames fell back in registration:\n", s.report.registration_fallbacks);
    for (const EncodedFrameReport& f : s.report.frames) {
      if (f.fallback != RegistrationFallback::kNone) std::printf("    %s: %s\n", f.name.c_str(), f.fallback_reason.c_str());
    }
  }
  for (const EncodedFrameReport& f : s.report.frames) {
    if (!f.conformal_fallback_reason.empty()) {
      std::printf("  %s: mapped by the %s map: %s\n", f.name.c_str(), conformal_method_name(f.conformal_method),
                  f.conformal_fallback_reason.c_str());
    }
  }
  if (!s.report.dropped.empty()) {
    std::printf("  %zu of %zu frames dropped (the spline covers their times; --strict ends the encode instead):\n", s.report.dropped.size(),
                s.frame_count);
    for (const DroppedFrame& d : s.report.dropped)
      std::printf("    %s (frame %d, %.3f s): %s\n", d.name.c_str(), d.index, d.time, d.reason.c_str());
  }
  for (const std::string& warning : s.report.warnings) std::printf("  warning: %s\n", warning.c_str());
  if (s.report.orientation_found > 0) {
    std::printf(
        "  landmarks: nose tip and up found from the geometry on %d frames (mirror plane within %.2f%% of the diagonal, up evidence at "
        "least %.2f of 1; %d frames took up from another frame)%s\n",
        s.report.orientation_found, 100 * s.report.worst_mirror_error, s.report.weakest_up_evidence, s.report.up_from_hint,
        s.report.rim_markers_found ? "; rim markers placed on each frame's rim" : "");
    std::printf("  face found by %s (frames: %d whole surface, %d texture, %d face region), confidence at least %.2f of 1\n",
                s.report.main_orientation_method(), s.report.orientation_methods[0], s.report.orientation_methods[1],
                s.report.orientation_methods[2], s.report.lowest_face_confidence);
  } else if (s.report.rim_markers_found) {
    std::printf("  landmarks: rim markers placed on each frame's rim (the capture has none)\n");
  }
  if (s.report.tracked_frames > 0) {
    std::printf(
        "  landmarks: %d points of the reference's disk tracked onto %d frames by optical flow (%.2f s): %.0f kept per frame on average, "
        "%d at fewest; round trip median %.2f%%, 90%% within %.2f%% of the disk's radius\n",
        s.report.tracking_grid_points, s.report.tracked_frames, s.report.seconds_tracking, s.report.tracked_points_mean,
        s.report.tracked_points_fewest, 100 * s.report.tracked_round_trip_median, 100 * s.report.tracked_round_trip_p90);
  }
}

// The repairs: the totals as the file states them, and the first frames' own.
void print_repairs(const Summary& s) {
  const nlohmann::json repairs = nlohmann::json::parse(s.metadata.settings)["repairs"];  // the totals, as the file states them
  if (repairs["frames_repaired"].get<int>() > 0) {
    std::printf(
        "  repairs: %d of %zu frames repaired, %d faces and %d vertices changed in all, the surface moved at most %.3g (%.3g%% of the "
        "diagonal)%s\n",
        repairs["frames_repaired"].get<int>(), s.report.frames.size(), repairs["faces_changed"].get<int>(),
        repairs["vertices_changed"].get<int>(), repairs["largest_move"].get<double>(),
        100 * repairs["largest_move_of_diagonal"].get<double>(),
        s.options.strict ? "" : " (--strict refuses a frame with bow ties, edges of 3+ faces or islands)");
  }
  // Each frame's own repairs, as many lines as a reader takes in; the settings hold the totals.
  constexpr int kRepairLinesShown = 8;
  std::string last;
  int shown = 0, more = 0;
  for (const EncodedFrameReport& f : s.report.frames) {
    if (f.repair == "valid as captured" || f.repair == last) continue;
    last = f.repair;
    if (shown++ < kRepairLinesShown) {
      std::printf("  %s: %s\n", f.name.c_str(), f.repair.c_str());
    } else {
      ++more;
    }
  }
  if (more > 0) std::printf("  ... and %d more frames repaired (fminfo lists the first %zu)\n", more, kRepairedFramesListed);
}

void print_summary(const Summary& s) {
  print_keyframes(s);
  print_grid_choice(s);
  print_radial_equalising(s);
  print_rate_and_fields(s);
  print_textures(s);
  print_costs(s);
  print_frame_notes(s);
  print_repairs(s);
}

}  // namespace

int main(int argc, char** argv) {
  tools::start_with_huge_pages(argv);  // before anything is allocated: the process may start again
  CLI::App app("Encode a face capture into a facemorph file (.fmv).", "fmenc");
  Arguments a;
  declare_options(app, a);
  return tools::guarded_main(app, argc, argv, [&] {
    const auto start = std::chrono::steady_clock::now();
    EncodeOptions options = encode_options(a, app.count("--keyframes") > 0);
    check_stage(a);
    if (a.stage == "check") return run_check(a, options);
    if (a.stage != "assemble" && a.stage != "measure" && a.inputs.size() != 1)
      throw Error(ErrorCode::kInvalidArgument, "one capture to encode, not " + std::to_string(a.inputs.size()));
    if (a.stage == "ranges") return run_ranges(a);
    if (a.output.empty()) throw Error(ErrorCode::kInvalidArgument, "--output is required");
    if (a.stage == "sample" && a.frames.empty()) throw Error(ErrorCode::kInvalidArgument, "--stage sample needs --frames A:B");
    if (a.stage != "sample" && a.stage != "check" && !a.frames.empty())
      throw Error(ErrorCode::kInvalidArgument, "--frames is for --stage sample");
    const std::string input = a.inputs.front();
    if (a.stage == "all" && std::filesystem::path(input).extension() == ".fmv") {
      recode(input, a.output, options, options.texture_quality, parse_texture_coding(a.texture_coding), a.quiet);
      return 0;
    }
    StageProgress progress(a.quiet);
    options.progress = [&progress](const std::string& step, int done, int total) { progress.update(step, done, total); };
    if (a.stage == "measure") return run_measure(a, options, progress, start);
    Encoded encoded;
    if (a.stage == "assemble") {
      encoded = run_assemble(a, options);
      if (!encoded.sequence) return 0;
    } else {
      Capture capture = open_for_encode(a, input);
      if (a.stage == "sample") return run_sample(a, capture, options, progress, start);
      encoded = run_encode(std::move(capture), options);
    }
    progress.finish();
    SequenceFileMetadata metadata;
    const double seconds_writing = write_output(a, options, encoded, metadata);
    if (a.quiet) return 0;
    const double seconds = tools::seconds_since(start);
    print_summary(Summary{options, encoded.report, encoded.sequence.get(), metadata, a.output, encoded.frame_count, encoded.duration,
                          seconds, seconds_writing, std::filesystem::file_size(a.output)});
    return 0;
  });
}
