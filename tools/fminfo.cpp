// fminfo: describes a facemorph input or output. For a capture (a folder with capture.json, or a
// plain folder of meshes with --fps) it reads, validates and repairs every frame the way the
// encoder will, and prints a summary (or JSON).
#include "facemorph.h"

#include "codec/core/util/parallel.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/prepare/frame.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/chunk_writers.hpp"
#include "format/container.hpp"

#include "tools/player_options.hpp"
#include "tools/tool_support.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <optional>

namespace {

using namespace facemorph;
namespace fs = std::filesystem;

struct FrameSummary {
  int vertices = 0, faces = 0, prepared_vertices = 0, prepared_faces = 0;
  std::string report;
  std::vector<FilledHole> holes;
  bool has_uvs = false, has_texture = false, has_colours = false;
};

std::vector<Vec3> rim_markers(const Capture& capture, size_t frame) {
  std::vector<Vec3> markers;
  for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
    if (capture.landmark_names[l].rfind("rim_", 0) == 0 && frame < capture.landmarks.size() && capture.landmarks[frame][l].allFinite()) {
      markers.push_back(capture.landmarks[frame][l]);
    }
  }
  return markers;
}

int describe_capture(const Capture& capture, bool json_out, bool quiet, const std::string& prepared_dir) {
  const size_t count = capture.frames.size();
  std::vector<FrameSummary> frames(count);
  tools::Progress progress("fminfo", quiet || json_out);
  parallel_for(
      static_cast<int>(count), 0,
      [&](int i) {
        const fs::path path = capture.mesh_path(static_cast<size_t>(i));
        const TriangleMesh mesh = read_mesh(path);
        PrepareOptions options;
        options.rim_markers = rim_markers(capture, static_cast<size_t>(i));
        const PreparedFrame prepared = prepare_frame(mesh, path.filename().string(), options);
        FrameSummary& s = frames[static_cast<size_t>(i)];
        s.vertices = mesh.vertex_count();
        s.faces = mesh.face_count();
        s.prepared_vertices = prepared.mesh.vertex_count();
        s.prepared_faces = prepared.mesh.face_count();
        s.report = prepared.report.summary();
        s.holes = prepared.report.holes;
        s.has_uvs = mesh.has_uvs();
        s.has_texture = !mesh.texture.empty();
        s.has_colours = mesh.has_colours();
        if (!prepared_dir.empty()) write_mesh(fs::path(prepared_dir) / path.filename().replace_extension(".obj"), prepared.mesh);
      },
      [&](int done, int total) { progress.update(done, total); });
  progress.finish();

  auto [vmin, vmax] = std::minmax_element(frames.begin(), frames.end(), [](auto& a, auto& b) { return a.vertices < b.vertices; });
  size_t repaired = 0, holes = 0;
  double min_angle = 180;
  int folded = 0;
  for (const FrameSummary& s : frames) {
    repaired += s.report != "valid as captured";
    holes += s.holes.size();
    for (const FilledHole& h : s.holes) {
      min_angle = std::min(min_angle, h.min_angle_degrees);
      folded += h.folded_faces;
    }
  }
  if (json_out) {
    nlohmann::json doc;
    doc["kind"] = "capture";
    doc["root"] = capture.root.string();
    doc["description"] = capture.description;
    doc["fps"] = capture.fps;
    doc["units"] = capture.units;
    doc["frames"] = count;
    doc["duration_seconds"] = capture.duration();
    doc["landmarks"] = capture.landmark_names;
    doc["vertices_min"] = vmin->vertices;
    doc["vertices_max"] = vmax->vertices;
    doc["frames_repaired"] = repaired;
    doc["holes_filled"] = holes;
    doc["fill_min_angle_degrees"] = holes ? min_angle : 0.0;
    doc["fill_folded_faces"] = folded;
    nlohmann::json per_frame = nlohmann::json::array();
    for (size_t i = 0; i < count; ++i) {
      per_frame.push_back({{"mesh", capture.frames[i].mesh.generic_string()},
                           {"time", capture.frames[i].time},
                           {"vertices", frames[i].vertices},
                           {"faces", frames[i].faces},
                           {"prepared_vertices", frames[i].prepared_vertices},
                           {"prepared_faces", frames[i].prepared_faces},
                           {"holes", frames[i].holes.size()},
                           {"report", frames[i].report}});
    }
    doc["per_frame"] = std::move(per_frame);
    std::printf("%s\n", doc.dump(1, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
    return 0;
  }
  std::printf("capture     %s\n", capture.root.string().c_str());
  if (!capture.description.empty()) std::printf("            %s\n", capture.description.c_str());
  std::printf("frames      %zu at %.3f fps, %.3f s, units %s\n", count, capture.fps, capture.duration(), capture.units.c_str());
  std::printf("vertices    %d .. %d per frame\n", vmin->vertices, vmax->vertices);
  std::printf("texture     %s\n", frames[0].has_texture   ? "per-frame image with UVs"
                                  : frames[0].has_colours ? "colour per vertex, no image (painted onto the disk)"
                                  : frames[0].has_uvs     ? "UVs, no image"
                                                          : "none");
  std::printf("landmarks   %zu (%zu on the rim)\n", capture.landmark_names.size(), rim_markers(capture, 0).size());
  std::printf("validation  all %zu frames are disks after repair; %zu repaired\n", count, repaired);
  if (holes > 0) {
    std::printf("holes       %zu filled, smallest fill angle %.1f deg, %d folded fill faces\n", holes, min_angle, folded);
  }
  std::string last;
  for (size_t i = 0; i < count; ++i) {
    if (frames[i].report == "valid as captured" || frames[i].report == last) continue;
    std::printf("  %s: %s\n", capture.frames[i].mesh.string().c_str(), frames[i].report.c_str());
    last = frames[i].report;
  }
  return 0;
}

bool is_container(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || path.filename() == "capture.json") return false;
  std::array<uint8_t, format::kMagic.size()> head{};
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(head.data()), static_cast<std::streamsize>(head.size()));
  return in.gcount() == static_cast<std::streamsize>(head.size()) && head == format::kMagic;
}

// A .fmv file: what it holds, how the bytes divide among its parts, and how it was made.

// The settings are the file's to choose (informative JSON, spec/container.md §5), and nlohmann's
// walks over a parsed value (dump, copy, comparison) recurse once per level: settings nested
// 524,288 levels deep (1 MiB of brackets) crashed fminfo --json. fminfo reads settings nested at
// most kMaxSettingsDepth levels: fmenc's and fmcat's nest 3 (arrays of objects in the top object),
// so 64 leaves room for any encoder's, and 64 recursive calls take a few kB of stack anywhere.
constexpr int kMaxSettingsDepth = 64;
// The header reader refuses longer strings; bounded here too so that the parse below stays bounded
// whatever a reader lets through.
constexpr size_t kMaxSettingsBytes = size_t{1} << 20;

// The file's settings as JSON, or why fminfo did not read them.
struct Settings {
  nlohmann::json value;  // null when not read
  std::string problem;   // empty when read
};

Settings read_settings(const std::string& text) {
  Settings settings;
  if (text.empty()) {  // files written before fmenc stored settings
    settings.value = nlohmann::json::object();
    return settings;
  }
  if (text.size() > kMaxSettingsBytes) {
    settings.problem = std::to_string(text.size()) + " bytes, more than the " + std::to_string(kMaxSettingsBytes) + " fminfo reads";
    return settings;
  }
  // nlohmann's parser keeps its own stack (no recursion); the callback stops it at the first array
  // or object that would open level kMaxSettingsDepth + 1 (the outermost one opens at depth 0).
  struct TooDeep {};
  try {
    settings.value = nlohmann::json::parse(text, [](int depth, nlohmann::json::parse_event_t event, nlohmann::json&) {
      const bool opens = event == nlohmann::json::parse_event_t::object_start || event == nlohmann::json::parse_event_t::array_start;
      if (opens && depth >= kMaxSettingsDepth) throw TooDeep{};
      return true;
    });
  } catch (const TooDeep&) {
    settings.value = nullptr;
    settings.problem = "nested deeper than " + std::to_string(kMaxSettingsDepth) + " levels, the most fminfo reads";
  } catch (const nlohmann::json::exception& e) {
    settings.value = nullptr;
    settings.problem = std::string("not JSON (") + e.what() + ")";
  }
  return settings;
}

// What the encoder dropped, mapped another way or warned about, from the settings it stored
// (spec/container.md §8): written by fmenc 0.8 on, absent before.
void print_encoder_notes(const nlohmann::json& settings) {
  if (!settings.is_object()) return;
  // References into the settings, never copies: a copy is another walk of the whole value.
  static const nlohmann::json kNone = nlohmann::json::array();
  auto list = [&](const char* key) -> const nlohmann::json& {
    const auto it = settings.find(key);
    return it != settings.end() && it->is_array() ? *it : kNone;
  };
  auto text = [](const nlohmann::json& item, const char* key) {
    return item.is_object() && item.contains(key) && item[key].is_string() ? item[key].get<std::string>() : std::string("?");
  };
  auto number = [](const nlohmann::json& item, const char* key) {
    return item.is_object() && item.contains(key) && item[key].is_number() ? item[key].get<double>() : 0.0;
  };
  const nlohmann::json &dropped = list("dropped_frames"), &fallbacks = list("conformal_fallbacks"), &warnings = list("warnings");
  if (!dropped.empty()) {
    std::printf("dropped     %zu frames, not encoded (the spline covers their times):\n", dropped.size());
    for (const auto& d : dropped)
      std::printf("            %s at %.3f s: %s\n", text(d, "name").c_str(), number(d, "time"), text(d, "reason").c_str());
  }
  if (!fallbacks.empty()) {
    std::printf("fallbacks   %zu frames mapped without QIEM:\n", fallbacks.size());
    for (const auto& f : fallbacks) {
      std::printf("            %s at %.3f s, %s map: %s\n", text(f, "name").c_str(), number(f, "time"), text(f, "method").c_str(),
                  text(f, "reason").c_str());
    }
  }
  for (const auto& w : warnings) {
    if (w.is_string()) std::printf("warning     %s\n", w.get<std::string>().c_str());
  }
  // The encoder's repairs of the captured meshes (spec/method.md §2.1); absent in files older than issue 47.
  const auto repairs = settings.find("repairs");
  if (repairs != settings.end() && repairs->is_object() && number(*repairs, "frames_repaired") > 0) {
    std::printf(
        "repairs     %.0f frames repaired: %.0f faces and %.0f vertices changed, the surface moved at most %.3g (%.3g%% of the diagonal)\n",
        number(*repairs, "frames_repaired"), number(*repairs, "faces_changed"), number(*repairs, "vertices_changed"),
        number(*repairs, "largest_move"), 100 * number(*repairs, "largest_move_of_diagonal"));
    const auto frames = repairs->find("frames");
    if (frames != repairs->end() && frames->is_array()) {
      for (const auto& f : *frames) std::printf("            %s: %s\n", text(f, "name").c_str(), text(f, "repair").c_str());
    }
  }
}

// The format version a file needs (§12): the oldest minor whose decoder reads all of it. Each minor
// only appended what a file may go without (2.1 texture groups, 2.2 shared textures, 2.3 residual
// frames, 2.4 frame patches), and the writer stamps every file with its own minor, so a file stated
// 2.4 that uses none of them is, but for its preamble, a 2.0 file (spec/container.md §12). 2.5's
// predictor (linear along the rim, §7.2) lies inside the keyframes' streams, where a description
// that decodes nothing cannot see it, and its writer takes it for nearly every rim coded from
// nothing: a file stated 2.5 or later is taken to need 2.5 (its header against the dictionary and
// its patches range-coded, which only a 2.5 file may hold, included). 2.6's levels predictor is in
// KGLV chunks, which the chunk table shows: a file with one needs 2.6, one without 2.5.
int minor_version_needed(const SequenceFileInfo& info, size_t keyframes) {
  if (std::any_of(info.chunks.begin(), info.chunks.end(), [](const auto& c) { return c.type == "KGLV"; })) return 6;
  if (info.minor_version >= 5) return 5;
  const bool texture_groups = std::any_of(info.chunks.begin(), info.chunks.end(), [](const auto& c) { return c.type == "TGOP"; });
  if (info.frame_patches > 0) return 4;
  if (info.residual_frames > 0) return 3;
  if (!texture_groups && info.texture_size > 0 && info.distinct_textures < keyframes) return 2;
  return texture_groups ? 1 : 0;
}

// Where the fields' bytes go (--field-bytes): the arrays of spec/container.md §7.1 in groups (the band's
// and the rim's three components, the positions' three, together), summed over the keyframes, each
// keyframe predicted as the writer predicts it (file_layout::keyframe_array_bits: fresh models, so
// the sum is an estimate of the KGOP chunks' bytes, not a division of them). The keyframes are
// decoded one at a time as --verify decodes them (inspect_sequence_file, within the limits' budget),
// and only the one before is kept: memory does not grow with the file, and a file too long to be
// decoded whole (the encoder's whole-ICT file, 723 MiB) is measured at the default budget.
struct ArrayGroup {
  const char* name;
  size_t first, end;  // arrays [first, end)
  double bytes = 0;
  size_t values = 0;
};
struct FieldBytes {
  std::vector<ArrayGroup> groups;
  SequenceFileInfo checked;  // inspect_sequence_file's description: --verify's, from the same decode
};
// Each keyframe coded as the file's writer coded it: its header's field coding, N (`grid_n`) and
// minor version, whose predictors that writer had (2.5 added one), all read from the same open.
FieldBytes field_bytes_by_group(const fs::path& path, int grid_n, const DecoderLimits& limits) {
  std::vector<ArrayGroup> groups = {{"H", 0, 1},    {"log lambda", 1, 2}, {"a", 2, 3},   {"b", 3, 4},
                                    {"band", 4, 7}, {"positions", 7, 10}, {"rim", 10, 13}, {"hole level", 13, 14}};
  const std::shared_ptr<const file_layout::GridFacts> grid = file_layout::grid_facts(grid_n);
  FieldCoding coding;
  uint16_t minor_version = 0;
  std::optional<Keyframe> previous;
  const auto opened = [&](const SequenceFileInfo& file) {
    coding = file.metadata.field_coding;
    minor_version = file.minor_version;
  };
  SequenceFileInfo checked = inspect_sequence_file(path, limits, opened, [&](size_t k, const Keyframe& key) {
    const std::vector<double> bits =
        file_layout::keyframe_array_bits(key, coding.intra(k) ? nullptr : &*previous, coding, *grid, minor_version);
    const std::vector<std::vector<double>> arrays = file_layout::keyframe_arrays(key);
    for (ArrayGroup& g : groups) {
      for (size_t a = g.first; a < g.end; ++a) g.bytes += bits[a] / 8, g.values += arrays[a].size();
    }
    previous = key;
  });
  return {std::move(groups), std::move(checked)};
}

// By default the file is described from its header and index, every checksum verified, nothing
// decoded: a few ms a MB, so that fminfo stays within the decoder's time bound on any file
// (spec/container.md §10.5). --verify decodes every keyframe once, one at a time, as a player would
// meet it (about 0.4 s a MB at N = 257), and gives each keyframe the bytes its fields took.
int describe_container(const fs::path& path, bool json_out, bool verify, bool field_bytes, const DecoderLimits& limits) {
  // Opened as a player opens it first (the player API, facemorph.h): a file no player may open is
  // refused before anything is decoded, and the description is what a player is told of the file.
  // Closed before the file is opened again below: each open holds the file's residual frames and
  // patches within the budget, both at once would not be (a 58 KB range-coded PTCH holds 250 MB).
  fm_info sequence{};
  std::vector<double> times;
  {
    const tools::PlayerFile player(path.string(), limits);
    sequence = player.info();
    times = player.keyframe_times();
  }
  // --field-bytes decodes every keyframe anyway, and verifies every checksum: that one open serves
  // --verify and the plain description too (each keyframe's fields bytes are shown with --verify only).
  FieldBytes by_array;
  if (field_bytes) by_array = field_bytes_by_group(path, static_cast<int>(sequence.grid_n), limits);
  const SequenceFileInfo info = field_bytes ? std::move(by_array.checked)
                                : verify    ? inspect_sequence_file(path, limits)
                                            : describe_sequence_file(path, limits);
  const std::vector<ArrayGroup>& array_groups = by_array.groups;
  const DiskGridShape shape = disk_grid_shape(static_cast<int>(sequence.grid_n));
  const double duration = sequence.last_time - sequence.first_time + 1.0 / sequence.fps;  // frames last 1/fps each
  const double bytes_per_second = static_cast<double>(info.file_bytes) / duration;
  const size_t fixed = sequence.fixed_node_count;
  const int needed_minor = std::min<int>(minor_version_needed(info, times.size()), info.minor_version);
  // Settings fminfo will not walk are left out (null in --json), said on stderr: the rest of the
  // description stands, as the settings are informative.
  const Settings settings = read_settings(info.metadata.settings);
  if (!settings.problem.empty()) {
    std::fprintf(stderr, "fminfo: warning: %s: the settings are %s; left out\n", path.string().c_str(), settings.problem.c_str());
  }
  if (json_out) {
    nlohmann::json doc;
    doc["file"] = path.string();
    doc["bytes"] = info.file_bytes;
    doc["format_version"] = std::to_string(info.major_version) + "." + std::to_string(info.minor_version);
    doc["format_version_needed"] = std::to_string(info.major_version) + "." + std::to_string(needed_minor);
    doc["encoder"] = info.metadata.encoder;
    doc["fps"] = sequence.fps;
    doc["first_time"] = sequence.first_time;
    doc["last_time"] = sequence.last_time;
    doc["duration_seconds"] = duration;
    doc["units"] = std::string(sequence.units);
    doc["grid"] = {{"n", static_cast<int>(sequence.grid_n)}, {"rule", info.grid_rule},
                   {"hash", tools::hex64(info.grid_hash)},   {"nodes", shape.interior_count + shape.rim_count},
                   {"rim_nodes", shape.rim_count},           {"fixed_nodes", fixed}};
    doc["representation"] = std::string(sequence.representation);
    const FieldCoding& coding = info.metadata.field_coding;
    doc["field_coding"] = {{"steps", coding.steps},
                           {"intra_period", coding.intra_period},
                           {"pose_steps", {{"rotation_radians", coding.rotation_step}, {"translation", coding.translation_step}}}};
    doc["spline"] = std::string(sequence.spline);
    doc["sane_range"] = {sequence.range_begin, sequence.range_end};
    doc["texture_size"] = info.texture_size;
    if (info.texture_size > 0) doc["texture_coding"] = texture_coding_name(info.metadata.texture_coding);
    doc["holes"] = sequence.has_holes != 0;
    doc["residual_frames"] = info.residual_frames;
    doc["frame_patches"] = info.frame_patches;
    doc["patch_nodes"] = info.patch_nodes;
    doc["landmarks"] = info.metadata.landmark_names;
    doc["bytes_per_second"] = bytes_per_second;
    doc["verified"] = verify;  // every keyframe decoded (--verify), or checksums only
    nlohmann::json keys = nlohmann::json::array();
    for (size_t k = 0; k < times.size(); ++k) {
      nlohmann::json key = {{"time", times[k]}, {"texture_bytes", info.keyframes[k].texture}};
      if (verify) key["fields_bytes"] = info.keyframes[k].fields;
      keys.push_back(std::move(key));
    }
    doc["keyframes"] = std::move(keys);
    nlohmann::json groups = nlohmann::json::array();
    for (const auto& g : info.field_groups) groups.push_back({{"first", g.first}, {"count", g.count}, {"bytes", g.bytes}});
    doc["field_groups"] = std::move(groups);
    if (field_bytes) {
      nlohmann::json arrays = nlohmann::json::array();
      for (const ArrayGroup& g : array_groups)
        arrays.push_back({{"arrays", g.name}, {"bytes", g.bytes}, {"values", g.values}});
      doc["field_bytes_by_array"] = std::move(arrays);  // estimated: the writer's cost with fresh models
    }
    nlohmann::json chunks = nlohmann::json::array();
    for (const auto& c : info.chunks)
      chunks.push_back({{"type", c.type},
                        {"count", c.count},
                        {"bytes", c.stored_bytes},
                        {"raw_bytes", c.raw_bytes},
                        {"against_dictionary", c.against_dictionary}});
    doc["chunks"] = std::move(chunks);
    doc["settings"] = settings.value;
    if (!settings.problem.empty()) doc["settings_error"] = settings.problem;
    // The file's strings (encoder, units, landmark names) are the file's bytes: invalid UTF-8
    // shows as U+FFFD, where dump would throw without naming the file.
    std::printf("%s\n", doc.dump(1, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
    return 0;
  }
  // The version the file states, and the one it needs where that is older.
  const std::string needs =
      needed_minor < info.minor_version ? " (needs " + std::to_string(info.major_version) + "." + std::to_string(needed_minor) + ")" : "";
  std::printf("file        %s: %llu bytes, format %d.%d%s, written by %s\n", path.string().c_str(),
              static_cast<unsigned long long>(info.file_bytes), info.major_version, info.minor_version, needs.c_str(),
              info.metadata.encoder.c_str());
  std::printf("capture     %.3f s at %.3f fps (frames at %.3f .. %.3f s), units %s\n", duration, sequence.fps, sequence.first_time,
              sequence.last_time, sequence.units);
  std::printf("rate        %.0f bytes per second of capture (%.1f kbit/s)\n", bytes_per_second, bytes_per_second * 8 / 1000);
  std::printf("grid        N = %d: %d nodes, %d on the rim, rule %d, hash %s\n", static_cast<int>(sequence.grid_n),
              shape.interior_count + shape.rim_count, shape.rim_count, info.grid_rule, tools::hex64(info.grid_hash).c_str());
  const FieldCoding& coding = info.metadata.field_coding;
  std::printf(
      "fields      %s, integer multiples of a step per array, predicted and range-coded in groups of %d keyframes; %zu nodes in boundary "
      "frames\n",
      sequence.representation, coding.intra_period, fixed);
  std::printf("steps       H %.3g, log λ %.3g, tangential %.3g, band %.3g, positions %.3g, rim %.3g, hole level %.3g\n", coding.steps[0],
              coding.steps[1], coding.steps[2], coding.steps[4], coding.steps[7], coding.steps[10], coding.steps[13]);
  std::printf("pose        in the index: rotation vector in steps of %.3g rad, translation in steps of %.3g %s\n", coding.rotation_step,
              coding.translation_step, sequence.units);
  std::printf("spline      %s; decodes t in [%.3f, %.3f] s (one keyframe interval past each end)\n", sequence.spline, sequence.range_begin,
              sequence.range_end);
  const bool texture_groups = info.texture_size > 0 && info.metadata.texture_coding == TextureCoding::kSequence;
  const std::string texture_coding =
      texture_groups
          ? " AVIF image sequence per group of " + std::to_string(coding.intra_period) +
                " keyframes (format 2.1 TGOP; each keyframe's bytes its AV1 sample, a group's first also the chunk's and AVIF container's)"
          : std::string(info.metadata.texture_codec == TextureCodec::kAvif ? " AVIF" : " WebP") +
                (info.distinct_textures < times.size()
                     ? " stills, " + std::to_string(info.distinct_textures) + " for " + std::to_string(times.size()) +
                           " keyframes (format 2.2: keyframes showing one texture name one TEXR; its bytes are the first's)"
                     : " still per keyframe");
  std::printf("texture     %s\n",
              info.texture_size > 0 ? (std::to_string(info.texture_size) + "x" + std::to_string(info.texture_size) + texture_coding).c_str()
                                    : "none");
  std::printf("holes       %s\n", sequence.has_holes != 0 ? "stored as a level set, cut on decode" : "none stored");
  if (info.residual_frames > 0)
    std::printf("residuals   %zu frames between keyframes correct the spline's blend (format 2.3 RSDW)\n", info.residual_frames);
  if (info.frame_patches > 0) {
    std::printf("patches     %zu frames between keyframes displace the surface, %zu lattice nodes in all (format 2.4 PTCH%s)\n",
                info.frame_patches, info.patch_nodes, info.minor_version >= file_layout::kRangedPatchMinorVersion ? ", range-coded as 2.5" : "");
  }
  std::printf("landmarks   %zu names\n", info.metadata.landmark_names.size());
  if (field_bytes) {
    double sum = 0;
    for (const ArrayGroup& g : array_groups) sum += g.bytes;
    std::printf("fields by array (the writer's prediction, fresh models: ~%.0f B in all)\n", sum);
    for (const ArrayGroup& g : array_groups) {
      if (g.values == 0) continue;
      std::printf("  %-11s %9.0f B  %5.1f%%  %6.3f bits a value (%zu values)\n", g.name, g.bytes, 100 * g.bytes / sum,
                  8 * g.bytes / static_cast<double>(g.values), g.values);
    }
  }
  if (verify) {
    std::printf("keyframes   %zu, every one decoded and checked\n", times.size());
    std::printf("    #     time   fields B  texture B\n");
    for (size_t k = 0; k < times.size(); ++k) {
      std::printf("  %3zu %8.3f %10llu %10llu\n", k, times[k], static_cast<unsigned long long>(info.keyframes[k].fields),
                  static_cast<unsigned long long>(info.keyframes[k].texture));
    }
  } else {
    // A group's stream is divided among its keyframes only by decoding it: the group's bytes stand
    // on its first keyframe's line.
    std::printf("keyframes   %zu, checksums verified (fminfo --verify decodes each and gives its fields' bytes)\n", times.size());
    std::printf("    #     time  group's fields B  texture B\n");
    size_t group = 0;
    for (size_t k = 0; k < times.size(); ++k) {
      const bool first = group < info.field_groups.size() && info.field_groups[group].first == k;
      const std::string fields =
          first ? std::to_string(info.field_groups[group].bytes) + " (" + std::to_string(info.field_groups[group].count) + ")" : "";
      group += first;
      std::printf("  %3zu %8.3f %17s %10llu\n", k, times[k], fields.c_str(), static_cast<unsigned long long>(info.keyframes[k].texture));
    }
  }
  std::printf("chunks      type  count      bytes  (decompressed)\n");
  for (const auto& c : info.chunks) {
    std::printf("            %s %6d %10llu  (%llu%s)\n", c.type.c_str(), c.count, static_cast<unsigned long long>(c.stored_bytes),
                static_cast<unsigned long long>(c.raw_bytes), c.against_dictionary > 0 ? "; against the header dictionary" : "");
  }
  if (!settings.problem.empty()) {
    std::printf("settings    left out: %s\n", settings.problem.c_str());
  } else if (!info.metadata.settings.empty()) {
    std::printf("settings    %s\n", info.metadata.settings.c_str());
  }
  print_encoder_notes(settings.value);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  tools::reuse_freed_memory();
  CLI::App app("Describe a capture (validating every frame as the encoder will) or a facemorph file.", "fminfo");
  std::string input, landmarks, prepared;
  double fps = 0;
  bool json_out = false, quiet = false, verify = false, field_bytes = false;
  app.add_option("input", input, "A .fmv file, a capture folder, capture.json, or a plain folder of meshes (with --fps)")->required();
  app.add_option("--fps", fps, "Frame rate for a plain folder of meshes");
  app.add_option("--landmarks", landmarks, "Landmarks CSV for a plain folder (frame,name,x,y,z)");
  app.add_option("--prepared", prepared, "Write each validated, hole-filled frame into this folder");
  app.add_flag("--json", json_out, "Print JSON");
  app.add_flag("--verify", verify,
               "For a .fmv file: decode every keyframe once (as a player would), not only verify the checksums, and give each keyframe its "
               "fields' bytes");
  app.add_flag("--field-bytes", field_bytes,
               "For a .fmv file: where the fields' bytes go, array by array (H, log lambda, a, b, band, positions, rim, hole level; "
               "the writer's own cost estimate); decodes every keyframe once, one at a time, as --verify does");
  app.add_flag("-q,--quiet", quiet, "No progress display");
  DecoderLimits limits;
  std::string max_memory;
  tools::add_limit_options(app, limits, max_memory);
  return tools::guarded_main(app, argc, argv, [&] {
    if (is_container(input)) return describe_container(input, json_out, verify, field_bytes, tools::parsed_limits(limits, max_memory));
    const Capture capture = open_capture(input, fps, landmarks);
    std::error_code ec;
    if (!prepared.empty()) fs::create_directories(prepared, ec);
    return describe_capture(capture, json_out, quiet, prepared);
  });
}
