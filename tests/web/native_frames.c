/* The native side of the WebAssembly exactness test (tests/web/exactness.sh): decodes FILE at COUNT
 * times spread over its whole range (extrapolation included) through the C API, and writes for each
 * time t (float64), the vertex count (uint32) and the positions (float32 × 3 per vertex) to OUT, the
 * same record web/test/exactness.mjs makes with the WebAssembly module. C, against facemorph.h alone:
 * the same calls the browser's decoder makes. It asks for what the page asks for (positions,
 * normals, UVs, indices; no texture) and prints the mean decode time a frame on stderr. */
#define _POSIX_C_SOURCE 199309L /* clock_gettime in C99 */
#include <facemorph.h>

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e3 * (double)t.tv_sec + 1e-6 * (double)t.tv_nsec;
}

int main(int argc, char** argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: native_frames FILE.fmv COUNT OUT\n");
    return 2;
  }
  const int count = atoi(argv[2]);
  fm_file* file = NULL;
  fm_decoder* decoder = NULL;
  fm_info info;
  fm_info_init(&info);
  fm_status status = fm_file_open(argv[1], &file);
  if (status == FM_OK) status = fm_file_get_info(file, &info);
  if (status == FM_OK) status = fm_decoder_create(file, &decoder);
  FILE* out = status == FM_OK ? fopen(argv[3], "wb") : NULL;
  if (status == FM_OK && !out) {
    fprintf(stderr, "native_frames: cannot write %s\n", argv[3]);
    return 1;
  }
  const size_t vertices = (size_t)info.max_vertex_count + 1, triangles = (size_t)info.max_triangle_count + 1;
  float* positions = malloc(3 * sizeof(float) * vertices);
  float* normals = malloc(3 * sizeof(float) * vertices);
  float* uvs = malloc(2 * sizeof(float) * vertices);
  uint32_t* indices = malloc(3 * sizeof(uint32_t) * triangles);
  double total_ms = 0;
  for (int i = 0; status == FM_OK && i < count; ++i) {
    /* The same times as the JavaScript side: begin + (end - begin) * i / (count - 1). */
    const double t = info.range_begin + (info.range_end - info.range_begin) * i / (count - 1);
    fm_frame frame;
    fm_frame_init(&frame);
    frame.positions = positions;
    frame.positions_bytes = 3 * sizeof(float) * vertices;
    frame.normals = normals;
    frame.normals_bytes = 3 * sizeof(float) * vertices;
    frame.uvs = uvs;
    frame.uvs_bytes = 2 * sizeof(float) * vertices;
    frame.indices = indices;
    frame.indices_bytes = 3 * sizeof(uint32_t) * triangles;
    const double start = now_ms();
    status = fm_decoder_decode(decoder, t, 0, &frame);
    total_ms += now_ms() - start;
    if (status != FM_OK) break;
    fwrite(&t, sizeof t, 1, out);
    fwrite(&frame.vertex_count, sizeof frame.vertex_count, 1, out);
    fwrite(positions, sizeof(float), 3 * (size_t)frame.vertex_count, out);
  }
  if (status != FM_OK)
    fprintf(stderr, "native_frames: %s: %s\n", fm_status_name(status), fm_last_error_message());
  else
    fprintf(stderr, "native_frames: N = %u: native decode %.2f ms a frame (mean of %d, the first included)\n", info.grid_n,
            total_ms / count, count);
  free(positions);
  free(normals);
  free(uvs);
  free(indices);
  if (out) fclose(out);
  fm_decoder_destroy(decoder);
  fm_file_close(file);
  return status == FM_OK ? 0 : 1;
}
