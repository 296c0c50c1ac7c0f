/* A player's first program: decode one time of a .fmv file through the installed C API and print
 * the vertex count. Built against the installed package by run_consumer_test.sh (CMake and
 * pkg-config). Usage: consumer FILE.fmv [T] */
#include <facemorph.h>

#include <stdio.h>
#include <stdlib.h>

int main(int argc, char** argv) {
  if (argc < 2) return fprintf(stderr, "usage: consumer FILE.fmv [T]\n"), 2;
  const double t = argc > 2 ? atof(argv[2]) : 0.2;
  fm_file* file = NULL;
  fm_decoder* decoder = NULL;
  fm_info info;
  fm_status status = fm_file_open(argv[1], &file);
  if (status == FM_OK) status = fm_file_get_info(file, &info);
  if (status == FM_OK) status = fm_decoder_create(file, &decoder);
  if (status == FM_OK) {
    fm_frame frame = {0};
    frame.positions_bytes = 3 * sizeof(float) * info.max_vertex_count;
    frame.positions = malloc(frame.positions_bytes);
    status = frame.positions ? fm_decoder_decode(decoder, t, 0, &frame) : FM_ERROR_OUT_OF_MEMORY;
    if (status == FM_OK) printf("facemorph %s: t = %.3f s: %u vertices, %u triangles\n", fm_version(), frame.time, frame.vertex_count, frame.triangle_count);
    free(frame.positions);
  }
  if (status != FM_OK) fprintf(stderr, "consumer: %s: %s\n", fm_status_name(status), fm_last_error_message());
  fm_decoder_destroy(decoder);
  fm_file_close(file);
  return status == FM_OK ? 0 : 1;
}
