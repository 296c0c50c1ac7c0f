// fminfo: describes a facemorph input or output. For a capture (a folder with capture.json, or a
// plain folder of meshes with --fps) it reads, validates and repairs every frame the way the
// encoder will, and prints a summary (or JSON).
#include "facemorph/encoder/capture.hpp"
#include "facemorph/encoder/frame.hpp"
#include "facemorph/mesh_io.hpp"
#include "facemorph/parallel.hpp"

#include "tools/tool_support.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>

namespace {

using namespace facemorph;
namespace fs = std::filesystem;

struct FrameSummary {
  int vertices = 0, faces = 0, prepared_vertices = 0, prepared_faces = 0;
  std::string report;
  std::vector<FilledHole> holes;
  bool has_uvs = false, has_texture = false;
};

std::vector<Vec3> rim_markers(const Capture& capture, size_t frame) {
  std::vector<Vec3> markers;
  for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
    if (capture.landmark_names[l].rfind("rim_", 0) == 0 && frame < capture.landmarks.size() &&
        capture.landmarks[frame][l].allFinite()) {
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
      per_frame.push_back({{"mesh", capture.frames[i].mesh.generic_string()}, {"time", capture.frames[i].time},
                           {"vertices", frames[i].vertices}, {"faces", frames[i].faces},
                           {"prepared_vertices", frames[i].prepared_vertices}, {"prepared_faces", frames[i].prepared_faces},
                           {"holes", frames[i].holes.size()}, {"report", frames[i].report}});
    }
    doc["per_frame"] = std::move(per_frame);
    std::printf("%s\n", doc.dump(1).c_str());
    return 0;
  }
  std::printf("capture     %s\n", capture.root.string().c_str());
  if (!capture.description.empty()) std::printf("            %s\n", capture.description.c_str());
  std::printf("frames      %zu at %.3f fps, %.3f s, units %s\n", count, capture.fps, capture.duration(), capture.units.c_str());
  std::printf("vertices    %d .. %d per frame\n", vmin->vertices, vmax->vertices);
  std::printf("texture     %s\n", frames[0].has_texture ? "per-frame image with UVs" : frames[0].has_uvs ? "UVs, no image" : "none");
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Describe a capture (validating every frame as the encoder will) or a facemorph file.", "fminfo");
  std::string input, landmarks, prepared;
  double fps = 0;
  bool json_out = false, quiet = false;
  app.add_option("input", input, "Capture folder, capture.json, or a plain folder of meshes (with --fps)")->required();
  app.add_option("--fps", fps, "Frame rate for a plain folder of meshes");
  app.add_option("--landmarks", landmarks, "Landmarks CSV for a plain folder (frame,name,x,y,z)");
  app.add_option("--prepared", prepared, "Write each validated, hole-filled frame into this folder");
  app.add_flag("--json", json_out, "Print JSON");
  app.add_flag("-q,--quiet", quiet, "No progress display");
  return tools::guarded_main(app, argc, argv, [&] {
    std::error_code ec;
    const fs::path path(input);
    const bool manifest = fs::is_regular_file(path, ec) || fs::exists(path / "capture.json", ec);
    if (!manifest && fps <= 0) {
      throw Error(ErrorCode::kInvalidArgument, input + ": no capture.json here; give --fps to read it as a plain folder of meshes");
    }
    const Capture capture = manifest ? read_capture(path) : scan_capture_folder(path, fps, landmarks);
    if (!prepared.empty()) fs::create_directories(prepared, ec);
    return describe_capture(capture, json_out, quiet, prepared);
  });
}
