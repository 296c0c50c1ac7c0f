// fmbench temporal: the temporal model on whole captures — registration (the paper's Tables 1 and
// 3), keyframes and the spline (held-out error, Table 4's extrapolation), holes, texture — every
// captured frame decoded at its own time and compared with the frame as captured.
#include "tools/bench_temporal.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/image/texture_codec.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/conformal/resample.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/imageio/image_io.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tools/bench_inputs.hpp"
#include "tools/bench_sequence.hpp"
#include "tools/plot.hpp"
#include "tools/tool_support.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include <unistd.h>

namespace facemorph::tools {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// --through-file: every sequence is measured as a user gets it from fmenc and fmdec: its fields
// rounded as fmenc rounds them (round_fields), written by
// encode_sequence_file with AVIF textures at fmenc's qualities (choose_texture_qualities), and read back.
bool through_file = false;

Sequence stored(SequenceEncoder& encoder, Sequence sequence, const KeyframeSelection& chosen, size_t* file_bytes = nullptr) {
  if (!through_file) return sequence;
  const FieldCoding coding = round_fields(field_precision_options(encoder.options(), chosen), sequence, encoder.report());
  std::vector<uint8_t> file;
  Sequence back = file_round_trip(
      sequence,
      choose_texture_qualities(texture_settings(encoder.options()), texture_frames(encoder), sequence, chosen.keyframes, encoder.report()),
      &file, nullptr, coding);
  if (file_bytes) *file_bytes = file.size();
  return back;
}

void print_evaluation(const std::string& label, const Evaluation& e) {
  const Summary s = summarise(e);
  std::printf("%-28s %-8s %-11s %4d %5d %9.4f %9.4f %9.4f %9.4f %9.4f %8.2f %8.2f %8.1f\n", label.c_str(), e.registration.c_str(),
              e.spline.c_str(), e.keyframes, e.grid, 100 * s.key_rms_worst, 100 * s.held_rms_mean, 100 * s.held_rms_worst,
              100 * s.held_max_worst, 100 * s.key_rms_mean, s.psnr_mean, s.psnr_worst, e.decode_ms);
}

// The paper's Table 1 for one registration: matching energies averaged over the frames.
struct MatchingEnergies {
  double disk_moebius = 0, disk = 0;  // E_D of the OMT alone and of the registration (disk units²)
  double local = 0;                   // E_loc: Σ |f(p) - q|² over the landmarks, in 3D (capture units²)
  double global = 0;                  // E: ∫_D |S_b(f(x)) - S_a(x)|² dx in the face frame (capture units²)
  double global_relative = 0;         // sqrt(E / area of D) / diagonal: the RMS correspondence distance
};

MatchingEnergies matching_energies(SequenceEncoder& encoder) {
  MatchingEnergies m;
  const Capture& capture = encoder.capture();
  const int reference = encoder.options().reference_frame;
  const auto& selection = encoder.selection().frames();
  const auto& weights = encoder.selection().weights();
  double area = 0;
  for (double w : weights) area += w;
  int counted = 0;
  for (int i = 0; i < encoder.frame_count(); ++i) {
    if (i == reference) continue;
    const std::shared_ptr<const DiskRegistration> registration = encoder.registration(i);
    const DiskRegistration& f = *registration;
    m.disk_moebius += f.energy_moebius;
    m.disk += f.energy;
    // E_loc: the reference's landmarks carried through f onto frame i, against frame i's own.
    const std::shared_ptr<const MappedFrame> frame = encoder.frame(i);  // held while `inverse` refers to its map
    const InverseDiskMap inverse(frame->map);
    const DiskLandmarks landmarks = encoder.frame_disk_landmarks(i);
    const std::vector<Vec3> reference_points = encoder.landmarks(reference), frame_points = encoder.landmarks(i);
    size_t j = 0;
    for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
      const Vec3 &p = reference_points[l], &q = frame_points[l];
      if (!p.allFinite() || !q.allFinite()) continue;
      const auto hit = inverse.locate(f(landmarks.reference[j++]));
      if (hit) m.local += (inverse.position(*hit) - q).squaredNorm();
    }
    double sum = 0;
    const std::shared_ptr<const SelectionFrame> sampled = encoder.selection().frame(i);
    for (size_t v = 0; v < weights.size(); ++v)
      sum += weights[v] * (sampled->local[v] - selection[static_cast<size_t>(reference)].local[v]).squaredNorm();
    m.global += sum;
    m.global_relative += std::sqrt(sum / area) / selection[static_cast<size_t>(i)].diagonal;
    ++counted;
  }
  if (counted) {
    m.disk_moebius /= counted, m.disk /= counted, m.local /= counted, m.global /= counted, m.global_relative /= counted;
  }
  return m;
}

}  // namespace

void add_temporal_command(CLI::App& app, TemporalBenchOptions& options) {
  CLI::App* cmd = app.add_subcommand("temporal", "The temporal model: registration, keyframes, spline, holes, texture on whole captures");
  cmd->add_option("inputs", options.inputs,
                  "Capture folders, or: synth (fmsynth --frames 60 --expression mixed --remesh --noise 0), synth:head30 (the same with "
                  "--head-motion 30), medusa, ict (make_capture.py --start-seconds 56 --seconds 4). None: all four");
  cmd->add_option("--keyframes", options.keyframes, "Keyframe budget, e.g. 10%")->capture_default_str();
  cmd->add_option("--registration", options.registration,
                  "Registrations to compare, a comma-separated list of moebius, gmf, frame (e.g. moebius,gmf,frame), or all (those three). "
                  "Improvements are over the first when it is moebius; the later stages use gmf when listed")
      ->capture_default_str();
  cmd->add_option("--spline", options.spline, "local | catmull-rom | not-a-knot | linear | all")->capture_default_str();
  cmd->add_option("--representation", options.representation, "hl | hl+t | xyz")->capture_default_str();
  cmd->add_option("--grid", options.grid, "auto or N")->capture_default_str();
  cmd->add_option("--texture-size", options.texture_size, "Disk texture texels per side")->capture_default_str();
  cmd->add_option("--data", options.data, "Folder of the shared real data")->capture_default_str();
  cmd->add_option("--density-equalising", options.density_equalising,
                  "Strength in [0, 1] of the reference disk's density-equalising reparametrisation (0: the conformal disk)")
      ->capture_default_str();
  cmd->add_option("--limit", options.limit, "At most this many frames per capture (0: all)")->capture_default_str();
  cmd->add_option("--json", options.json_out, "Also write the results as JSON to this file ('-': standard output)");
  cmd->add_option("--plots", options.plots, "Folder for error-against-time plots (PNG), keyframes marked");
  cmd->add_flag("--through-file", through_file,
                "Measure each sequence after writing it as a .fmv file and reading it back (as fmenc and fmdec: fields rounded to "
                "--field-error auto, AVIF textures at --quality auto); report the file's bytes");
  cmd->add_flag("--no-targets", options.no_targets, "Skip the keyframes-for-1%-and-0.5% searches");
  cmd->add_flag("-q,--quiet", options.quiet, "No progress display");
  cmd->footer(
      "Errors: symmetric point-to-surface distance between the decoded surface (holes cut) and the captured frame, "
      "relative to its bounding-box diagonal, %. key: keyframes' worst RMS; held: held-out frames' mean and worst RMS "
      "and worst max; psnr: held-out texture against the captured one on the disk, mean and worst (dB).");
}

int run_temporal_bench(const TemporalBenchOptions& options) {
  std::vector<std::string> inputs = options.inputs;
  if (inputs.empty()) inputs = {"synth", "synth:head30", "medusa", "ict"};
  // A list: "moebius,gmf,frame"; "all" is that list. Each registration is measured in the order given.
  std::vector<RegistrationMethod> methods;
  if (options.registration == "all") {
    methods = {RegistrationMethod::kMoebius, RegistrationMethod::kGmf, RegistrationMethod::kFrame};
  } else {
    size_t begin = 0;
    while (begin <= options.registration.size()) {
      const size_t end = std::min(options.registration.find(',', begin), options.registration.size());
      const RegistrationMethod method = parse_registration_method(options.registration.substr(begin, end - begin));
      if (std::find(methods.begin(), methods.end(), method) == methods.end()) methods.push_back(method);
      begin = end + 1;
    }
  }
  std::vector<SplineKind> splines;
  if (options.spline == "all") {
    splines = {SplineKind::kCatmullRom, SplineKind::kLocalCubic, SplineKind::kNotAKnot, SplineKind::kLinear};
  } else {
    splines = {parse_spline_kind(options.spline)};
  }
  // Read before any capture is made: a bad fraction is refused at once, not after a synthesis.
  const double keyframe_fraction = parse_fraction(options.keyframes, "--keyframes");
  const ScratchFolder scratch_folder("fmbench-temporal");
  const fs::path& scratch = scratch_folder.path;

  json results = json::array();
  for (const std::string& input : inputs) {
    SynthOptions synth;
    synth.remesh = true;
    synth.noise = 0;
    synth.texture_size = 512;
    const auto folder = make_bench_capture(input, options.data, scratch, synth, "fmbench temporal", options.quiet);
    if (!folder) {
      std::printf("\n%s: skipped (the shared data or python3 is absent)\n", input.c_str());
      continue;
    }
    Capture capture = read_capture(*folder);
    if (options.limit > 0 && capture.frames.size() > static_cast<size_t>(options.limit)) {
      capture.frames.resize(static_cast<size_t>(options.limit));
      capture.landmarks.resize(static_cast<size_t>(options.limit));
    }
    const int count = static_cast<int>(capture.frames.size());
    EncodeOptions encode;
    encode.keyframe_fraction = keyframe_fraction;
    encode.residual_frames = false;  // the sequences here are built without residuals: the spline's own keyframes
    encode.representation = parse_representation(options.representation);
    encode.grid = options.grid == "auto" ? 0 : tools::parse_whole_number(options.grid, "--grid", kMinGridSize, kMaxGridSize);
    encode.texture_size = options.texture_size;
    encode.spline = splines.front();
    encode.density_equalising.strength = options.density_equalising;
    Progress progress(input, options.quiet);
    encode.progress = [&](const std::string&, int done, int total) { progress.update(done, total); };
    SequenceEncoder encoder(capture, encode);
    map_frames(encoder);
    progress.finish();
    std::vector<TriangleMesh> captured;
    for (int i = 0; i < count; ++i)
      captured.push_back(read_mesh(capture.mesh_path(static_cast<size_t>(i)), {.allow_missing_texture = true}));
    std::vector<int> every(static_cast<size_t>(count));
    for (int i = 0; i < count; ++i) every[static_cast<size_t>(i)] = i;
    bool textured = encoder.has_texture(0);

    std::printf("\n%s: %d frames at %.3g fps, %s\n", input.c_str(), count, capture.fps, folder->c_str());
    json entry = {{"input", input}, {"frames", count}, {"fps", capture.fps}};
    // Table 1 and Table 3: each registration, keyframes chosen by its own prediction.
    std::printf("%-28s %-8s %-11s %4s %5s %9s %9s %9s %9s %9s %8s %8s %8s\n", "", "reg", "spline", "keys", "N", "key wst%", "held mn%",
                "held wst%", "held max%", "key mn%", "psnr mn", "psnr wst", "dec ms");
    json registrations = json::array();
    std::vector<Evaluation> by_method;
    std::vector<MatchingEnergies> energies_by_method;
    int grid = 0;
    for (RegistrationMethod method : methods) {
      encoder.options().registration.method = method;
      encoder.options().spline = splines.front();
      register_frames(encoder);
      sample_frames(encoder);
      const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
      if (grid == 0) {
        grid = choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report(), &chosen);
        if (!encoder.report().grid_floors.empty()) {
          std::printf("    --grid auto: N = %d (median frame noise %.4f%%; floors", grid, 100 * encoder.report().median_noise);
          for (const auto& [n, floor] : encoder.report().grid_floors) std::printf(" %d: %.4f%%", n, 100 * floor);
          std::printf(")\n");
        }
      }
      if (!encoder.reparametrisation().identity()) {
        const DensityEqualisingReport& d = encoder.reparametrisation().report();
        std::printf("    density-equalising (strength %.2f): %d steps%s, area density variation %.3f -> %.3f\n", options.density_equalising,
                    d.steps, d.stopped_early ? " (stopped: a step would make a sliver)" : "", d.variation_before, d.variation_after);
        entry["density_equalising"] = {{"strength", options.density_equalising},
                                       {"steps", d.steps},
                                       {"stopped_early", d.stopped_early},
                                       {"variation_before", d.variation_before},
                                       {"variation_after", d.variation_after}};
      }
      const MatchingEnergies energies = matching_energies(encoder);
      energies_by_method.push_back(energies);
      size_t file_bytes = 0;
      const Sequence sequence = stored(encoder, build_sequence(encoder, chosen.keyframes, grid), chosen, &file_bytes);
      Evaluation e = evaluate(encoder, sequence, chosen.keyframes, captured, every, textured);
      print_evaluation(input, e);
      const double file_seconds = capture.duration() + 1.0 / capture.fps;
      if (through_file) {
        std::printf("    through the file: %zu bytes, %.0f bytes per second of capture (%.3f s)\n", file_bytes, file_bytes / file_seconds,
                    file_seconds);
      }
      int fallbacks = 0, frame_fallbacks = 0;
      for (int i = 0; i < count; ++i) {
        fallbacks += encoder.registration(i)->fallback != RegistrationFallback::kNone;
        frame_fallbacks += encoder.registration(i)->fallback == RegistrationFallback::kGmfInsteadOfFrame;
      }
      json r = evaluation_json(e);
      if (through_file) r["file_bytes"] = file_bytes, r["file_bytes_per_second"] = file_bytes / file_seconds;
      if (const GeodesicFrame* frame = encoder.geodesic_frame()) {
        const PartitionMesh& partition = *frame->partition;
        std::printf(
            "    geodesic frame of frame %d: %d landmarks, %zu curves (%d straight, %d unconverged), partition %zu vertices / %zu "
            "triangles (%d curve pieces not edges), built in %.2f + %.2f s; %d of %d frames fell back to the GMF\n",
            encoder.options().reference_frame, frame->landmark_count, frame->paths.size(), frame->straight_paths, frame->unconverged_paths,
            partition.vertices().size(), partition.faces().size(), frame->unconforming_segments, frame->seconds_paths,
            frame->seconds_partition, frame_fallbacks, count);
        r["geodesic_frame"] = {{"landmarks", frame->landmark_count},
                               {"curves", frame->paths.size()},
                               {"straight_curves", frame->straight_paths},
                               {"unconverged_curves", frame->unconverged_paths},
                               {"partition_vertices", partition.vertices().size()},
                               {"partition_triangles", partition.faces().size()},
                               {"unconforming_segments", frame->unconforming_segments},
                               {"seconds_paths", frame->seconds_paths},
                               {"seconds_partition", frame->seconds_partition},
                               {"frames_fallen_back_to_gmf", frame_fallbacks}};
      }
      r["matching_energies"] = {{"E_D_moebius", energies.disk_moebius},
                                {"E_D", energies.disk},
                                {"E_loc", energies.local},
                                {"E", energies.global},
                                {"E_rms_relative", energies.global_relative}};
      r["registration_fallbacks"] = fallbacks;
      r["selection_history"] = chosen.history;
      registrations.push_back(r);
      if (!options.plots.empty()) {
        write_error_plot(
            fs::path(options.plots) / (fs::path(input).filename().string() + "_" + registration_method_name(method) + "_error.png"), e);
      }
      by_method.push_back(std::move(e));
      std::printf(
          "    matching energies (mean over frames): E_D OMT %.3e, E_D %.3e, E_loc %.3e %s², E %.3e %s² (RMS %.4f%% of the diagonal); %d "
          "fallbacks\n",
          energies.disk_moebius, energies.disk, energies.local, capture.units.c_str(), energies.global, capture.units.c_str(),
          100 * energies.global_relative, fallbacks);
    }
    entry["grid"] = grid;
    entry["grid_floors"] = encoder.report().grid_floors;
    entry["median_frame_noise"] = encoder.report().median_noise;
    entry["registrations"] = registrations;
    // The rate of improvement over the OMT (paper Tables 1 and 3): 1 - (measure with f) / (measure with m).
    if (by_method.size() > 1 && methods.front() == RegistrationMethod::kMoebius) {
      const double m = summarise(by_method.front()).held_rms_mean;
      const MatchingEnergies& em = energies_by_method.front();
      for (size_t k = 1; k < by_method.size(); ++k) {
        const double g = summarise(by_method[k]).held_rms_mean;
        const MatchingEnergies& ek = energies_by_method[k];
        auto rate = [](double omt, double other) { return omt > 0 ? (omt - other) / omt : 0.0; };
        std::printf("    improvement of %s over moebius: held-out mean RMS %.1f%%, E_D %.1f%%, E_loc %.1f%%, E %.1f%%\n",
                    by_method[k].registration.c_str(), 100 * rate(m, g), 100 * rate(em.disk, ek.disk), 100 * rate(em.local, ek.local),
                    100 * rate(em.global, ek.global));
        entry["improvement_over_moebius"][by_method[k].registration] = rate(m, g);
        entry["energy_improvement_over_moebius"][by_method[k].registration] = {
            {"E_D", rate(em.disk, ek.disk)}, {"E_loc", rate(em.local, ek.local)}, {"E", rate(em.global, ek.global)}};
      }
    }

    // The rest with the encoder's default registration when it was measured, else the last one run.
    const RegistrationMethod default_method = RegistrationOptions{}.method;
    const RegistrationMethod main_method =
        std::find(methods.begin(), methods.end(), default_method) != methods.end() ? default_method : methods.back();
    if (encoder.registration(0)->method != main_method) {
      encoder.options().registration.method = main_method;
      register_frames(encoder);
      sample_frames(encoder);
    }
    // Spline kinds, same keyframes count, each choosing its own keyframes.
    if (splines.size() > 1) {
      json kinds = json::array();
      for (SplineKind kind : splines) {
        encoder.options().spline = kind;
        const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
        Sequence sequence = stored(encoder, build_sequence(encoder, chosen.keyframes, grid), chosen);
        const Evaluation e = evaluate(encoder, sequence, chosen.keyframes, captured, every, false);
        print_evaluation(input, e);
        kinds.push_back(evaluation_json(e));
      }
      entry["splines"] = kinds;
      encoder.options().spline = splines.front();
    }
    // Table 4: keyframes chosen from all but the last 10 frames, decoded 1, 3 and 10 frames past.
    if (count >= 20) {
      const int last = count - 11;
      std::vector<SelectionFrame> head;  // with their samples, read back from the encoder's store
      for (int i = 0; i <= last; ++i) head.push_back(*encoder.selection().frame(i));
      SelectionOptions so;
      so.fraction = encode.keyframe_fraction;
      so.spline = encoder.options().spline;
      so.pose_centre = encoder.pose_centre();
      const KeyframeSelection chosen = select_keyframes(head, encoder.selection().weights(), so);
      const Sequence sequence = stored(encoder, build_sequence(encoder, chosen.keyframes, grid), chosen);
      const KeyframeSpline spline(sequence.keyframe_times(), sequence.spline);
      const Evaluation e = evaluate(encoder, sequence, chosen.keyframes, captured, {last + 1, last + 3, last + 10}, false);
      json extrapolation = json::array();
      std::printf("    extrapolation past the last keyframe (t = %.3f s; sane to %.3f s):", capture.frames[static_cast<size_t>(last)].time,
                  spline.sane_range().end);
      for (size_t k = 0; k < e.frames.size(); ++k) {
        const int ahead = k == 0 ? 1 : k == 1 ? 3 : 10;
        std::printf("  +%d frames: %.4f%% RMS, %.4f%% max", ahead, 100 * e.frames[k].rms, 100 * e.frames[k].max);
        extrapolation.push_back({{"frames_past", ahead},
                                 {"time", e.frames[k].time},
                                 {"rms_relative", e.frames[k].rms},
                                 {"max_relative", e.frames[k].max},
                                 {"within_sane_range", e.frames[k].time <= spline.sane_range().end}});
      }
      std::printf("\n");
      entry["extrapolation"] = extrapolation;
    }
    // Keyframes needed for a worst held-out RMS of 1% and of 0.5%: the tolerance mode, tightened
    // until the measured worst meets it (the selection predicts; the decoder decides).
    if (!options.no_targets) {
      json targets = json::array();
      for (double target : {0.01, 0.005}) {
        double tolerance = target;
        for (int attempt = 0; attempt < 4; ++attempt) {
          encoder.options().max_error = tolerance;
          const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
          const Sequence sequence = stored(encoder, build_sequence(encoder, chosen.keyframes, grid), chosen);
          const Evaluation e = evaluate(encoder, sequence, chosen.keyframes, captured, every, false);
          const double worst = summarise(e).held_rms_worst;
          if (worst <= target || attempt == 3 || static_cast<int>(chosen.keyframes.size()) == count) {
            std::printf("    worst held-out RMS <= %.1f%%: %d keyframes of %d (%.1f%%), measured worst %.4f%%%s\n", 100 * target,
                        static_cast<int>(chosen.keyframes.size()), count, 100.0 * chosen.keyframes.size() / count, 100 * worst,
                        worst <= target ? "" : " (not met)");
            targets.push_back(
                {{"target", target}, {"keyframes", chosen.keyframes.size()}, {"measured_worst", worst}, {"met", worst <= target}});
            break;
          }
          tolerance *= 0.7 * target / worst;
        }
      }
      encoder.options().max_error = 0;
      entry["keyframes_for_target"] = targets;
    }
    results.push_back(entry);
  }
  if (!options.json_out.empty()) write_json(options.json_out, {{"benchmark", "temporal"}, {"results", results}});
  return 0;
}

}  // namespace facemorph::tools
