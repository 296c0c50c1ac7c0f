// fmsynth: writes a synthetic face capture (spec/capture.md), facemorph's own sample and test data.
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"

#include "tools/tool_support.hpp"

#include <cstdio>

int main(int argc, char** argv) {
  using namespace facemorph;
  CLI::App app("Write a synthetic 4D face capture (capture.json, OBJ+MTL+JPEG per frame, landmarks.csv).", "fmsynth");
  SynthOptions options;
  std::string out, expression = "mixed";
  std::vector<double> truth_times;
  int truth_vertices = 50000;
  bool quiet = false;
  app.add_option("-o,--out", out, "Output folder (created)")->required();
  app.add_option("--frames", options.frames, "Number of frames")->capture_default_str()->check(CLI::Range(1, 100000));
  app.add_option("--fps", options.fps, "Frames per second")->capture_default_str()->check(CLI::Range(0.1, 1000.0));
  app.add_option("--expression", expression, "blink | mouth | smile | talk | mixed")->capture_default_str();
  app.add_option("--vertices", options.vertices, "Vertices per frame (target)")->capture_default_str();
  app.add_flag("--remesh", options.remesh, "Give every frame its own sampling and connectivity, like a raw scanner");
  app.add_option("--noise", options.noise, "Scanner noise along the normal, metres (standard deviation)")->capture_default_str();
  app.add_option("--seed", options.seed, "Face identity, texture detail, noise and remeshing seed")->capture_default_str();
  app.add_option("--texture-size", options.texture_size, "Texture pixels per side")->capture_default_str();
  app.add_flag("--shared-texture", options.shared_texture,
               "One texture image (texture.jpg) for every frame, as a rig that paints one atlas for the take: only the geometry moves");
  app.add_flag("--vertex-colour", options.vertex_colour,
               "Colour per vertex instead of a texture: binary PLY frames with red/green/blue, no UVs or image (a depth camera's capture)");
  app.add_option("--head-motion", options.head_motion_degrees, "Amplitude of a slow rigid head rotation, degrees")->capture_default_str();
  app.add_option("--speech-rate", options.speech_rate, "Mouth speed in talk and mixed, times the normal pace (fast speech: 2-3)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 100.0));
  app.add_option("--truth-at", truth_times, "Also write the exact noise-free surface at these times as truth_T.obj");
  app.add_option("--truth-vertices", truth_vertices, "Vertices of the truth meshes")->capture_default_str();
  std::string defects;
  app.add_option("--defects", defects,
                 "Write what scanners write into every frame, for the encoder's repairs: all, or a comma-separated list of bow-ties, "
                 "three-face-edges, duplicates, degenerate, flipped, islands, torso (spec/capture.md)");
  app.add_flag("--holes", options.holes,
               "Leave the eyes, mouth and nostrils open, as scanners do (holes the encoder fills and cuts back out)");
  app.add_flag(
      "--head", options.whole_head,
      "The whole head: the face closed round the back of the head down to a neck, whose rim is the outer boundary (rim_* markers on it); "
      "not with --remesh, --defects or --vertex-colour");
  app.add_flag(
      "--surround", options.surround,
      "A head-and-shoulders scan: hair heaped on one side and a shoulder forward on the other round the face, textured (face, hair, "
      "shirt), 0.44 x 0.54 m, no rim markers; not with --remesh, --defects, --holes, --head, --vertex-colour or --shared-texture");
  app.add_flag("--no-face", options.no_face,
               "With --surround: a plain dome and bare skin where the face was, and no landmarks: a scan with no face, which fmenc "
               "--landmarks auto refuses by name");
  app.add_flag("-q,--quiet", quiet, "No progress display");

  return tools::guarded_main(app, argc, argv, [&] {
    options.expression = parse_expression(expression);
    if (!defects.empty()) options.defects = parse_defects(defects);
    const auto start = std::chrono::steady_clock::now();
    tools::Progress progress("fmsynth", quiet);
    write_synthetic_capture(out, options, [&](int done, int total) { progress.update(done, total); });
    progress.finish();
    const SyntheticFace face(options.expression, options.seed, options.head_motion_degrees, options.speech_rate);
    for (double t : truth_times) {
      char name[64];
      std::snprintf(name, sizeof name, "truth_%.4f.obj", t);
      TriangleMesh truth = face.truth_mesh(t, truth_vertices);
      write_mesh(std::filesystem::path(out) / name, truth, {.write_material = false});
    }
    if (!quiet) {
      std::printf("fmsynth: wrote %d frames (%s, %s%d vertices) to %s in %.2f s\n", options.frames, expression.c_str(),
                  options.remesh ? "remeshed, about " : "", options.vertices, out.c_str(), tools::seconds_since(start));
    }
    return 0;
  });
}
