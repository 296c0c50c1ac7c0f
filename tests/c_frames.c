/* A player of the C API alone (facemorph.h), as any other, for the tests that compare another
 * decoder with the native one: the Python package's tests and benchmark (tests/python,
 * python/bench/bench_decode.py) and the WebAssembly exactness test (tests/web/exactness.sh). Each
 * decodes FILE at COUNT times spread over its whole range, extrapolation included:
 * t_i = begin + (end - begin) * i / (COUNT - 1), the times the other side decodes too.
 *
 *   c_frames FILE COUNT OUT       every output; each frame written to OUT as t (float64), the
 *                                 vertex, triangle and texture counts (uint32 × 3), positions,
 *                                 normals (float32 × 3 a vertex), UVs (float32 × 2), indices
 *                                 (uint32 × 3 a triangle), texture (RGBA8, M × M)
 *   c_frames FILE COUNT - PASSES  the same decodes PASSES times over, writing nothing; prints the
 *                                 mean time a frame of each pass (ms) on stdout
 *   c_frames --web FILE COUNT OUT what the browser's page asks for (positions, normals, UVs,
 *                                 indices; no texture), each frame written as web/test/exactness.mjs
 *                                 writes it: t (float64), the vertex count (uint32), the positions
 *                                 (float32 × 3 a vertex); the mean decode time a frame on stderr
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime in C99 */
#include <facemorph.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return 1e3 * (double)t.tv_sec + 1e-6 * (double)t.tv_nsec;
}

/* One frame's record: the whole frame, or the web test's (t, vertex count, positions). */
static void write_frame(FILE* out, int web, double t, const fm_frame* frame) {
  fwrite(&t, sizeof t, 1, out);
  if (web) {
    fwrite(&frame->vertex_count, sizeof frame->vertex_count, 1, out);
    fwrite(frame->positions, sizeof(float), 3 * (size_t)frame->vertex_count, out);
    return;
  }
  const uint32_t counts[3] = {frame->vertex_count, frame->triangle_count, frame->texture_size};
  fwrite(counts, sizeof counts, 1, out);
  fwrite(frame->positions, sizeof(float), 3 * (size_t)frame->vertex_count, out);
  fwrite(frame->normals, sizeof(float), 3 * (size_t)frame->vertex_count, out);
  fwrite(frame->uvs, sizeof(float), 2 * (size_t)frame->vertex_count, out);
  fwrite(frame->indices, sizeof(uint32_t), 3 * (size_t)frame->triangle_count, out);
  fwrite(frame->texture, 1, 4 * (size_t)frame->texture_size * frame->texture_size, out);
}

int main(int argc, char** argv) {
  const int web = argc > 1 && strcmp(argv[1], "--web") == 0;
  argv += web;
  argc -= web;
  if (argc < 4 || argc > 5 || (web && argc != 4)) {
    fprintf(stderr, "usage: c_frames FILE COUNT OUT | c_frames FILE COUNT - PASSES | c_frames --web FILE COUNT OUT\n");
    return 2;
  }
  const int count = atoi(argv[2]);
  const int timing = strcmp(argv[3], "-") == 0;
  const int passes = timing && argc == 5 ? atoi(argv[4]) : 1;
  if (count < 2 || passes < 1) {
    fprintf(stderr, "c_frames: COUNT must be at least 2, PASSES at least 1\n");
    return 2;
  }
  fm_file* file = NULL;
  fm_decoder* decoder = NULL;
  fm_info info;
  fm_info_init(&info);
  fm_status status = fm_file_open(argv[1], &file);
  if (status == FM_OK) status = fm_file_get_info(file, &info);
  if (status == FM_OK) status = fm_decoder_create(file, &decoder);
  FILE* out = NULL;
  if (status == FM_OK && !timing && !(out = fopen(argv[3], "wb"))) {
    fprintf(stderr, "c_frames: cannot write %s\n", argv[3]);
    return 1;
  }
  const size_t vertices = info.max_vertex_count, triangles = info.max_triangle_count;
  const size_t texels = web ? 0 : (size_t)info.texture_size * info.texture_size;
  float* positions = malloc(3 * sizeof(float) * vertices + 1);
  float* normals = malloc(3 * sizeof(float) * vertices + 1);
  float* uvs = malloc(2 * sizeof(float) * vertices + 1);
  uint32_t* indices = malloc(3 * sizeof(uint32_t) * triangles + 1);
  uint8_t* texture = malloc(4 * texels + 1);
  double total_ms = 0;
  for (int pass = 0; status == FM_OK && pass < passes; ++pass) {
    total_ms = 0;
    for (int i = 0; status == FM_OK && i < count; ++i) {
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
      if (texels > 0) {
        frame.texture = texture;
        frame.texture_bytes = 4 * texels;
      }
      const double start = now_ms();
      status = fm_decoder_decode(decoder, t, 0, &frame);
      total_ms += now_ms() - start;
      if (status == FM_OK && !timing) write_frame(out, web, t, &frame);
    }
    if (status == FM_OK && timing) printf("%.4f\n", total_ms / count);
  }
  if (status != FM_OK) {
    fprintf(stderr, "c_frames: %s: %s\n", fm_status_name(status), fm_last_error_message());
  } else if (web) {
    fprintf(stderr, "c_frames: N = %u: native decode %.2f ms a frame (mean of %d, the first included)\n", info.grid_n, total_ms / count,
            count);
  }
  free(positions);
  free(normals);
  free(uvs);
  free(indices);
  free(texture);
  if (out && fclose(out) != 0) {
    fprintf(stderr, "c_frames: cannot write %s\n", argv[3]);
    status = FM_ERROR_IO;
  }
  fm_decoder_destroy(decoder);
  fm_file_close(file);
  return status == FM_OK ? 0 : 1;
}
