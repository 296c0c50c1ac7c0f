// The C API (facemorph.h) over facemorph::Decoder: handles that check their own type, every
// exception caught at the boundary and turned into an fm_status with a thread-local message.
#include "facemorph.h"

#include "facemorph/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <new>
#include <span>
#include <string>
#include <vector>

// fm_version() is the library's version (CMake's project version); the header must say the same.
static_assert(FACEMORPH_VERSION_NUMBER == FACEMORPH_VERSION_NUMBER_BUILT, "bump FACEMORPH_VERSION_* in facemorph.h with the project's version");

// The C enum mirrors facemorph::ErrorCode value for value.
static_assert(FM_OK == static_cast<int>(facemorph::ErrorCode::kOk));
static_assert(FM_ERROR_IO == static_cast<int>(facemorph::ErrorCode::kIo));
static_assert(FM_ERROR_PARSE == static_cast<int>(facemorph::ErrorCode::kParse));
static_assert(FM_ERROR_TRUNCATED == static_cast<int>(facemorph::ErrorCode::kTruncated));
static_assert(FM_ERROR_CORRUPT == static_cast<int>(facemorph::ErrorCode::kCorrupt));
static_assert(FM_ERROR_UNSUPPORTED == static_cast<int>(facemorph::ErrorCode::kUnsupported));
static_assert(FM_ERROR_INVALID_MESH == static_cast<int>(facemorph::ErrorCode::kInvalidMesh));
static_assert(FM_ERROR_NOT_A_DISK == static_cast<int>(facemorph::ErrorCode::kNotADisk));
static_assert(FM_ERROR_MISSING_TEXTURE == static_cast<int>(facemorph::ErrorCode::kMissingTexture));
static_assert(FM_ERROR_INVALID_ARGUMENT == static_cast<int>(facemorph::ErrorCode::kInvalidArgument));
static_assert(FM_ERROR_NUMERICAL == static_cast<int>(facemorph::ErrorCode::kNumerical));
static_assert(FM_ERROR_NOT_CONVERGED == static_cast<int>(facemorph::ErrorCode::kNotConverged));
static_assert(FM_ERROR_OUT_OF_RANGE == static_cast<int>(facemorph::ErrorCode::kOutOfRange));
static_assert(FM_ERROR_BUFFER_TOO_SMALL == static_cast<int>(facemorph::ErrorCode::kBufferTooSmall));
static_assert(FM_ERROR_OUT_OF_MEMORY == static_cast<int>(facemorph::ErrorCode::kOutOfMemory));
static_assert(FM_ERROR_INTERNAL == static_cast<int>(facemorph::ErrorCode::kInternal));

// Each handle starts with a tag, so that a NULL, a closed (best effort: the tag is cleared on
// release) or a wrong kind of handle is an FM_ERROR_INVALID_ARGUMENT rather than a crash.
namespace {
constexpr uint32_t kFileTag = 0x464d4649;     // "FMFI"
constexpr uint32_t kDecoderTag = 0x464d4445;  // "FMDE"
}  // namespace

struct fm_file {
  uint32_t tag = kFileTag;
  std::shared_ptr<const facemorph::Sequence> sequence;
  facemorph::FileInfo info;
};

struct fm_decoder {
  uint32_t tag = kDecoderTag;
  facemorph::Decoder decoder;
};

namespace {

using facemorph::Error;
using facemorph::ErrorCode;

std::string& last_message() {
  thread_local std::string message;
  return message;
}

fm_status fail(ErrorCode code, const std::string& message) {
  try {
    last_message() = message;
  } catch (...) {
    last_message().clear();  // no memory for the message: the status still says what happened
  }
  return static_cast<fm_status>(code);
}

fm_status ok() {
  last_message().clear();
  return FM_OK;
}

// Runs `body` (returning fm_status) with every exception turned into a status and message.
template <typename Body>
fm_status guarded(const char* function, Body&& body) noexcept {
  try {
    return body();
  } catch (const Error& e) {
    return fail(e.code(), std::string(function) + ": " + e.what());
  } catch (const std::bad_alloc&) {
    return fail(ErrorCode::kOutOfMemory, std::string(function) + ": out of memory");
  } catch (const std::exception& e) {
    return fail(ErrorCode::kInternal, std::string(function) + ": " + e.what());
  } catch (...) {
    return fail(ErrorCode::kInternal, std::string(function) + ": unknown exception");
  }
}

void check_file(const fm_file* file, const char* name = "file") {
  if (file == nullptr) throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is NULL");
  if (file->tag != kFileTag) throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is not an open fm_file handle");
}

void check_decoder(const fm_decoder* decoder) {
  if (decoder == nullptr) throw Error(ErrorCode::kInvalidArgument, "decoder is NULL");
  if (decoder->tag != kDecoderTag) throw Error(ErrorCode::kInvalidArgument, "decoder is not an fm_decoder handle");
}

void check_pointer(const void* pointer, const char* name) {
  if (pointer == nullptr) throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is NULL");
}

fm_status open_into(std::shared_ptr<const facemorph::Sequence> sequence, fm_file** file) {
  auto handle = std::make_unique<fm_file>();
  handle->info = facemorph::file_info(*sequence);  // validates it as a decoder will
  handle->sequence = std::move(sequence);
  *file = handle.release();
  return ok();
}

// A buffer's element count from its size in bytes; a NULL buffer is an empty span.
template <typename T>
std::span<T> span_of(T* data, size_t bytes) {
  return data == nullptr ? std::span<T>() : std::span<T>(data, bytes / sizeof(T));
}

void describe(const facemorph::FrameInfo& info, fm_frame* frame) {
  frame->time = info.time;
  frame->vertex_count = static_cast<uint32_t>(info.vertex_count);
  frame->triangle_count = static_cast<uint32_t>(info.triangle_count);
  frame->texture_size = static_cast<uint32_t>(info.texture_size);
  frame->iterations = static_cast<uint32_t>(info.iterations);
  frame->fell_back = info.fell_back ? 1 : 0;
}

}  // namespace

extern "C" {

const char* fm_status_name(fm_status status) {
  if (status < FM_OK || status > FM_ERROR_INTERNAL) return "unknown";
  return facemorph::error_code_name(static_cast<ErrorCode>(status));
}

const char* fm_last_error_message(void) { return last_message().c_str(); }

const char* fm_version(void) { return FACEMORPH_VERSION; }

uint32_t fm_version_number(void) { return FACEMORPH_VERSION_NUMBER_BUILT; }

fm_status fm_file_open(const char* path, fm_file** file) {
  return guarded("fm_file_open", [&] {
    check_pointer(file, "file");
    *file = nullptr;
    check_pointer(path, "path");
    return open_into(facemorph::open_sequence_file(path), file);
  });
}

fm_status fm_file_open_memory(const void* data, size_t size, fm_file** file) {
  return guarded("fm_file_open_memory", [&] {
    check_pointer(file, "file");
    *file = nullptr;
    if (data == nullptr && size > 0) throw Error(ErrorCode::kInvalidArgument, "data is NULL");
    const std::span<const uint8_t> bytes(static_cast<const uint8_t*>(data), data == nullptr ? 0 : size);
    return open_into(facemorph::open_sequence_memory(bytes), file);
  });
}

void fm_file_close(fm_file* file) {
  if (file == nullptr || file->tag != kFileTag) return;
  file->tag = 0;
  delete file;
}

fm_status fm_file_get_info(const fm_file* file, fm_info* info) {
  return guarded("fm_file_get_info", [&] {
    check_file(file);
    check_pointer(info, "info");
    const facemorph::FileInfo& in = file->info;
    fm_info out{};
    out.fps = in.fps;
    out.first_time = in.first_time;
    out.last_time = in.last_time;
    out.duration = in.duration;
    out.range_begin = in.range_begin;
    out.range_end = in.range_end;
    out.keyframe_count = static_cast<uint32_t>(in.keyframe_times.size());
    out.grid_n = static_cast<uint32_t>(in.grid_n);
    out.max_vertex_count = static_cast<uint32_t>(in.max_vertex_count);
    out.max_triangle_count = static_cast<uint32_t>(in.max_triangle_count);
    out.grid_vertex_count = static_cast<uint32_t>(in.grid_vertex_count);
    out.grid_triangle_count = static_cast<uint32_t>(in.grid_triangle_count);
    out.has_holes = in.has_holes ? 1 : 0;
    out.texture_size = static_cast<uint32_t>(in.texture_size);
    // Units are "m", "cm" or "mm" (the container's reader checks): they fit with their NUL.
    std::strncpy(out.units, in.units.c_str(), sizeof out.units - 1);
    *info = out;
    return ok();
  });
}

fm_status fm_file_get_keyframe_times(const fm_file* file, double* times, size_t capacity, size_t* count) {
  return guarded("fm_file_get_keyframe_times", [&] {
    check_file(file);
    check_pointer(count, "count");
    const std::vector<double>& keys = file->info.keyframe_times;
    *count = keys.size();
    if (capacity < keys.size()) {
      throw Error(ErrorCode::kBufferTooSmall, std::to_string(keys.size()) + " keyframe times, room for " + std::to_string(capacity));
    }
    check_pointer(times, "times");
    std::copy(keys.begin(), keys.end(), times);
    return ok();
  });
}

fm_status fm_decoder_create(const fm_file* file, fm_decoder** decoder) {
  return guarded("fm_decoder_create", [&] {
    check_pointer(decoder, "decoder");
    *decoder = nullptr;
    check_file(file);
    *decoder = new fm_decoder{kDecoderTag, facemorph::Decoder(file->sequence)};
    return ok();
  });
}

void fm_decoder_destroy(fm_decoder* decoder) {
  if (decoder == nullptr || decoder->tag != kDecoderTag) return;
  decoder->tag = 0;
  delete decoder;
}

fm_status fm_decoder_decode(fm_decoder* decoder, double t, uint32_t flags, fm_frame* frame) {
  return guarded("fm_decoder_decode", [&] {
    check_decoder(decoder);
    check_pointer(frame, "frame");
    if (!std::isfinite(t)) throw Error(ErrorCode::kInvalidArgument, "t is not finite");
    constexpr uint32_t known = FM_DECODE_CLAMP | FM_DECODE_KEEP_HOLES_FILLED | FM_DECODE_FLIP_V;
    if ((flags & ~known) != 0) throw Error(ErrorCode::kInvalidArgument, "unknown decode flags " + std::to_string(flags & ~known));
    facemorph::FrameOptions options;
    options.clamp = (flags & FM_DECODE_CLAMP) != 0;
    options.keep_holes_filled = (flags & FM_DECODE_KEEP_HOLES_FILLED) != 0;
    options.flip_v = (flags & FM_DECODE_FLIP_V) != 0;
    facemorph::FrameBuffers buffers;
    buffers.positions = span_of(frame->positions, frame->positions_bytes);
    buffers.normals = span_of(frame->normals, frame->normals_bytes);
    buffers.uvs = span_of(frame->uvs, frame->uvs_bytes);
    buffers.indices = span_of(frame->indices, frame->indices_bytes);
    buffers.texture = span_of(frame->texture, frame->texture_bytes);
    // A non-NULL buffer smaller than one element is too small, not "not wanted".
    auto tiny = [](const void* p, size_t bytes, size_t element) { return p != nullptr && bytes < element; };
    if (tiny(frame->positions, frame->positions_bytes, sizeof(float)) || tiny(frame->normals, frame->normals_bytes, sizeof(float)) ||
        tiny(frame->uvs, frame->uvs_bytes, sizeof(float)) || tiny(frame->indices, frame->indices_bytes, sizeof(uint32_t)) ||
        tiny(frame->texture, frame->texture_bytes, 1)) {
      describe(decoder->decoder.frame_info(t, options), frame);
      throw Error(ErrorCode::kBufferTooSmall, "a buffer smaller than one element (sizes are in bytes)");
    }
    const bool wants_nothing = buffers.positions.empty() && buffers.normals.empty() && buffers.uvs.empty() && buffers.indices.empty() &&
                               buffers.texture.empty();
    try {
      describe(wants_nothing ? decoder->decoder.frame_info(t, options) : decoder->decoder.decode(t, buffers, options), frame);
    } catch (const Error& e) {
      // The frame was decoded and kept: say what it needs.
      if (e.code() == ErrorCode::kBufferTooSmall) describe(decoder->decoder.frame_info(t, options), frame);
      throw;
    }
    return ok();
  });
}

}  // extern "C"
