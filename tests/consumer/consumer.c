/* A C player's program: decode one time of a .fmv file through the C API and check what comes back,
 * field by field, against what the header it was compiled with says. Built against the installed
 * package (run_consumer_test.sh: CMake and pkg-config, shared and static) and against the saved API
 * 1.0 header (tests/consumer/api-1.0/facemorph.h) linked to the freshly built shared library
 * (Api.Header1_0ProgramRunsOnThisLibrary): a struct field moved or an enum value renumbered makes it
 * fail. Prints "t = T s: V vertices, F triangles". Usage: consumer FILE.fmv [T] */
#include <facemorph.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;
#define EXPECT(condition)                                                       \
  do {                                                                          \
    if (!(condition)) {                                                         \
      fprintf(stderr, "consumer: %s:%d: %s\n", __FILE__, __LINE__, #condition); \
      ++failures;                                                               \
    }                                                                           \
  } while (0)

int main(int argc, char** argv) {
  if (argc < 2) return fprintf(stderr, "usage: consumer FILE.fmv [T]\n"), 2;
  const double t = argc > 2 ? atof(argv[2]) : 0.2;
  fm_file* file = NULL;
  fm_decoder* decoder = NULL;
  fm_info info;
  fm_frame frame;
  size_t keyframes = 0;
  float* positions = NULL;
  float* normals = NULL;
  float* uvs = NULL;
  uint32_t* indices = NULL;
  uint8_t* texture = NULL;

  /* The statuses' values and names are the header's. */
  EXPECT(fm_file_open("/nonexistent/facemorph.fmv", &file) == FM_ERROR_IO && file == NULL);
  EXPECT(strlen(fm_last_error_message()) > 0);
  EXPECT(strcmp(fm_status_name(FM_ERROR_BUFFER_TOO_SMALL), "buffer-too-small") == 0);
  EXPECT(strcmp(fm_status_name(FM_ERROR_CLOSED_HANDLE), "closed-handle") == 0);
  EXPECT(fm_version_number() > 0 && strlen(fm_version()) >= 5); /* the library's, not the header's */

  fm_status status = fm_file_open(argv[1], &file);
  if (status == FM_OK) {
    fm_info_init(&info);
    status = fm_file_get_info(file, &info);
  }
  if (status == FM_OK) status = fm_file_get_keyframe_times(file, NULL, 0, &keyframes); /* the count alone */
  if (status == FM_OK) status = fm_decoder_create(file, &decoder);
  if (status == FM_OK) {
    EXPECT(keyframes == info.keyframe_count && keyframes > 0);
    EXPECT(info.fps > 0 && info.first_time <= info.last_time && fabs(info.duration - (info.last_time - info.first_time)) < 1e-9);
    EXPECT(info.range_begin <= info.first_time && info.range_end >= info.last_time);
    EXPECT(info.grid_n >= 5 && info.grid_vertex_count > 0 && info.max_vertex_count >= info.grid_vertex_count);
    EXPECT(info.max_triangle_count >= info.grid_triangle_count && info.has_holes <= 1);
    EXPECT(strcmp(info.units, "m") == 0 || strcmp(info.units, "cm") == 0 || strcmp(info.units, "mm") == 0);
    {
      const size_t v = info.max_vertex_count, f = info.max_triangle_count, m = info.texture_size;
      size_t i;
      positions = malloc(3 * sizeof(float) * v);
      normals = malloc(3 * sizeof(float) * v);
      uvs = malloc(2 * sizeof(float) * v);
      indices = malloc(3 * sizeof(uint32_t) * f);
      texture = malloc(4 * m * m + 1);
      if (!positions || !normals || !uvs || !indices || !texture) return fprintf(stderr, "consumer: out of memory\n"), 1;
      for (i = 0; i < 3 * v; ++i) positions[i] = normals[i] = NAN;
      for (i = 0; i < 2 * v; ++i) uvs[i] = NAN;
      memset(indices, 0xff, 3 * sizeof(uint32_t) * f);

      /* A buffer too small: nothing written, the counts say what is needed. */
      fm_frame_init(&frame);
      frame.positions = positions;
      frame.positions_bytes = 4;
      EXPECT(fm_decoder_decode(decoder, t, 0, &frame) == FM_ERROR_BUFFER_TOO_SMALL);
      EXPECT(frame.vertex_count > 0 && frame.vertex_count <= info.max_vertex_count && isnan(positions[0]));

      fm_frame_init(&frame);
      frame.positions = positions, frame.positions_bytes = 3 * sizeof(float) * v;
      frame.normals = normals, frame.normals_bytes = 3 * sizeof(float) * v;
      frame.uvs = uvs, frame.uvs_bytes = 2 * sizeof(float) * v;
      frame.indices = indices, frame.indices_bytes = 3 * sizeof(uint32_t) * f;
      frame.texture = m > 0 ? texture : NULL, frame.texture_bytes = 4 * m * m;
      status = fm_decoder_decode(decoder, t, 0, &frame);
    }
  }
  if (status == FM_OK) {
    size_t i;
    EXPECT(frame.time == t && frame.texture_size == info.texture_size && frame.fell_back <= 1);
    EXPECT(frame.vertex_count > 0 && frame.vertex_count <= info.max_vertex_count);
    EXPECT(frame.triangle_count > 0 && frame.triangle_count <= info.max_triangle_count);
    for (i = 0; i < 3 * (size_t)frame.vertex_count; ++i) EXPECT(isfinite(positions[i]));
    for (i = 0; i < (size_t)frame.vertex_count; ++i) {
      const float* n = normals + 3 * i;
      const double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      EXPECT(fabs(length - 1) < 1e-3 || length == 0);
      EXPECT(uvs[2 * i] >= 0 && uvs[2 * i] <= 1 && uvs[2 * i + 1] >= 0 && uvs[2 * i + 1] <= 1);
    }
    for (i = 0; i < 3 * (size_t)frame.triangle_count; ++i) EXPECT(indices[i] < frame.vertex_count);
    if (frame.texture_size > 0) EXPECT(texture[3] == 255 && texture[4 * (size_t)frame.texture_size * frame.texture_size - 1] == 255);
    if (failures == 0) {
      printf("facemorph %s: t = %.3f s: %u vertices, %u triangles\n", fm_version(), frame.time, frame.vertex_count, frame.triangle_count);
    }
  }
  if (status != FM_OK) fprintf(stderr, "consumer: %s: %s\n", fm_status_name(status), fm_last_error_message());
  free(positions);
  free(normals);
  free(uvs);
  free(indices);
  free(texture);
  fm_decoder_destroy(decoder);
  fm_file_close(file);
  /* A closed handle is a named error. */
  if (file != NULL) EXPECT(fm_file_release(file) == FM_ERROR_CLOSED_HANDLE);
  return status == FM_OK && failures == 0 ? 0 : 1;
}
