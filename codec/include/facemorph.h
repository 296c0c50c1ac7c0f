/* facemorph.h: the C API of the facemorph decoder, for players in any language.
 *
 * Open a .fmv file (fm_file_open, fm_file_open_memory), ask what it holds (fm_file_get_info), make
 * a decoder on it (fm_decoder_create) and decode any time t into buffers the caller owns
 * (fm_decoder_decode): positions, normals and UVs per vertex, triangle indices, an RGBA8 texture.
 *
 *   fm_file* file; fm_decoder* decoder; fm_info info;
 *   if (fm_file_open("face.fmv", &file) != FM_OK) { fprintf(stderr, "%s\n", fm_last_error_message()); ... }
 *   fm_file_get_info(file, &info);
 *   fm_decoder_create(file, &decoder);
 *   float* positions = malloc(3 * sizeof(float) * info.max_vertex_count);
 *   fm_frame frame = {0};
 *   frame.positions = positions; frame.positions_bytes = 3 * sizeof(float) * info.max_vertex_count;
 *   if (fm_decoder_decode(decoder, 1.45, 0, &frame) == FM_OK) printf("%u vertices\n", frame.vertex_count);
 *   fm_decoder_destroy(decoder); fm_file_close(file); free(positions);
 *
 * Status: every function that can fail returns an fm_status. Its values mirror facemorph::ErrorCode
 * (facemorph/error.hpp), never change meaning and are never renumbered; new ones are appended.
 * fm_status_name gives a short stable name, fm_last_error_message the full message (naming the
 * file, chunk and reason) of the last failed call on the calling thread.
 *
 * Threads: an fm_file is immutable once opened; any number of threads may create decoders on it at
 * once. An fm_decoder is used by one thread at a time; decoders on one file may decode on
 * different threads at once. A file may be closed while its decoders live (they share it).
 *
 * Conventions (spec/container.md §8, spec/method.md §7): positions in the capture's frame and units
 * (fm_info.units), normals unit and area-weighted, pointing to the side from which the triangles
 * wind counter-clockwise; UV = (w + 1) / 2 of the vertex's point w of the unit disk, v up (OBJ,
 * OpenGL) unless FM_DECODE_FLIP_V; texture M x M texels of 4 bytes (R, G, B, 255), row 0 at the top
 * (v = 1), rows packed.
 */
#ifndef FACEMORPH_H
#define FACEMORPH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FACEMORPH_VERSION_MAJOR 0
#define FACEMORPH_VERSION_MINOR 8
#define FACEMORPH_VERSION_PATCH 0
/* major * 10000 + minor * 100 + patch, as fm_version_number returns it. */
#define FACEMORPH_VERSION_NUMBER (FACEMORPH_VERSION_MAJOR * 10000 + FACEMORPH_VERSION_MINOR * 100 + FACEMORPH_VERSION_PATCH)

typedef enum fm_status {
  FM_OK = 0,
  FM_ERROR_IO = 1,               /* a file could not be opened or read */
  FM_ERROR_PARSE = 2,            /* text or structure that does not follow its grammar */
  FM_ERROR_TRUNCATED = 3,        /* the input ends before the data it announces */
  FM_ERROR_CORRUPT = 4,          /* bytes present but wrong (checksum, impossible value, a file that decodes to non-finite numbers) */
  FM_ERROR_UNSUPPORTED = 5,      /* a valid file using a feature this decoder does not implement */
  FM_ERROR_INVALID_MESH = 6,
  FM_ERROR_NOT_A_DISK = 7,
  FM_ERROR_MISSING_TEXTURE = 8,
  FM_ERROR_INVALID_ARGUMENT = 9, /* the caller's fault, never the file's: a NULL or wrong handle or pointer, t not finite, a bad option */
  FM_ERROR_NUMERICAL = 10,       /* the reconstruction failed numerically (a non-finite iterate: a corrupt file) */
  FM_ERROR_NOT_CONVERGED = 11,
  FM_ERROR_OUT_OF_RANGE = 12,    /* t outside [range_begin, range_end] without FM_DECODE_CLAMP */
  FM_ERROR_BUFFER_TOO_SMALL = 13,/* an output buffer too small: the frame's counts say what is needed */
  FM_ERROR_OUT_OF_MEMORY = 14,
  FM_ERROR_INTERNAL = 15,        /* a bug in facemorph: please report it with the message */
  FM_ERROR_LIMIT = 16,           /* the file needs more than the decoder's limits allow (fm_decoder_options): refused before allocating */
  FM_ERROR_CLOSED_HANDLE = 17,   /* a handle used after fm_file_close / fm_decoder_destroy, or closed twice */
  /* Never returned: gives fm_status the range of a 32-bit int in C and C++ alike, so that any
   * non-negative int a caller passes to fm_status_name is a valid value. */
  FM_STATUS_FORCE_32BIT = 0x7fffffff
} fm_status;

/* Short stable name of a status ("ok", "truncated", "buffer-too-small", ...); "unknown" for
 * another value. Never NULL; a static string. */
const char* fm_status_name(fm_status status);

/* The message of the last call on this thread that did not return FM_OK (every failing call sets
 * it; a call that succeeds sets it to ""). Valid until the next facemorph call on this thread.
 * Never NULL. */
const char* fm_last_error_message(void);

/* "0.8.0": the library's version, which may differ from the header's FACEMORPH_VERSION_*. */
const char* fm_version(void);
uint32_t fm_version_number(void);

/* An opened .fmv file: every chunk read, checked and decoded.
 *
 * Handles are not pointers to memory: they name an entry of a table with a generation count, so a
 * handle used after it was closed (or closed twice) is FM_ERROR_CLOSED_HANDLE and never reads freed
 * memory, and closing a stale handle never closes the live handle that reuses its entry. */
typedef struct fm_file fm_file;
/* The state that decodes one file's frames. */
typedef struct fm_decoder fm_decoder;

/* What a decoder may spend on a file it did not write (spec/container.md §10). Set struct_size to
 * sizeof(fm_decoder_options) and call fm_decoder_options_init first: fields appended by later
 * versions then keep their defaults. A file that would exceed a limit is refused with
 * FM_ERROR_LIMIT, before the memory is allocated. */
typedef struct fm_decoder_options {
  size_t struct_size;          /* sizeof(fm_decoder_options) as the caller compiled it */
  uint32_t max_grid_n;         /* largest grid N (default 1025; the format allows 4097) */
  uint32_t max_keyframes;      /* most keyframes (default 65536) */
  uint32_t max_texture_size;   /* largest texture M, texels per side (default 4096; the format allows 16384) */
  uint64_t max_memory_bytes;   /* what an opened file and one decoder on it may hold (default 512 MiB) */
} fm_decoder_options;

/* Sets every field to its default, struct_size to sizeof(fm_decoder_options). NULL is ignored. */
void fm_decoder_options_init(fm_decoder_options* options);

/* Opens a file under the default limits: its header and index read, every keyframe's fields decoded
 * once and checked, every checksum verified; keyframes and textures are then decoded again when a
 * frame needs them, into a cache bounded by max_memory_bytes (spec/container.md §10.1). Returns FM_OK, FM_ERROR_INVALID_ARGUMENT
 * (NULL path or file), FM_ERROR_IO, FM_ERROR_TRUNCATED, FM_ERROR_CORRUPT, FM_ERROR_UNSUPPORTED,
 * FM_ERROR_LIMIT, FM_ERROR_OUT_OF_MEMORY. On success *file is a new handle for fm_file_close; on
 * failure *file is NULL. */
fm_status fm_file_open(const char* path, fm_file** file);
/* The same from `size` bytes at `data`. They are copied (the copy counts against max_memory_bytes):
 * the caller may free them at once. */
fm_status fm_file_open_memory(const void* data, size_t size, fm_file** file);
/* fm_file_open / fm_file_open_memory under the caller's limits (options NULL: the defaults).
 * FM_ERROR_INVALID_ARGUMENT also for options whose struct_size is 0 or whose limits cannot work
 * (max_grid_n below 5, max_keyframes or max_memory_bytes 0). */
fm_status fm_file_open_with_options(const char* path, const fm_decoder_options* options, fm_file** file);
fm_status fm_file_open_memory_with_options(const void* data, size_t size, const fm_decoder_options* options, fm_file** file);
/* Releases the handle; decoders created from it stay valid. NULL is ignored. A handle already
 * closed (or never opened) changes nothing; fm_last_error_message then says so. */
void fm_file_close(fm_file* file);
/* fm_file_close with a status: FM_OK, FM_ERROR_CLOSED_HANDLE (already closed), FM_ERROR_INVALID_ARGUMENT
 * (NULL, or not a file handle). */
fm_status fm_file_release(fm_file* file);

typedef struct fm_info {
  double fps;              /* the capture's nominal frame rate */
  double first_time;       /* the capture's first and last frame times, seconds */
  double last_time;
  double duration;         /* last_time - first_time */
  double range_begin;      /* the times fm_decoder_decode serves without FM_DECODE_CLAMP (+-infinity with one keyframe) */
  double range_end;
  uint32_t keyframe_count;
  uint32_t grid_n;         /* N of the disk grid */
  /* Buffers for these many vertices and triangles always suffice. Without holes (or with
   * FM_DECODE_KEEP_HOLES_FILLED) every frame has exactly the grid's counts and the same indices. */
  uint32_t max_vertex_count;
  uint32_t max_triangle_count;
  uint32_t grid_vertex_count;
  uint32_t grid_triangle_count;
  uint32_t has_holes;      /* 1: eyes and mouth are cut per frame, the counts change between frames */
  uint32_t texture_size;   /* M, texels per side; 0: the file has no texture */
  char units[8];           /* "m", "cm" or "mm", NUL-terminated */
} fm_info;

/* Fills *info. FM_OK, FM_ERROR_INVALID_ARGUMENT (a NULL or wrong handle, NULL info), FM_ERROR_CLOSED_HANDLE. */
fm_status fm_file_get_info(const fm_file* file, fm_info* info);
/* Copies the keyframe times (seconds) into times[0 .. capacity) and sets *count to the number of
 * keyframes; FM_ERROR_BUFFER_TOO_SMALL (copying nothing) when capacity < *count. times NULL with
 * capacity 0 asks the count only: FM_OK, no error message set. FM_OK, FM_ERROR_INVALID_ARGUMENT,
 * FM_ERROR_CLOSED_HANDLE, FM_ERROR_BUFFER_TOO_SMALL. */
fm_status fm_file_get_keyframe_times(const fm_file* file, double* times, size_t capacity, size_t* count);

/* A decoder on the file (which it shares: the file handle may be closed afterwards), under the
 * limits the file was opened with. FM_OK, FM_ERROR_INVALID_ARGUMENT, FM_ERROR_CLOSED_HANDLE,
 * FM_ERROR_LIMIT, FM_ERROR_OUT_OF_MEMORY, FM_ERROR_INTERNAL. */
fm_status fm_decoder_create(const fm_file* file, fm_decoder** decoder);
/* NULL is ignored; a destroyed handle changes nothing (fm_last_error_message says so). */
void fm_decoder_destroy(fm_decoder* decoder);
/* fm_decoder_destroy with a status: FM_OK, FM_ERROR_CLOSED_HANDLE, FM_ERROR_INVALID_ARGUMENT. */
fm_status fm_decoder_release(fm_decoder* decoder);

/* Decode flags, or-ed; 0 is the default. */
#define FM_DECODE_CLAMP 1u              /* clamp t into [range_begin, range_end] instead of FM_ERROR_OUT_OF_RANGE */
#define FM_DECODE_KEEP_HOLES_FILLED 2u  /* keep the filled eyes and mouth: fixed topology */
#define FM_DECODE_FLIP_V 4u             /* UV v down (glTF, Direct3D): v -> 1 - v */

/* One frame: the caller's buffers in, the frame's description out. A NULL buffer is not wanted
 * (and not computed); a buffer that is not NULL must hold the whole array, its size given in
 * BYTES: 3 floats per vertex (positions, normals), 2 floats per vertex (uvs), 3 uint32 per triangle
 * (indices), 4 bytes per texel (texture). Zero-initialise the struct, then set what you want. */
typedef struct fm_frame {
  float* positions;
  size_t positions_bytes;
  float* normals;
  size_t normals_bytes;
  float* uvs;
  size_t uvs_bytes;
  uint32_t* indices;
  size_t indices_bytes;
  uint8_t* texture;
  size_t texture_bytes;
  /* Set by fm_decoder_decode on FM_OK and on FM_ERROR_BUFFER_TOO_SMALL (then they say what is
   * needed; nothing was written to any buffer). */
  double time;             /* the time decoded (t, or t clamped) */
  uint32_t vertex_count;
  uint32_t triangle_count;
  uint32_t texture_size;   /* M (0: no texture) */
  uint32_t iterations;     /* reconstruction steps */
  uint32_t fell_back;      /* 1: the reconstruction did not converge; the frame is the spline of the keyframes' surfaces */
} fm_frame;

/* Decodes the frame at time t (seconds from the capture's first frame) into the buffers of
 * *frame. Returns FM_OK (every number written is finite), FM_ERROR_INVALID_ARGUMENT (NULL or wrong
 * handle, NULL frame, t not finite, unknown flag: the caller's fault only), FM_ERROR_CLOSED_HANDLE,
 * FM_ERROR_OUT_OF_RANGE, FM_ERROR_BUFFER_TOO_SMALL, FM_ERROR_CORRUPT (the file decodes to
 * non-finite numbers, or a keyframe of it cannot be reconstructed: every later call that needs that
 * keyframe fails at once the same way; or a keyframe's texture, decoded when a frame first shows it,
 * does not decode), FM_ERROR_UNSUPPORTED (that texture is in an image codec this decoder does not
 * read), FM_ERROR_LIMIT (its chunk is larger than the memory budget), FM_ERROR_NUMERICAL, FM_ERROR_NOT_CONVERGED,
 * FM_ERROR_OUT_OF_MEMORY, FM_ERROR_INTERNAL. The decoded frame is
 * kept: calling again with the same t and flags (larger buffers after FM_ERROR_BUFFER_TOO_SMALL)
 * only copies it. Leaving every buffer NULL decodes and reports the sizes. */
fm_status fm_decoder_decode(fm_decoder* decoder, double t, uint32_t flags, fm_frame* frame);

#ifdef __cplusplus
}
#endif

#endif /* FACEMORPH_H */
