// A C++ player's program: the same decode as consumer.c through the header-only C++ API
// (facemorph/decoder.hpp), built as C++17 and as C++20 against the installed package. Prints
// "t = T s: V vertices, F triangles". Usage: consumer_cxx FILE.fmv [T]
#include <facemorph/decoder.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  if (argc < 2) return std::fprintf(stderr, "usage: consumer_cxx FILE.fmv [T]\n"), 2;
  const double t = argc > 2 ? std::atof(argv[2]) : 0.2;
  try {
    try {
      fm::File::open("/nonexistent/facemorph.fmv");
      std::fprintf(stderr, "consumer_cxx: a missing file opened\n");
      return 1;
    } catch (const fm::Error& e) {
      if (e.status() != FM_ERROR_IO || std::string(e.what()).rfind("io: ", 0) != 0) throw;
    }
    fm_decoder_options options = fm::default_options();
    options.max_memory_bytes = 256u << 20;
    const fm::File file = fm::File::open(argv[1], options);
    const fm_info info = file.info();
    if (file.keyframe_times().size() != info.keyframe_count) return std::fprintf(stderr, "consumer_cxx: keyframe count\n"), 1;
    fm::Decoder decoder(file);
    fm::Frame frame;
    decoder.decode(t, frame);
    const bool sizes = frame.positions.size() == 3 * size_t{frame.vertex_count} && frame.normals.size() == frame.positions.size() &&
                       frame.uvs.size() == 2 * size_t{frame.vertex_count} && frame.indices.size() == 3 * size_t{frame.triangle_count} &&
                       frame.texture.size() == 4 * size_t{frame.texture_size} * frame.texture_size;
    bool finite = true;
    for (float x : frame.positions) finite = finite && std::isfinite(x);
    if (!sizes || !finite || frame.vertex_count > info.max_vertex_count) return std::fprintf(stderr, "consumer_cxx: a wrong frame\n"), 1;
    // Only what is asked for; the arrays are reused.
    decoder.decode(t, frame, fm::kPositions | fm::kIndices);
    if (!frame.normals.empty() || frame.positions.size() != 3 * size_t{frame.vertex_count})
      return std::fprintf(stderr, "consumer_cxx: outputs\n"), 1;
    std::printf("facemorph %s (C++ %ld): t = %.3f s: %u vertices, %u triangles\n", fm_version(), static_cast<long>(__cplusplus), frame.time,
                frame.vertex_count, frame.triangle_count);
    return 0;
  } catch (const fm::Error& e) {
    std::fprintf(stderr, "consumer_cxx: %s\n", e.what());
    return 1;
  }
}
