/* facemorph.h: the C API of the facemorph decoder, for players in any language.
 *
 * Open a .fmv file (fm_file_open, fm_file_open_memory), ask what it holds (fm_file_get_info), make
 * a decoder on it (fm_decoder_create) and decode any time t into buffers the caller owns
 * (fm_decoder_decode): positions, normals and UVs per vertex, triangle indices, an RGBA8 texture.
 *
 *   fm_file* file; fm_decoder* decoder; fm_info info; fm_frame frame;
 *   if (fm_file_open("face.fmv", &file) != FM_OK) { fprintf(stderr, "%s\n", fm_last_error_message()); ... }
 *   fm_info_init(&info); fm_file_get_info(file, &info);
 *   fm_decoder_create(file, &decoder);
 *   float* positions = malloc(3 * sizeof(float) * info.max_vertex_count);
 *   fm_frame_init(&frame);
 *   frame.positions = positions; frame.positions_bytes = 3 * sizeof(float) * info.max_vertex_count;
 *   if (fm_decoder_decode(decoder, 1.45, 0, &frame) == FM_OK) printf("%u vertices\n", frame.vertex_count);
 *   fm_decoder_destroy(decoder); fm_file_close(file); free(positions);
 *
 * Status: every function that can fail returns an fm_status. Its values never change meaning and
 * are never renumbered; new ones are appended. Each function lists every status it can return.
 * fm_status_name gives a short stable name, fm_last_error_message the full message (naming the
 * file, chunk and reason) of the last failed call on the calling thread.
 *
 * Threads: an fm_file is immutable once opened; any number of threads may create decoders on it at
 * once. An fm_decoder is used by one thread at a time; decoders on one file may decode on
 * different threads at once. A file may be closed while its decoders live (they share it).
 *
 * API and ABI 1.3 (spec/api.md; 1.1 appends fm_file_open_memory_borrowed and
 * fm_decoder_get_texture_weights to 1.0, 1.2 fm_decoder_options.max_work, 1.3 the frame's
 * double-precision arrays and hole levels and fm_decoder_set_tolerance): this header is the only one a C player needs; the library exports
 * exactly the functions below (every one starts with fm_) and nothing else. Within 1.x nothing is
 * removed, renumbered or reordered: functions, enum values, flags and struct fields are only ever
 * appended, and libfacemorph_decoder.so.1 keeps its name; a program built against 1.0 runs on every
 * 1.x library. Structs that cross the API grow by one rule: their first field, struct_size, is set by
 * the caller to sizeof the struct as it compiled it; the library reads and writes only the fields
 * that lie wholly inside struct_size bytes (fields beyond it keep their defaults: zero, NULL, not
 * wanted), and struct_size 0 is FM_ERROR_INVALID_ARGUMENT. fm_info_init, fm_frame_init and
 * fm_decoder_options_init (inline) set it. Handles are opaque.
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
#include <string.h>

/* FM_API marks the library's exported functions. The shared library is built with
 * -fvisibility=hidden and FACEMORPH_BUILDING_LIBRARY, so that these are all it exports. */
#if defined(_WIN32)
#if defined(FACEMORPH_BUILDING_LIBRARY)
#define FM_API __declspec(dllexport)
#elif defined(FACEMORPH_STATIC)
#define FM_API
#else
#define FM_API __declspec(dllimport)
#endif
#elif defined(__GNUC__) && __GNUC__ >= 4
#define FM_API __attribute__((visibility("default")))
#else
#define FM_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* The API (and ABI) this header declares: 1.4 (1.0 with two functions appended in 1.1,
 * fm_decoder_options.max_work appended in 1.2, in 1.3 fm_frame's double-precision arrays and
 * hole levels and fm_decoder_set_tolerance, and in 1.4 fm_info's representation, spline and
 * fixed_node_count, below). The soname follows the major version only
 * (libfacemorph_decoder.so.1); the library's own version is FACEMORPH_VERSION_*, below. */
#define FACEMORPH_API_VERSION_MAJOR 1
#define FACEMORPH_API_VERSION_MINOR 4

#define FACEMORPH_VERSION_MAJOR 0
#define FACEMORPH_VERSION_MINOR 8
#define FACEMORPH_VERSION_PATCH 0
/* major * 10000 + minor * 100 + patch, as fm_version_number returns it. */
#define FACEMORPH_VERSION_NUMBER (FACEMORPH_VERSION_MAJOR * 10000 + FACEMORPH_VERSION_MINOR * 100 + FACEMORPH_VERSION_PATCH)

typedef enum fm_status {
  FM_OK = 0,
  FM_ERROR_IO = 1,          /* a file could not be opened or read */
  FM_ERROR_PARSE = 2,       /* text or structure that does not follow its grammar */
  FM_ERROR_TRUNCATED = 3,   /* the input ends before the data it announces */
  FM_ERROR_CORRUPT = 4,     /* bytes present but wrong (checksum, impossible value, a file that decodes to non-finite numbers) */
  FM_ERROR_UNSUPPORTED = 5, /* a valid file using a feature this decoder does not implement */
  FM_ERROR_INVALID_MESH = 6,
  FM_ERROR_NOT_A_DISK = 7,
  FM_ERROR_MISSING_TEXTURE = 8,
  FM_ERROR_INVALID_ARGUMENT = 9, /* the caller's fault, never the file's: a NULL or wrong handle or pointer, t not finite, a bad option */
  FM_ERROR_NUMERICAL = 10,       /* the reconstruction failed numerically (a non-finite iterate: a corrupt file) */
  FM_ERROR_NOT_CONVERGED = 11,
  FM_ERROR_OUT_OF_RANGE = 12,     /* t outside [range_begin, range_end] without FM_DECODE_CLAMP */
  FM_ERROR_BUFFER_TOO_SMALL = 13, /* an output buffer too small: the frame's counts say what is needed */
  FM_ERROR_OUT_OF_MEMORY = 14,
  FM_ERROR_INTERNAL = 15,      /* a bug in facemorph: please report it with the message */
  FM_ERROR_LIMIT = 16,         /* the file needs more than the decoder's limits allow (fm_decoder_options): refused before allocating */
  FM_ERROR_CLOSED_HANDLE = 17, /* a handle used after fm_file_close / fm_decoder_destroy, or closed twice */
  /* Never returned: gives fm_status the range of a 32-bit int in C and C++ alike, so that any
   * non-negative int a caller passes to fm_status_name is a valid value. */
  FM_STATUS_FORCE_32BIT = 0x7fffffff
} fm_status;

/* Short stable name of a status ("ok", "truncated", "buffer-too-small", ...); "unknown" for
 * another value. Never NULL; a static string. Cannot fail; sets no message. */
FM_API const char* fm_status_name(fm_status status);

/* The message of the last call on this thread that did not return FM_OK (every failing call sets
 * it; a call that succeeds sets it to ""). Valid until the next facemorph call on this thread.
 * Never NULL. */
FM_API const char* fm_last_error_message(void);

/* "0.8.0": the library's version, which may differ from the header's FACEMORPH_VERSION_* (a 1.x
 * program may run on any 1.x library). Never NULL; a static string. Cannot fail; sets no message. */
FM_API const char* fm_version(void);
/* The same as major * 10000 + minor * 100 + patch. Cannot fail; sets no message. */
FM_API uint32_t fm_version_number(void);

/* An opened .fmv file: its header and index read and checked; keyframes decoded when needed.
 *
 * Handles are not pointers to memory: they name an entry of a table with a generation count, so a
 * handle used after it was closed (or closed twice) is FM_ERROR_CLOSED_HANDLE and never reads freed
 * memory, and closing a stale handle never closes the live handle that reuses its entry. */
typedef struct fm_file fm_file;
/* The state that decodes one file's frames. */
typedef struct fm_decoder fm_decoder;

/* What a decoder may spend on a file it did not write (spec/container.md §10). Call
 * fm_decoder_options_init first, then change what you want: fields appended by later versions keep
 * their defaults. A file that would exceed a limit is refused with FM_ERROR_LIMIT, before the
 * memory is allocated. */
typedef struct fm_decoder_options {
  size_t struct_size;        /* sizeof(fm_decoder_options) as the caller compiled it */
  uint32_t max_grid_n;       /* largest grid N (default 1025; the format allows 4097) */
  uint32_t max_keyframes;    /* most keyframes (default 65536) */
  uint32_t max_texture_size; /* largest texture M, texels per side (default 4096; the format allows 16384) */
  uint64_t max_memory_bytes; /* what an opened file and one decoder on it may hold (default 256 MiB) */
  /* 1.2: what one fm_decoder_decode (or fm_decoder_get_texture_weights) call may do, in work units
   * (spec/container.md §10.3: about a second on one core at the default; 0: no bound). A call that
   * would pass it returns FM_ERROR_LIMIT naming max_work and keeps what it finished, so that calling
   * again with the same t goes on from there. */
  uint64_t max_work;
} fm_decoder_options;

/* The defaults fm_decoder_options_init sets (those of API 1.0, and max_work's of 1.2). */
#define FM_DEFAULT_MAX_GRID_N 1025u
#define FM_DEFAULT_MAX_KEYFRAMES 65536u
#define FM_DEFAULT_MAX_TEXTURE_SIZE 4096u
#define FM_DEFAULT_MAX_MEMORY_BYTES (UINT64_C(256) << 20)
#define FM_DEFAULT_MAX_WORK UINT64_C(16000000) /* 1.2 */

/* Sets struct_size to sizeof(fm_decoder_options) and every field to its default. NULL is ignored.
 * Inline, not in the library: struct_size is then the size of the struct as the caller compiled it,
 * whatever version of the library runs (spec/api.md §3). */
static inline void fm_decoder_options_init(fm_decoder_options* options) {
  if (!options) return;
  memset(options, 0, sizeof *options);
  options->struct_size = sizeof *options;
  options->max_grid_n = FM_DEFAULT_MAX_GRID_N;
  options->max_keyframes = FM_DEFAULT_MAX_KEYFRAMES;
  options->max_texture_size = FM_DEFAULT_MAX_TEXTURE_SIZE;
  options->max_memory_bytes = FM_DEFAULT_MAX_MEMORY_BYTES;
  options->max_work = FM_DEFAULT_MAX_WORK;
}

/* Opens a file under the default limits: its header and index read and checked (every keyframe's
 * time and pose are there), and nothing else; a keyframe's fields and texture are decoded (their
 * checksums verified) when a frame first needs them, into a cache bounded by max_memory_bytes
 * (spec/container.md §10.1): a fault there is FM_ERROR_CORRUPT from fm_decoder_decode. Returns FM_OK, FM_ERROR_INVALID_ARGUMENT
 * (NULL path or file), FM_ERROR_IO, FM_ERROR_TRUNCATED, FM_ERROR_CORRUPT, FM_ERROR_UNSUPPORTED,
 * FM_ERROR_LIMIT, FM_ERROR_OUT_OF_MEMORY. On success *file is a new handle for fm_file_close; on
 * failure *file is NULL. */
FM_API fm_status fm_file_open(const char* path, fm_file** file);
/* The same from `size` bytes at `data`. They are copied (the copy counts against max_memory_bytes):
 * the caller may free them at once. FM_OK, FM_ERROR_INVALID_ARGUMENT (NULL file, or NULL data with
 * size > 0), FM_ERROR_TRUNCATED, FM_ERROR_CORRUPT, FM_ERROR_UNSUPPORTED, FM_ERROR_LIMIT,
 * FM_ERROR_OUT_OF_MEMORY. */
FM_API fm_status fm_file_open_memory(const void* data, size_t size, fm_file** file);
/* fm_file_open / fm_file_open_memory under the caller's limits (options NULL: the defaults). The
 * same statuses; FM_ERROR_INVALID_ARGUMENT also for options whose struct_size is 0 or whose limits
 * cannot work (max_grid_n below 5, max_keyframes or max_memory_bytes 0). */
FM_API fm_status fm_file_open_with_options(const char* path, const fm_decoder_options* options, fm_file** file);
FM_API fm_status fm_file_open_memory_with_options(const void* data, size_t size, const fm_decoder_options* options, fm_file** file);
/* Releases the handle; decoders created from it stay valid. NULL is ignored. A handle already
 * closed (or never opened) changes nothing; fm_last_error_message then says so. */
FM_API void fm_file_close(fm_file* file);
/* fm_file_close with a status: FM_OK, FM_ERROR_CLOSED_HANDLE (already closed), FM_ERROR_INVALID_ARGUMENT
 * (NULL, or not a file handle). */
FM_API fm_status fm_file_release(fm_file* file);

/* What a file holds. fm_info_init it (or set struct_size to sizeof(fm_info)) before fm_file_get_info. */
typedef struct fm_info {
  size_t struct_size; /* sizeof(fm_info) as the caller compiled it */
  double fps;         /* the capture's nominal frame rate */
  double first_time;  /* the capture's first and last frame times, seconds */
  double last_time;
  double duration;    /* last_time - first_time */
  double range_begin; /* the times fm_decoder_decode serves without FM_DECODE_CLAMP (+-infinity with one keyframe) */
  double range_end;
  uint32_t keyframe_count;
  uint32_t grid_n; /* N of the disk grid */
  /* Buffers for these many vertices and triangles always suffice. Without holes (or with
   * FM_DECODE_KEEP_HOLES_FILLED) every frame has exactly the grid's counts and the same indices. */
  uint32_t max_vertex_count;
  uint32_t max_triangle_count;
  uint32_t grid_vertex_count;
  uint32_t grid_triangle_count;
  uint32_t has_holes;    /* 1: eyes and mouth are cut per frame, the counts change between frames */
  uint32_t texture_size; /* M, texels per side; 0: the file has no texture */
  char units[8];         /* "m", "cm" or "mm", NUL-terminated */
  /* 1.4: how the file stores its keyframes (spec/container.md §5), what fminfo describes. Names
   * are NUL-terminated and never change (the encoder's settings use them too). */
  char representation[8];    /* what a keyframe stores on G: "hl", "hl+t" or "xyz" */
  char spline[16];           /* the keyframe spline: "local", "catmull-rom", "not-a-knot" or "linear" */
  uint32_t fixed_node_count; /* nodes of G stored in a boundary frame (hl+t's rim band; 0 otherwise) */
} fm_info;

/* Zeroes *info and sets struct_size to sizeof(fm_info) as the caller compiled it. NULL is ignored. */
static inline void fm_info_init(fm_info* info) {
  if (!info) return;
  memset(info, 0, sizeof *info);
  info->struct_size = sizeof *info;
}

/* Fills the fields of *info that its struct_size covers. FM_OK, FM_ERROR_INVALID_ARGUMENT (a NULL or
 * wrong handle, NULL info, info->struct_size 0), FM_ERROR_CLOSED_HANDLE. */
FM_API fm_status fm_file_get_info(const fm_file* file, fm_info* info);
/* Copies the keyframe times (seconds) into times[0 .. capacity) and sets *count to the number of
 * keyframes; FM_ERROR_BUFFER_TOO_SMALL (copying nothing) when capacity < *count. times NULL with
 * capacity 0 asks the count only: FM_OK, no error message set. FM_OK, FM_ERROR_INVALID_ARGUMENT
 * (a NULL or wrong handle, NULL count, NULL times with capacity > 0), FM_ERROR_CLOSED_HANDLE,
 * FM_ERROR_BUFFER_TOO_SMALL. */
FM_API fm_status fm_file_get_keyframe_times(const fm_file* file, double* times, size_t capacity, size_t* count);

/* A decoder on the file (which it shares: the file handle may be closed afterwards), under the
 * limits the file was opened with. FM_OK, FM_ERROR_INVALID_ARGUMENT, FM_ERROR_CLOSED_HANDLE,
 * FM_ERROR_LIMIT, FM_ERROR_OUT_OF_MEMORY, FM_ERROR_INTERNAL. */
FM_API fm_status fm_decoder_create(const fm_file* file, fm_decoder** decoder);
/* NULL is ignored; a destroyed handle changes nothing (fm_last_error_message says so). */
FM_API void fm_decoder_destroy(fm_decoder* decoder);
/* fm_decoder_destroy with a status: FM_OK, FM_ERROR_CLOSED_HANDLE, FM_ERROR_INVALID_ARGUMENT. */
FM_API fm_status fm_decoder_release(fm_decoder* decoder);

/* Decode flags, or-ed; 0 is the default. */
#define FM_DECODE_CLAMP 1u             /* clamp t into [range_begin, range_end] instead of FM_ERROR_OUT_OF_RANGE */
#define FM_DECODE_KEEP_HOLES_FILLED 2u /* keep the filled eyes and mouth: fixed topology */
#define FM_DECODE_FLIP_V 4u            /* UV v down (glTF, Direct3D): v -> 1 - v */

/* One frame: the caller's buffers in, the frame's description out. A NULL buffer is not wanted
 * (and not computed); a buffer that is not NULL must hold the whole array, its size given in
 * BYTES: 3 floats per vertex (positions, normals), 2 floats per vertex (uvs), 3 uint32 per triangle
 * (indices), 4 bytes per texel (texture). fm_frame_init it, then set what you want. */
typedef struct fm_frame {
  size_t struct_size; /* sizeof(fm_frame) as the caller compiled it */
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
  double time; /* the time decoded (t, or t clamped) */
  uint32_t vertex_count;
  uint32_t triangle_count;
  uint32_t texture_size; /* M (0: no texture) */
  uint32_t iterations;   /* reconstruction steps */
  uint32_t fell_back;    /* 1: the reconstruction did not converge; the frame is the spline of the keyframes' surfaces */
  /* 1.3: for tools that write the surface at the decoder's own precision (the reference decoder
   * fmdec writes its OBJ, PLY and glTF files from these) and players that keep the topology fixed
   * and cut the holes themselves. Buffers as above, sizes in BYTES: 3 doubles per vertex
   * (positions_f64), 2 per vertex (uvs_f64, flipped as uvs are), hole_level_count doubles
   * (hole_levels: the blended level set at each node of the disk grid, negative inside an eye or the
   * mouth, in the vertex order of a frame decoded with FM_DECODE_KEEP_HOLES_FILLED, the same whether
   * the holes are cut or not). */
  double* positions_f64;
  size_t positions_f64_bytes;
  double* uvs_f64;
  size_t uvs_f64_bytes;
  double* hole_levels;
  size_t hole_levels_bytes;
  uint32_t hole_level_count; /* set as the counts above: fm_info.grid_vertex_count in a file with holes, else 0 */
} fm_frame;

/* Zeroes *frame (no buffer wanted) and sets struct_size to sizeof(fm_frame) as the caller compiled
 * it. NULL is ignored. */
static inline void fm_frame_init(fm_frame* frame) {
  if (!frame) return;
  memset(frame, 0, sizeof *frame);
  frame->struct_size = sizeof *frame;
}

/* Decodes the frame at time t (seconds from the capture's first frame) into the buffers of
 * *frame. Returns FM_OK (every number written is finite), FM_ERROR_INVALID_ARGUMENT (NULL or wrong
 * handle, NULL frame, frame->struct_size 0, t not finite, unknown flag: the caller's fault only),
 * FM_ERROR_CLOSED_HANDLE,
 * FM_ERROR_OUT_OF_RANGE, FM_ERROR_BUFFER_TOO_SMALL, FM_ERROR_CORRUPT (the file decodes to
 * non-finite numbers, or a keyframe of it cannot be reconstructed: every later call that needs that
 * keyframe fails at once the same way; or a keyframe's fields or texture, decoded when a frame first
 * needs them, do not decode: a bad checksum, a damaged stream), FM_ERROR_UNSUPPORTED (that texture is in an image codec this decoder does
 * not read), FM_ERROR_LIMIT (its chunk is larger than the memory budget), FM_ERROR_NUMERICAL, FM_ERROR_NOT_CONVERGED,
 * FM_ERROR_OUT_OF_MEMORY, FM_ERROR_INTERNAL. The decoded frame is
 * kept: calling again with the same t and flags (larger buffers after FM_ERROR_BUFFER_TOO_SMALL)
 * only copies it. Leaving every buffer NULL decodes and reports the sizes (FM_OK): the count query. */
FM_API fm_status fm_decoder_decode(fm_decoder* decoder, double t, uint32_t flags, fm_frame* frame);

/* ---- Added in API 1.1 (facemorph 0.8.0): for players that hold the file's bytes themselves and
 * decode its textures themselves, as the browser player does (spec/web.md). ---- */

/* fm_file_open_memory_with_options without the copy: the file reads the `size` bytes at `data`
 * where they lie, for as long as it or any decoder on it lives; the caller keeps them there,
 * unchanged, until the last of them is closed. Opening reads the header's and index's chunks and
 * each chunk's 24-byte header and 4-byte checksum only; a keyframe group's chunk is read (and its
 * checksum verified) when a frame first needs one of its keyframes. So a player that streams the
 * file may allocate all `size` bytes, fill in those parts, open, and fill in a group's chunk before
 * the first decode that needs it: a chunk read before its bytes arrived fails its checksum
 * (FM_ERROR_CORRUPT), and that keyframe fails at once ever after. The same statuses as
 * fm_file_open_memory_with_options. */
FM_API fm_status fm_file_open_memory_borrowed(const void* data, size_t size, const fm_decoder_options* options, fm_file** file);

/* The texture blend of the frame at t (flags as fm_decoder_decode's) without the texture: the
 * keyframes whose textures it sums and the weight of each, so that a player that decodes the
 * keyframes' images itself (each keyframe's image is in its TEXR chunk, or frame k - gP of its
 * group's TGOP chunk, spec/container.md §8) makes the frame's texture as fm_decoder_decode does.
 * In a file of shared textures (format 2.2) a keyframe is named by the one whose TEXR it shows
 * (the chunk's keyframe number), which may then appear twice, each with its own weight:
 * texel = Σ weights[i] · texel of keyframe keyframes[i], each weight taken as a float, the sum in
 * float, plus ½, clamped to 0..255 and truncated. Weights may be 0 (that keyframe adds nothing) or
 * negative (cubic splines), and sum to 1. Decodes the frame as fm_decoder_decode with every buffer
 * NULL does (and keeps it). *count is the number of keyframes; keyframes and weights are both NULL
 * with capacity 0 to ask it alone (FM_OK); a capacity below it is FM_ERROR_BUFFER_TOO_SMALL,
 * writing nothing. A file without texture gives its weights all the same. Statuses: as
 * fm_decoder_decode, and FM_ERROR_INVALID_ARGUMENT for a NULL count, or NULL keyframes or weights
 * with capacity > 0. */
FM_API fm_status fm_decoder_get_texture_weights(fm_decoder* decoder, double t, uint32_t flags, uint32_t* keyframes, double* weights,
                                                size_t capacity, size_t* count);

/* ---- Added in API 1.3 (facemorph 0.8.0): the fm_frame fields above, and: ---- */

/* The reconstruction's stopping rule: a frame's iteration stops when a step moves no node more
 * than `tolerance` times the rim's diameter (default FM_DEFAULT_TOLERANCE). Frames decoded after
 * the call use it (a frame kept from before is decoded again); keyframe surfaces already
 * reconstructed are kept, as they only start each frame's iteration. Smaller is slower and closer
 * to the exact surface. FM_OK, FM_ERROR_INVALID_ARGUMENT (a NULL or wrong handle, tolerance not in
 * (0, 0.01]), FM_ERROR_CLOSED_HANDLE. */
#define FM_DEFAULT_TOLERANCE 1e-5
FM_API fm_status fm_decoder_set_tolerance(fm_decoder* decoder, double tolerance);

#ifdef __cplusplus
}
#endif

#endif /* FACEMORPH_H */
