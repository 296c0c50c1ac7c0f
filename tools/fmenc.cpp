// fmenc: encodes a capture into a .fmv file (spec/container.md): every frame made a disk and mapped
// conformally, registered to the reference frame, keyframes chosen by the spline's predicted error,
// each keyframe's fields, pose, holes and texture written. The file is written under a temporary
// name and renamed into place, so a failed encode leaves any earlier file untouched. Given a .fmv
// file instead of a capture, it re-codes it: the same keyframes, fields rounded to --field-error.
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
#include <limits>
#include <map>
#include <memory>
#include <optional>

namespace {

using namespace facemorph;

// "--intra-period N": a whole number of keyframes from 1 to 2^20 (the container's bound).
int parse_intra_period(const std::string& text) {
  try {
    size_t used = 0;
    const long value = std::stol(text, &used);
    if (used != text.size() || value < 1 || value > (1L << 20)) throw std::out_of_range(text);
    return static_cast<int>(value);
  } catch (const std::exception&) {
    throw Error(ErrorCode::kInvalidArgument, "--intra-period '" + text + "' is neither auto nor a whole number from 1 to 2^20");
  }
}

// Re-codes an existing file: keyframes, grid, poses and holes kept; the fields' rounding chosen
// again from --field-error (from the file's values, so never finer than what it held); textures
// re-encoded at `quality` (auto: the fallback quality, as there are no frames between keyframes to
// measure the blend against).
void recode(const std::filesystem::path& input, const std::filesystem::path& output, const EncodeOptions& options, int quality,
            TextureCoding texture_coding, bool quiet) {
  if (quality == kAutoTextureQuality) quality = options.texture_coding.fallback_quality;
  SequenceFileInfo info;
  Sequence sequence = read_sequence_file(input, &info);
  SequenceFileMetadata metadata = info.metadata;
  metadata.encoder.clear();
  metadata.texture_quality = quality;
  metadata.texture_codec = options.texture_codec;
  metadata.texture_coding = texture_coding;
  metadata.field_coding = {};
  FieldPrecisionReport precision;
  if (options.predicted_fields) metadata.field_coding = choose_field_coding(sequence, options.field_precision, &precision);
  write_sequence_file(output, sequence, metadata);
  if (quiet) return;
  std::printf("fmenc: %s re-coded to %s: %llu bytes (was %llu)\n", input.c_str(), output.c_str(),
              static_cast<unsigned long long>(std::filesystem::file_size(output)), static_cast<unsigned long long>(info.file_bytes));
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Encode a face capture into a facemorph file (.fmv).", "fmenc");
  std::vector<std::string> inputs;
  std::string output, stage = "all", frames, check_capture, keyframes = "10%", max_error, worst_region = "0", grid = "auto",
                      registration = "gmf", spline = "catmull-rom", representation = "auto", landmarks;
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
       quiet = false, strict = false;
  app.add_option("capture", inputs,
                 "Capture folder (capture.json), a plain folder of OBJ/PLY frames (with --fps, --landmarks), or a .fmv file to re-code; "
                 "with --stage assemble or check, the part files")
      ->required();
  app.add_option("-o,--output", output, "The .fmv file to write (with --stage sample, the part file)");
  app.add_option(
         "--stage", stage,
         "all | sample | assemble | measure | check | ranges. sample: map, register and sample --frames A:B into a part file (.fms); "
         "assemble: the "
         "parts covering the capture into the .fmv, given the options the parts were sampled with (with --segment S/N and --measures, "
         "segment S's file); measure: what segment --segment S/N settles with the others (a measure file); check: read and check part "
         "files (spec/part-file.md)")
      ->capture_default_str();
  app.add_option(
      "--segment", segment,
      "S/N: with --stage measure, measure segment S of N (0-based) of the keyframes' groups; with --stage assemble and --measures, "
      "code segment S into a segment file that fmcat joins with the others (spec/method.md 7.17)");
  app.add_option("--measures", measures, "With --stage assemble --segment: every segment's measure file (comma-separated)")->delimiter(',');
  app.add_option("--frames", frames,
                 "With --stage sample: frames A to B-1 of the capture (A:B, 0-based; B may be past the end); with --stage check: the "
                 "frames the part must hold");
  app.add_option("--capture", check_capture, "With --stage check: the capture the parts must come from, sampled with these options");
  app.add_option("--frames-per-part", frames_per_part,
                 "With --stage ranges: print the ranges A:B of this many frames the capture splits into")
      ->capture_default_str();
  app.add_option("--fps", fps, "Frame rate of a plain folder of meshes");
  app.add_option("--landmarks", landmarks,
                 "Landmarks CSV of a plain folder (frame,name,x,y,z), or auto: ignore the capture's landmarks and find the nose tip, "
                 "the face's up direction and rim markers from the geometry (frames without landmarks get them found anyway)");
  app.add_option("--keyframes", keyframes, "Keyframe budget, a fraction of the frames (10% or 0.1)")->capture_default_str();
  app.add_option("--max-error", max_error,
                 "Instead of a budget: as many keyframes as keep the predicted error below this (of the bbox diagonal, e.g. 0.5%)");
  app.add_option("--worst-region", worst_region,
                 "With the default budget: more keyframes until every frame's predicted 99th-percentile point error between keyframes "
                 "is within this (of the bbox diagonal, e.g. 0.75%; 0: no such bound, the default)")
      ->capture_default_str();
  app.add_option("--grid", grid,
                 "Grid size N of the disk grid, or auto (the smallest whose resampling floor is within the frame noise or half the error "
                 "between keyframes)")
      ->capture_default_str();
  app.add_option("--texture", texture_size, "Texels per side of the disk texture, or auto (as sharp as the capture's, at most 1024)")
      ->capture_default_str();
  app.add_option("--quality", quality_text,
                 "Texture quality (of --texture-codec, 0-100; above 100 lossless WebP), or auto: each keyframe's from the texture blend's "
                 "error beside it")
      ->capture_default_str();
  app.add_option("--texture-codec", texture_codec,
                 "avif | webp: how keyframe textures are stored (AVIF takes ~30% fewer bytes at equal PSNR)")
      ->capture_default_str();
  app.add_option("--texture-coding", texture_coding,
                 "sequence | stills: lossy AVIF textures as one AV1 image sequence per group of keyframes (format 2.1; 1.8-5x fewer bytes) "
                 "or one still each (format 2.0's); WebP and lossless textures are stills")
      ->capture_default_str();
  bool residual_frames = false;
  app.add_flag(
      "--residual-frames", residual_frames,
      "frames between keyframes carry a correction of the spline's blend, fitted to the stored keyframes and kept where the frame decodes "
      "closer with it (format 2.3's RSDW), and fast motion takes fewer keyframes; off by default (spec/method.md §7.18: on Medusa it adds "
      "bytes)");
  app.add_flag(
      "--no-texture-sharing", no_texture_sharing,
      "keep every keyframe's own texture: by default keyframes painted from one captured image show one texture, stored once (format 2.2), "
      "where it stays within the texture coding's coarsest PSNR (30 dB) of their own");
  app.add_option("--registration", registration, "moebius | gmf | frame")->capture_default_str();
  app.add_option("--spline", spline, "catmull-rom | local | not-a-knot | linear")->capture_default_str();
  app.add_option("--representation", representation,
                 "auto | hl+t | hl | xyz. auto: hl+t; where most frames share no interior landmarks with the reference frame (none "
                 "given, none tracked), the keyframes are blended both ways at up to 12 frames between them and xyz is stored where the "
                 "fields come out more than 1.1x farther than the positions")
      ->capture_default_str();
  app.add_option("--density-equalising", density_equalising,
                 "How far the disk grid spreads over the face by area rather than conformally, 0 to 1 (0: the conformal disk)")
      ->capture_default_str();
  app.add_option("--radial-equalising", radial_equalising,
                 "auto, or 0 to 1: how far the disk grid spreads over the surface by area along the disk's radius (auto: fully where the "
                 "conformal disk holds half the surface within a quarter of its radius, as a whole head whose rim is the neck; else not)")
      ->capture_default_str();
  app.add_option("--keyframe-fit", keyframe_fit,
                 "on | off: keyframes store the spline's least-squares fit to every frame (on: a capture's per-frame noise is averaged "
                 "out) or their own frames")
      ->capture_default_str();
  app.add_option("--reference", reference, "The frame every other is registered to")->capture_default_str();
  app.add_option("--field-error", field_error,
                 "RMS displacement of a decoded keyframe its fields' rounding may cause (of the bbox diagonal); auto: two fifths of the "
                 "predicted error between keyframes, within [0.005%, 0.2%]; 0: 16-bit precision, no search")
      ->capture_default_str();
  app.add_option("--field-rounding", field_rounding, "shaped (error diffusion, the default) | nearest")->capture_default_str();
  app.add_option("--inter-dead-zone", inter_dead_zone,
                 "Steps a value of a predicted keyframe must move before its code leaves the previous keyframe's (0.5: plain rounding; "
                 "below 1), or auto (the one of " +
                     dead_zone_candidates() + " that makes the smallest file)")
      ->capture_default_str();
  app.add_option("--intra-period", intra_period,
                 "Every P-th keyframe coded without the previous one (random access), or auto (one at least every 10 s of capture)")
      ->capture_default_str();
  app.add_flag("--no-texture", no_texture, "Geometry only");
  app.add_flag("--track-landmarks", track_landmarks,
               "Frames without interior landmarks (--landmarks auto, or none given) also take points of the reference tracked onto them "
               "by optical flow: lower error, larger files, slower (spec/method.md 7.14)");
  app.add_flag("--largest-component", largest_component, "Keep each frame's largest surface, drop others (eyeballs, teeth) and say so");
  app.add_flag("--keep-holes-filled", keep_holes_filled, "Store no holes: eyes and mouth decode as the fill");
  app.add_option("--threads", threads, "Worker threads (0: one per core)")->capture_default_str();
  app.add_flag("--strict", strict,
               "End the encode at the first frame that cannot be read or mapped, or a landmark off its frame's surface (default: drop "
               "the frame or ignore the landmark, and say so)");
  app.add_flag("-q,--quiet", quiet, "No progress display or summary");
  return tools::guarded_main(app, argc, argv, [&] {
    const auto start = std::chrono::steady_clock::now();
    EncodeOptions options;
    if (!max_error.empty()) {
      options.max_error = tools::parse_fraction(max_error, "--max-error");
    } else {
      options.keyframe_fraction = tools::parse_fraction(keyframes, "--keyframes");
      // A budget given is a budget kept; the default one grows where frames are far apart or fast.
      if (app.count("--keyframes") > 0) options.keyframe_error_bound = options.sparse_frame_interval = 0;
    }
    options.keyframe_p99_bound = worst_region == "0" || worst_region == "0%" ? 0.0 : tools::parse_fraction(worst_region, "--worst-region");
    if (grid != "auto") {
      try {
        options.grid = std::stoi(grid);
      } catch (const std::exception&) {
        throw Error(ErrorCode::kInvalidArgument, "--grid '" + grid + "' is neither auto nor a number");
      }
    }
    int quality = kAutoTextureQuality;
    if (quality_text != "auto") {
      try {
        size_t used = 0;
        quality = std::stoi(quality_text, &used);
        if (used != quality_text.size()) throw std::invalid_argument(quality_text);
      } catch (const std::exception&) {
        throw Error(ErrorCode::kInvalidArgument, "--quality '" + quality_text + "' is neither auto nor a number");
      }
      if (quality < 0 || quality > 101) throw Error(ErrorCode::kInvalidArgument, "--quality " + quality_text + " outside 0..101");
    }
    options.texture_quality = quality;
    options.texture_codec = parse_texture_codec(texture_codec);
    options.texture = !no_texture;
    options.share_textures = !no_texture_sharing;
    options.track_landmarks = track_landmarks;
    if (texture_size != "auto") {
      try {
        options.texture_size = std::stoi(texture_size);
      } catch (const std::exception&) {
        throw Error(ErrorCode::kInvalidArgument, "--texture '" + texture_size + "' is neither auto nor a number");
      }
    }
    options.registration.method = parse_registration_method(registration);
    options.spline = parse_spline_kind(spline);
    if (representation != "auto") options.representation = parse_representation(representation);
    options.keep_holes_filled = keep_holes_filled;
    options.largest_component = largest_component;
    options.threads = threads;
    options.strict = strict;
    options.reference_frame = reference;
    options.density_equalising.strength = density_equalising;
    options.density_equalising.radial = parse_radial(radial_equalising);
    if (keyframe_fit != "on" && keyframe_fit != "off")
      throw Error(ErrorCode::kInvalidArgument, "--keyframe-fit '" + keyframe_fit + "' is neither on nor off");
    options.keyframe_fit = keyframe_fit == "on";
    options.residual_frames = residual_frames;
    options.predicted_fields = field_error != "0";
    options.auto_field_error = field_error == "auto";
    if (options.predicted_fields && !options.auto_field_error)
      options.field_precision.target_error = tools::parse_fraction(field_error, "--field-error");
    options.field_precision.intra_period = intra_period == "auto" ? kAutoIntraPeriod : parse_intra_period(intra_period);
    if (field_rounding != "shaped" && field_rounding != "nearest") {
      throw Error(ErrorCode::kInvalidArgument, "--field-rounding '" + field_rounding + "' is neither shaped nor nearest");
    }
    options.field_precision.noise_shaping = field_rounding == "shaped";
    options.field_precision.inter_dead_zone = inter_dead_zone == "auto" ? kAutoDeadZone : parse_dead_zone(inter_dead_zone);
    if (stage != "all" && stage != "sample" && stage != "assemble" && stage != "measure" && stage != "check" && stage != "ranges") {
      throw Error(ErrorCode::kInvalidArgument, "--stage '" + stage + "' is none of all, sample, assemble, measure, check, ranges");
    }
    if (!segment.empty() && stage != "assemble" && stage != "measure")
      throw Error(ErrorCode::kInvalidArgument, "--segment is for --stage measure and assemble");
    if (stage == "measure" && segment.empty()) throw Error(ErrorCode::kInvalidArgument, "--stage measure needs --segment S/N");
    if (!segment.empty() && stage == "assemble" && measures.empty()) {
      throw Error(ErrorCode::kInvalidArgument,
                  "--stage assemble --segment needs --measures: every segment's measure file (--stage measure)");
    }
    if (!measures.empty() && (stage != "assemble" || segment.empty()))
      throw Error(ErrorCode::kInvalidArgument, "--measures is for --stage assemble --segment");
    // The capture as the encode reads it (--landmarks auto: without the capture's landmarks).
    const auto open_for_encode = [&](const std::string& path) {
      Capture capture = open_capture(path, fps, landmarks == "auto" ? "" : landmarks);
      if (landmarks == "auto") {
        capture.landmark_names.clear();
        capture.landmarks.assign(capture.frames.size(), {});
      }
      return capture;
    };
    if (stage == "check") {
      std::optional<Capture> capture;
      if (!check_capture.empty()) capture = open_for_encode(check_capture);
      check_parts(inputs, frames, capture ? &*capture : nullptr, options, quiet);
      return 0;
    }
    if (stage != "assemble" && stage != "measure" && inputs.size() != 1)
      throw Error(ErrorCode::kInvalidArgument, "one capture to encode, not " + std::to_string(inputs.size()));
    if (stage == "ranges") {
      // What a cluster encode splits the capture into (tools/slurm/fmenc-slurm): the capture read as
      // the encode reads it.
      if (inputs.size() != 1) throw Error(ErrorCode::kInvalidArgument, "--stage ranges reads one capture");
      const Capture capture = open_capture(inputs.front(), fps, landmarks == "auto" ? "" : landmarks);
      for (const FrameRange& r : part_ranges(static_cast<int>(capture.frames.size()), frames_per_part))
        std::printf("%d:%d\n", r.first, r.end);
      return 0;
    }
    if (output.empty()) throw Error(ErrorCode::kInvalidArgument, "--output is required");
    if (stage == "sample" && frames.empty()) throw Error(ErrorCode::kInvalidArgument, "--stage sample needs --frames A:B");
    if (stage != "sample" && stage != "check" && !frames.empty())
      throw Error(ErrorCode::kInvalidArgument, "--frames is for --stage sample");
    const std::string input = inputs.front();
    if (stage == "all" && std::filesystem::path(input).extension() == ".fmv") {
      recode(input, output, options, quality, parse_texture_coding(texture_coding), quiet);
      return 0;
    }
    std::map<std::string, std::unique_ptr<tools::Progress>> stages;
    std::string current;
    options.progress = [&](const std::string& step, int done, int total) {
      if (step != current && stages.count(current)) stages[current]->finish();
      current = step;
      auto& bar = stages[step];
      if (!bar) bar = std::make_unique<tools::Progress>("fmenc " + step, quiet);
      bar->update(done, total);
    };
    EncodeReport report;
    // The keyframes stay in the encoder's temporary file until the writer reads them, one at a time.
    // What the summary needs of the capture, kept: the encoder takes the capture itself.
    std::vector<std::string> landmark_names;
    double duration = 0;
    size_t frame_count = 0;
    std::unique_ptr<StoredSequence> sequence;
    std::optional<SegmentPlacement> placement;
    const std::vector<std::filesystem::path> parts(inputs.begin(), inputs.end());
    if (stage == "measure") {
      const SegmentMeasure measure = measure_segment(parts, options, parse_segment(segment), &report);
      write_segment_measure(output, measure);
      if (stages.count(current)) stages[current]->finish();
      if (!quiet && measure.first == measure.end) {
        std::printf("fmenc: %s: segment %s is empty: the capture's %d keyframes make fewer groups of %d\n", output.c_str(), segment.c_str(),
                    measure.keyframes, measure.intra_period);
      } else if (!quiet) {
        std::printf(
            "fmenc: %s: segment %s, keyframes %d:%d of %d (intra period %d), %zu folds, worst keyframe %.3g%% at its own steps, %.1f s\n",
            output.c_str(), segment.c_str(), measure.first, measure.end, measure.keyframes, measure.intra_period, measure.folds.size(),
            100 * *std::max_element(measure.keyframe_errors.begin(), measure.keyframe_errors.end()), tools::seconds_since(start));
      }
      if (!quiet) print_segment_seconds(report, true);
      return 0;
    }
    if (stage == "assemble") {
      PartHeader header;
      if (!segment.empty()) {
        std::vector<SegmentMeasure> read;
        for (const std::string& m : measures) read.push_back(read_segment_measure(m));
        placement.emplace();
        sequence = assemble_segment(parts, options, parse_segment(segment), read, &*placement, &report, &header);
        if (!sequence) {
          if (!quiet)
            std::printf("fmenc: segment %s is empty (the capture has fewer groups of keyframes): no file written\n", segment.c_str());
          return 0;
        }
        if (!quiet) print_segment_seconds(report, false);
      } else {
        sequence = assemble_parts(parts, options, &report, &header);
      }
      landmark_names = header.capture.given_landmark_names;
      duration = header.capture.last_time - header.capture.first_time + 1.0 / header.capture.fps;
      frame_count = static_cast<size_t>(header.capture.frame_count);
    } else {
      Capture capture = open_for_encode(input);
      if (stage == "sample") {
        const FrameRange range = parse_frames(frames, static_cast<int>(capture.frames.size()));
        const PartHeader header = encode_part(capture, options, range, output);
        if (stages.count(current)) stages[current]->finish();
        if (!quiet) {
          std::printf("fmenc: %s: frames %d:%d of %zu sampled (reference frame %d), %llu bytes, %.1f s\n", output.c_str(), range.first,
                      range.end, capture.frames.size(), header.capture.reference,
                      static_cast<unsigned long long>(std::filesystem::file_size(output)), tools::seconds_since(start));
        }
        return 0;
      }
      landmark_names = capture.landmark_names;
      duration = capture.duration() + 1.0 / capture.fps;
      frame_count = capture.frames.size();
      sequence = encode_capture_stored(std::move(capture), options, &report);
    }
    if (stages.count(current)) stages[current]->finish();
    SequenceFileMetadata metadata;
    metadata.settings = encode_settings_json(options, report);
    metadata.landmark_names = landmark_names;
    metadata.keyframe_texture_qualities = report.texture_qualities;
    metadata.texture_codec = options.texture_codec;
    metadata.texture_coding = parse_texture_coding(texture_coding);
    metadata.field_coding = report.field_coding;
    const auto write_start = std::chrono::steady_clock::now();
    if (placement) {
      write_segment_file(output, *sequence, metadata, *placement);
    } else {
      write_sequence_file(output, *sequence, metadata);
    }
    const double seconds_writing = tools::seconds_since(write_start);
    if (quiet) return 0;
    const double seconds = tools::seconds_since(start);
    const auto bytes = std::filesystem::file_size(output);
    std::printf("fmenc: %s: %zu frames, %zu keyframes at", output.c_str(), frame_count - report.dropped.size(),
                sequence->shape().keyframes.size());
    for (const Keyframe& key : sequence->shape().keyframes) std::printf(" %.3f", key.time);
    std::printf(" s\n");
    if (options.residual_frames) {
      const ResidualFitReport& r = report.residual_fit;
      std::printf(
          "  residual frames: %zu (fitted to the stored keyframes on %d frames between them: %d decode %.0f%% better or more, %d no "
          "better; "
          "their decoded error mean %.4f%% -> %.4f%%, worst %.4f%% -> %.4f%% of the diagonal; %.1f s)\n",
          sequence->shape().residuals.size(), r.frames_fitted, r.frames_improved, 100 * kDecodedResidualMinGain, r.frames_worse,
          100 * r.mean_before, 100 * r.mean_after, 100 * r.worst_before, 100 * r.worst_after, r.seconds);
    }
    std::printf("  grid N = %d, %s, %s registration, %s spline%s%s\n", sequence->shape().grid_n,
                representation_name(sequence->shape().representation), registration_method_name(options.registration.method),
                spline_kind_name(sequence->shape().spline),
                sequence->outline().has_texture()
                    ? (", " + std::to_string(report.texture_size) + "x" + std::to_string(report.texture_size) + " texture").c_str()
                    : ", no texture",
                sequence->outline().has_holes ? ", holes cut on decode" : "");
    if (report.blend.trials > 0) {
      std::printf(
          "  representation %s (auto): %d of %zu frames share no interior landmarks with the reference; blended at %d frames "
          "between keyframes, the fields come out %.3f%% from them, the positions %.3f%%%s\n",
          representation_name(report.representation), report.frames_without_interior_landmarks, frame_count - report.dropped.size() - 1,
          report.blend.trials, 100 * report.blend.fields_error, 100 * report.blend.positions_error,
          report.representation == Representation::kXYZ ? " (--representation hl+t stores the fields)" : "");
    }
    if (!report.sparse && report.keyframe_budget > 0 && static_cast<int>(sequence->shape().keyframes.size()) > report.keyframe_budget) {
      std::printf(
          "  keyframes: the %g%% budget (%d) left %.3f%% mean / %.3f%% worst / %.3f%% worst 99th percentile predicted between keyframes, "
          "above the %.2g%% / %.2g%% / %.2g%% bound for frames far apart or fast: %zu keyframes (--keyframes P keeps a budget exactly)\n",
          100 * options.keyframe_fraction, report.keyframe_budget, 100 * report.budget_mean_error, 100 * report.budget_worst_error,
          100 * report.budget_worst_p99, 100 * options.keyframe_error_bound, 300 * options.keyframe_error_bound,
          100 * options.keyframe_p99_bound, sequence->shape().keyframes.size());
    }
    if (report.sparse) {
      std::printf(
          "  keyframes: every frame, as the frames lie %.3f s apart (median), sparser than one every %.2f s: the spline has nothing "
          "between "
          "them to be checked against, so each is stored, not predicted (--keyframes P keeps a budget exactly)\n",
          report.median_frame_interval, options.sparse_frame_interval);
    }
    if (!report.grid_floors.empty()) {
      std::printf("  --grid auto: resampling floor (RMS of the diagonal)");
      for (const auto& [n, floor] : report.grid_floors) std::printf(" %d: %.3f%%", n, 100 * floor);
      std::printf("; 99th percentile");
      for (const auto& [n, p99] : report.grid_floor_p99s) std::printf(" %d: %.3f%%", n, 100 * p99);
      std::printf(
          "; the capture's median frame noise %.3f%%; density cap N = %d (a vertex of the denser quarter holds %.3g of the disk: %.2f "
          "nodes at N = %d)\n",
          100 * report.median_noise, report.grid_density_cap, report.grid_vertex_area,
          report.grid_vertex_area * (sequence->shape().grid_n - 1) * (sequence->shape().grid_n - 1) / 4.0, sequence->shape().grid_n);
      const char* why = report.grid_term == "interpolation" ? "half the mean error predicted between keyframes"
                        : report.grid_term == "noise"       ? "the median frame noise"
                                                            : "the fixed floor";
      if (report.grid_term == "density") {
        std::printf(
            "  --grid auto: N = %d, as fine as the captured mesh's density asks (at most 3 nodes in the area of a vertex of its denser "
            "quarter)\n",
            sequence->shape().grid_n);
      } else if (report.grid_term == "worst region") {
        std::printf("  --grid auto: N = %d, the smallest whose 99th percentile is within %.3f%% (the worst region)\n",
                    sequence->shape().grid_n, 100 * report.grid_worst_target);
      } else {
        std::printf("  --grid auto: N = %d, the smallest within %.3f%% (%s)\n", sequence->shape().grid_n, 100 * report.grid_target, why);
      }
    }
    if (report.radial_equalising > 0) {
      // A whole head (spec/method.md §7.11): the reparametrisation, the representation it forces and
      // what a keyframe then differs from its frame by (G's resampling floor, then the rounding).
      double floor = -1;
      for (const auto& [n, f] : report.grid_floors) {
        if (n == sequence->shape().grid_n) floor = f;
      }
      const std::vector<double>& rounding = report.field_precision.keyframe_errors;
      const double rounded = rounding.empty() ? 0 : *std::max_element(rounding.begin(), rounding.end());
      // "whole head" only where the rule found one; a strength asked for on a face says so.
      const bool crowded = report.density_equalising.half_area_radius_before < kCrowdedHalfAreaRadius;
      std::printf(
          "  %s: the conformal disk held half the surface within %.3f of its centre (%s); spread "
          "radially (strength %.2g) to %.3f; keyframes stored as positions (%s)",
          crowded ? "whole head" : "radial equalising", report.density_equalising.half_area_radius_before,
          crowded ? "the neck rim crowds the face" : "not crowded: asked for", report.radial_equalising,
          report.density_equalising.half_area_radius_after,
          sequence->shape().representation == Representation::kXYZ ? "hl+t does not converge on the spread disk"
                                                                   : "as asked: hl+t may not converge");
      if (floor >= 0) {
        std::printf("; keyframe error %.3f%% RMS of the diagonal (resampling at N = %d %.3f%%, rounding %.3f%% worst)",
                    100 * std::hypot(floor, rounded), sequence->shape().grid_n, 100 * floor, 100 * rounded);
      }
      std::printf("\n");
    }
    std::printf("  %llu bytes: %.0f bytes per second of capture (%.1f kbit/s)\n", static_cast<unsigned long long>(bytes),
                static_cast<double>(bytes) / duration, static_cast<double>(bytes) * 8 / duration / 1000);
    double worst = 0, worst_p99 = 0;
    for (const EncodedFrameReport& f : report.frames) {
      worst = std::max(worst, f.predicted_error);
      worst_p99 = std::max(worst_p99, f.predicted_p99);
    }
    std::printf("  predicted worst error between keyframes: %.3f%% of the bbox diagonal (RMS), %.3f%% (99th percentile)\n", 100 * worst,
                100 * worst_p99);
    if (report.field_coding.predicted()) {
      const std::vector<double>& e = report.field_precision.keyframe_errors;
      std::printf(
          "  fields rounded to %.3g%% of the diagonal%s (RMS; worst keyframe %.3g%%), intra every %d keyframes, dead zone %.2f steps\n",
          100 * report.field_precision.target_error, options.auto_field_error ? " (auto)" : "", 100 * *std::max_element(e.begin(), e.end()),
          report.field_coding.intra_period, report.field_precision.inter_dead_zone);
    }
    if (!report.texture_qualities.empty()) {
      const auto [lo, hi] = std::minmax_element(report.texture_qualities.begin(), report.texture_qualities.end());
      const bool lossless = *lo > 100;
      std::printf("  textures: %s", lossless ? "lossless WebP"
                                             : (std::string(options.texture_codec == TextureCodec::kAvif ? "AVIF" : "WebP") + " quality " +
                                                std::to_string(*lo) + " to " + std::to_string(*hi))
                                                   .c_str());
      std::vector<double> measured;
      for (double db : report.texture_interpolation_psnr) {
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
      const std::shared_ptr<const KeyframeSource> decoded = open_sequence_source(output, kDefaultDecoderLimits, &written);
      double sum_db = 0, low_db = std::numeric_limits<double>::infinity();
      for (size_t k = 0; k < sequence->shape().keyframes.size(); ++k) {
        const double db = psnr_of_mse(disk_texture_mse(*sequence->texture(k), *decoded->texture(k)));
        sum_db += db;
        low_db = std::min(low_db, db);
      }
      uint64_t texture_bytes = 0;
      for (const auto& c : written.chunks) texture_bytes += c.type == "TEXR" || c.type == "TGOP" ? c.stored_bytes : 0;
      const std::string layout = written.metadata.texture_coding == TextureCoding::kSequence ? "one AV1 sequence per group"
                                 : written.distinct_textures < sequence->shape().keyframes.size()
                                     ? std::to_string(written.distinct_textures) + (written.distinct_textures == 1 ? " still" : " stills") +
                                           std::string(" for ") + std::to_string(sequence->shape().keyframes.size()) + " keyframes"
                                     : "stills";
      std::printf("  textures as decoded: %llu bytes (%s), PSNR on the disk %.2f dB mean, %.2f dB lowest\n",
                  static_cast<unsigned long long>(texture_bytes), layout.c_str(),
                  sum_db / static_cast<double>(sequence->shape().keyframes.size()), low_db);
      // Keyframes showing an earlier keyframe's texture: what that costs against their own.
      int shared = 0;
      double lowest_share_db = std::numeric_limits<double>::infinity();
      for (size_t k = 0; k < report.texture_shared_with.size(); ++k) {
        if (report.texture_shared_with[k] < 0) continue;
        ++shared;
        lowest_share_db = std::min(lowest_share_db, report.texture_share_psnr[k]);
      }
      if (shared > 0) {
        std::printf(
            "  textures shared: %d of %zu keyframes show an earlier keyframe's, painted from the same captured image (against their own: "
            "%.1f dB lowest)\n",
            shared, sequence->shape().keyframes.size(), lowest_share_db);
      }
    }
    if (report.parts > 0) {
      std::printf(
          "  %d parts: mapping %.1f s, registration %.1f s, selection %.1f s in the sample stage (summed over the parts); here %.1f s, "
          "%.3f s per "
          "frame (reading the parts %.1f s, representation %.1f s, keyframes %.1f s, field precision %.1f s, texture quality %.1f s, "
          "writing %.1f s)\n",
          report.parts, report.seconds_mapping, report.seconds_registration, report.seconds_selection, seconds,
          seconds / static_cast<double>(frame_count), report.seconds_reading_parts, report.seconds_representation, report.seconds_keyframes,
          report.seconds_precision, report.seconds_texture, seconds_writing);
    } else {
      std::printf(
          "  %.1f s, %.2f s per frame (mapping %.1f s, registration %.1f s, selection %.1f s, representation %.1f s, keyframes %.1f s, "
          "field precision %.1f s, texture quality %.1f s, writing %.1f s)\n",
          seconds, seconds / static_cast<double>(frame_count), report.seconds_mapping, report.seconds_registration,
          report.seconds_selection, report.seconds_representation, report.seconds_keyframes, report.seconds_precision,
          report.seconds_texture, seconds_writing);
    }
    if (report.spilled_bytes > 0) {
      std::printf("  frames' maps: %.0f MB in a temporary file, at most %d in memory at once\n",
                  static_cast<double>(report.spilled_bytes) / 1e6, report.peak_frames_in_memory);
    }
    if (report.selection_spilled_bytes > 0 || report.keyframes_spilled_bytes > 0) {
      std::printf(
          "  the selection's samples: %.0f MB, at most %d frames' in memory; the keyframes' arrays: %.0f MB, at most %d a step in memory\n",
          static_cast<double>(report.selection_spilled_bytes) / 1e6, report.peak_selection_samples_in_memory,
          static_cast<double>(report.keyframes_spilled_bytes) / 1e6, report.peak_keyframes_in_memory);
    }
    if (report.registration_fallbacks > 0) {
      std::printf("  %d frames fell back in registration:\n", report.registration_fallbacks);
      for (const EncodedFrameReport& f : report.frames) {
        if (f.fallback != RegistrationFallback::kNone) std::printf("    %s: %s\n", f.name.c_str(), f.fallback_reason.c_str());
      }
    }
    for (const EncodedFrameReport& f : report.frames) {
      if (!f.conformal_fallback_reason.empty()) {
        std::printf("  %s: mapped by the %s map: %s\n", f.name.c_str(), conformal_method_name(f.conformal_method),
                    f.conformal_fallback_reason.c_str());
      }
    }
    if (!report.dropped.empty()) {
      std::printf("  %zu of %zu frames dropped (the spline covers their times; --strict ends the encode instead):\n", report.dropped.size(),
                  frame_count);
      for (const DroppedFrame& d : report.dropped)
        std::printf("    %s (frame %d, %.3f s): %s\n", d.name.c_str(), d.index, d.time, d.reason.c_str());
    }
    for (const std::string& warning : report.warnings) std::printf("  warning: %s\n", warning.c_str());
    if (report.orientation_found > 0) {
      std::printf(
          "  landmarks: nose tip and up found from the geometry on %d frames (mirror plane within %.2f%% of the diagonal, up evidence at "
          "least %.2f of 1; %d frames took up from another frame)%s\n",
          report.orientation_found, 100 * report.worst_mirror_error, report.weakest_up_evidence, report.up_from_hint,
          report.rim_markers_found ? "; rim markers placed on each frame's rim" : "");
      std::printf("  face found by %s (frames: %d whole surface, %d texture, %d face region), confidence at least %.2f of 1\n",
                  report.main_orientation_method(), report.orientation_methods[0], report.orientation_methods[1],
                  report.orientation_methods[2], report.lowest_face_confidence);
    } else if (report.rim_markers_found) {
      std::printf("  landmarks: rim markers placed on each frame's rim (the capture has none)\n");
    }
    if (report.tracked_frames > 0) {
      std::printf(
          "  landmarks: %d points of the reference's disk tracked onto %d frames by optical flow (%.2f s): %.0f kept per frame on average, "
          "%d at fewest; round trip median %.2f%%, 90%% within %.2f%% of the disk's radius\n",
          report.tracking_grid_points, report.tracked_frames, report.seconds_tracking, report.tracked_points_mean,
          report.tracked_points_fewest, 100 * report.tracked_round_trip_median, 100 * report.tracked_round_trip_p90);
    }
    const nlohmann::json repairs = nlohmann::json::parse(metadata.settings)["repairs"];  // the totals, as the file states them
    if (repairs["frames_repaired"].get<int>() > 0) {
      std::printf(
          "  repairs: %d of %zu frames repaired, %d faces and %d vertices changed in all, the surface moved at most %.3g (%.3g%% of the "
          "diagonal)%s\n",
          repairs["frames_repaired"].get<int>(), report.frames.size(), repairs["faces_changed"].get<int>(),
          repairs["vertices_changed"].get<int>(), repairs["largest_move"].get<double>(),
          100 * repairs["largest_move_of_diagonal"].get<double>(),
          options.strict ? "" : " (--strict refuses a frame with bow ties, edges of 3+ faces or islands)");
    }
    // Each frame's own repairs, as many lines as a reader takes in; the settings hold the totals.
    constexpr int kRepairLinesShown = 8;
    std::string last;
    int shown = 0, more = 0;
    for (const EncodedFrameReport& f : report.frames) {
      if (f.repair == "valid as captured" || f.repair == last) continue;
      last = f.repair;
      if (shown++ < kRepairLinesShown) {
        std::printf("  %s: %s\n", f.name.c_str(), f.repair.c_str());
      } else {
        ++more;
      }
    }
    if (more > 0) std::printf("  ... and %d more frames repaired (fminfo lists the first %zu)\n", more, kRepairedFramesListed);
    return 0;
  });
}
