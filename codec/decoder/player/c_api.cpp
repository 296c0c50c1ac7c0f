// The C API (facemorph.h) over facemorph::Decoder: handles that name entries of a table with a
// generation count (never pointers the library dereferences), every exception caught at the
// boundary and turned into an fm_status with a thread-local message, structs read and written only
// as far as their struct_size reaches (spec/api.md §3).
#define FACEMORPH_BUILDING_LIBRARY
#include "facemorph.h"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/player/decoder.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

// fm_info's names (1.4) fit their fields with the NUL: every name of the enumerations' tables.
template <typename Entry, size_t N>
constexpr bool names_fit(const Entry (&table)[N], size_t field_bytes) {
  for (const Entry& entry : table) {
    if (std::char_traits<char>::length(entry.name) >= field_bytes) return false;
  }
  return true;
}
static_assert(names_fit(facemorph::kRepresentations, sizeof(fm_info::representation)));
static_assert(names_fit(facemorph::kSplineKinds, sizeof(fm_info::spline)));

// fm_decoder_options_init (inline in the header) sets the library's own defaults.
static_assert(FM_DEFAULT_MAX_GRID_N == facemorph::kDefaultDecoderLimits.max_grid_n);
static_assert(FM_DEFAULT_MAX_KEYFRAMES == facemorph::kDefaultDecoderLimits.max_keyframes);
static_assert(FM_DEFAULT_MAX_TEXTURE_SIZE == facemorph::kDefaultDecoderLimits.max_texture_size);
static_assert(FM_DEFAULT_MAX_MEMORY_BYTES == facemorph::kDefaultDecoderLimits.max_memory_bytes);
static_assert(FM_DEFAULT_MAX_WORK == facemorph::kDefaultDecoderLimits.max_work);
static_assert(FM_DEFAULT_TOLERANCE == facemorph::ReconstructOptions{}.tolerance);

// The C enum mirrors facemorph::ErrorCode value for value: every row of the one list
// (FACEMORPH_ERROR_CODES, format/error.hpp) names its fm_status, whose value facemorph.h states
// (the ABI) and must equal the row's; and the codes run 0 .. kErrorCodeCount - 1 with none left out.
#define FACEMORPH_CHECK_STATUS(code, value, name, status) \
  static_assert(status == value && static_cast<int>(facemorph::ErrorCode::code) == value, #status " is not facemorph::ErrorCode::" #code);
FACEMORPH_ERROR_CODES(FACEMORPH_CHECK_STATUS)
#undef FACEMORPH_CHECK_STATUS
static_assert(FM_ERROR_CLOSED_HANDLE + 1 == facemorph::kErrorCodeCount, "fm_status and facemorph::ErrorCode differ in count");
constexpr bool error_codes_run_from_zero() {
#define FACEMORPH_ERROR_VALUE(code, value, name, status) value,
  constexpr int values[] = {FACEMORPH_ERROR_CODES(FACEMORPH_ERROR_VALUE)};
#undef FACEMORPH_ERROR_VALUE
  for (int i = 0; i < facemorph::kErrorCodeCount; ++i) {
    if (values[i] != i) return false;
  }
  return true;
}
static_assert(error_codes_run_from_zero(), "the error codes skip a value or leave their order");

namespace {

using facemorph::Error;
using facemorph::ErrorCode;

// The status of a code, from the one list (FACEMORPH_ERROR_CODES).
constexpr fm_status status_of(ErrorCode code) noexcept {
  switch (code) {
#define FACEMORPH_STATUS_CASE(code, value, name, status) \
  case ErrorCode::code: return status;
    FACEMORPH_ERROR_CODES(FACEMORPH_STATUS_CASE)
#undef FACEMORPH_STATUS_CASE
  }
  return FM_ERROR_INTERNAL;
}

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
  return status_of(code);
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

// What a file handle names: the opened file, what it holds, and the limits it was opened under.
struct FileEntry {
  std::shared_ptr<const facemorph::KeyframeSource> source;
  facemorph::FileInfo info;
};

// A table of objects named by handles: (kind, generation, slot) packed into a pointer-sized value
// that is never dereferenced. Closing bumps the slot's generation, so every copy of the old handle
// is stale forever (FM_ERROR_CLOSED_HANDLE) and a slot reused by a new object never answers to
// the old handle. Lookups copy a shared_ptr under the lock: an object closed on another thread
// while a call uses it lives until that call returns. The table grows only to the most handles
// open at once.
template <typename T>
class HandleTable {
  static constexpr bool kWide = sizeof(uintptr_t) >= 8;
  static constexpr unsigned kSlotBits = kWide ? 24 : 12, kGenerationBits = kWide ? 32 : 16;
  static constexpr uintptr_t kSlotMask = (uintptr_t{1} << kSlotBits) - 1, kGenerationMask = (uintptr_t{1} << kGenerationBits) - 1;

 public:
  HandleTable(uintptr_t kind, const char* type) : kind_(kind), type_(type) {}

  uintptr_t add(std::shared_ptr<T> object) {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t slot;
    if (!free_.empty()) {
      slot = free_.back();
      free_.pop_back();
    } else {
      if (slots_.size() >= kSlotMask) throw Error(ErrorCode::kOutOfMemory, std::string("too many open ") + type_ + " handles");
      slot = slots_.size();
      slots_.emplace_back();
    }
    slots_[slot].object = std::move(object);
    return (kind_ << (kSlotBits + kGenerationBits)) | ((slots_[slot].generation & kGenerationMask) << kSlotBits) | (slot + 1);
  }

  // The object `handle` names; kInvalidArgument for NULL or another kind, kClosedHandle once closed.
  std::shared_ptr<T> get(const void* handle, const char* name) {
    std::lock_guard<std::mutex> lock(mutex_);
    return slot_of(handle, name).object;
  }

  // Closes `handle` (kClosedHandle when it already is).
  void remove(const void* handle, const char* name) {
    std::shared_ptr<T> released;  // freed after the lock is let go
    {
      std::lock_guard<std::mutex> lock(mutex_);
      Slot& slot = slot_of(handle, name);
      released = std::move(slot.object);
      ++slot.generation;
      free_.push_back(static_cast<size_t>(&slot - slots_.data()));
    }
  }

 private:
  struct Slot {
    uintptr_t generation = 1;
    std::shared_ptr<T> object;
  };

  Slot& slot_of(const void* handle, const char* name) {
    const auto value = reinterpret_cast<uintptr_t>(handle);
    if (value == 0) throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is NULL");
    const uintptr_t slot = value & kSlotMask;
    if ((value >> (kSlotBits + kGenerationBits)) != kind_ || slot == 0 || slot > slots_.size()) {
      throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is not an " + type_ + " handle");
    }
    Slot& s = slots_[slot - 1];
    const uintptr_t generation = (value >> kSlotBits) & kGenerationMask;
    if (generation != (s.generation & kGenerationMask) || !s.object) {
      throw Error(ErrorCode::kClosedHandle, std::string(name) + " is an " + type_ + " handle that was already closed");
    }
    return s;
  }

  std::mutex mutex_;
  std::vector<Slot> slots_;
  std::vector<size_t> free_;
  const uintptr_t kind_;
  const char* type_;
};

// Never destroyed: a handle closed from another static destructor at exit still finds its table.
HandleTable<FileEntry>& files() {
  static auto* table = new HandleTable<FileEntry>(1, "fm_file");
  return *table;
}
HandleTable<facemorph::Decoder>& decoders() {
  static auto* table = new HandleTable<facemorph::Decoder>(2, "fm_decoder");
  return *table;
}

std::shared_ptr<FileEntry> check_file(const fm_file* file, const char* name = "file") { return files().get(file, name); }

std::shared_ptr<facemorph::Decoder> check_decoder(const fm_decoder* decoder) { return decoders().get(decoder, "decoder"); }

// Whether a caller's struct of `struct_size` bytes holds the whole field at [offset, offset + size):
// the growth rule of every struct of the API (a field appended later lies beyond an older caller's
// struct_size and is neither read nor written).
constexpr bool covers(size_t struct_size, size_t offset, size_t size) { return struct_size >= offset + size; }
#define FM_COVERS(object, type, field) covers((object)->struct_size, offsetof(type, field), sizeof((object)->field))

void check_struct_size(size_t struct_size, const char* name) {
  if (struct_size == 0) throw Error(ErrorCode::kInvalidArgument, std::string(name) + "->struct_size is 0 (set it to sizeof the struct)");
}

facemorph::DecoderLimits limits_of(const fm_decoder_options* options) {
  facemorph::DecoderLimits limits;
  if (options == nullptr) return limits;
  if (options->struct_size == 0) throw Error(ErrorCode::kInvalidArgument, "options->struct_size is 0 (fm_decoder_options_init sets it)");
  // Fields the caller's struct has; later ones keep their defaults.
  if (FM_COVERS(options, fm_decoder_options, max_grid_n)) {
    limits.max_grid_n = static_cast<int>(std::min<uint32_t>(options->max_grid_n, facemorph::kMaxGridSize));
  }
  if (FM_COVERS(options, fm_decoder_options, max_keyframes)) limits.max_keyframes = options->max_keyframes;
  if (FM_COVERS(options, fm_decoder_options, max_texture_size)) {
    limits.max_texture_size = static_cast<int>(std::min<uint32_t>(options->max_texture_size, 1u << 20));
  }
  if (FM_COVERS(options, fm_decoder_options, max_memory_bytes)) limits.max_memory_bytes = options->max_memory_bytes;
  if (FM_COVERS(options, fm_decoder_options, max_work)) limits.max_work = options->max_work;  // 1.2
  facemorph::check_decoder_limits(limits, "options");
  return limits;
}

void check_pointer(const void* pointer, const char* name) {
  if (pointer == nullptr) throw Error(ErrorCode::kInvalidArgument, std::string(name) + " is NULL");
}

fm_status open_into(std::shared_ptr<const facemorph::KeyframeSource> source, fm_file** file) {
  auto entry = std::make_shared<FileEntry>();
  entry->info = facemorph::file_info(*source);
  entry->source = std::move(source);
  *file = reinterpret_cast<fm_file*>(files().add(std::move(entry)));
  return ok();
}

fm_status open_path(const char* function, const char* path, const fm_decoder_options* options, fm_file** file) {
  return guarded(function, [&] {
    check_pointer(file, "file");
    *file = nullptr;
    check_pointer(path, "path");
    const facemorph::DecoderLimits limits = limits_of(options);
    return open_into(facemorph::open_sequence_file(path, limits), file);
  });
}

fm_status open_bytes(const char* function, const void* data, size_t size, const fm_decoder_options* options, fm_file** file,
                     bool borrowed = false) {
  return guarded(function, [&] {
    check_pointer(file, "file");
    *file = nullptr;
    if (data == nullptr && size > 0) throw Error(ErrorCode::kInvalidArgument, "data is NULL");
    const facemorph::DecoderLimits limits = limits_of(options);
    const std::span<const uint8_t> bytes(static_cast<const uint8_t*>(data), data == nullptr ? 0 : size);
    if (borrowed) return open_into(facemorph::open_borrowed_sequence_source(bytes, "memory", limits), file);
    return open_into(facemorph::open_sequence_memory(bytes, "memory", limits), file);
  });
}

// A buffer's element count from its size in bytes; a NULL buffer is an empty span.
template <typename T>
std::span<T> span_of(T* data, size_t bytes) {
  return data == nullptr ? std::span<T>() : std::span<T>(data, bytes / sizeof(T));
}

// A caller's buffer as *frame gives it: its pointer and its size in bytes.
template <typename T>
struct CallerBuffer {
  T* data = nullptr;
  size_t bytes = 0;
  // A buffer given (not NULL) but smaller than one element: too small, not "not wanted".
  bool tiny() const { return data != nullptr && bytes < sizeof(T); }
  std::span<T> span() const { return span_of(data, bytes); }
};

// The buffer `field` of *frame with its size `field`_bytes, read only where the caller's struct
// holds both (spec/api.md §3); NULL (not wanted) otherwise. Every use of a buffer goes through
// what this read, so no field beyond struct_size is ever loaded, not even for a check.
#define FM_FRAME_BUFFER(frame, field)                                                                          \
  (FM_COVERS(frame, fm_frame, field) && FM_COVERS(frame, fm_frame, field##_bytes)                              \
       ? CallerBuffer<std::remove_pointer_t<decltype((frame)->field)>>{(frame)->field, (frame)->field##_bytes} \
       : CallerBuffer<std::remove_pointer_t<decltype((frame)->field)>>{})

facemorph::FrameOptions frame_options(double t, uint32_t flags) {
  if (!std::isfinite(t)) throw Error(ErrorCode::kInvalidArgument, "t is not finite");
  constexpr uint32_t known = FM_DECODE_CLAMP | FM_DECODE_KEEP_HOLES_FILLED | FM_DECODE_FLIP_V;
  if ((flags & ~known) != 0) throw Error(ErrorCode::kInvalidArgument, "unknown decode flags " + std::to_string(flags & ~known));
  facemorph::FrameOptions options;
  options.clamp = (flags & FM_DECODE_CLAMP) != 0;
  options.keep_holes_filled = (flags & FM_DECODE_KEEP_HOLES_FILLED) != 0;
  options.flip_v = (flags & FM_DECODE_FLIP_V) != 0;
  return options;
}

void describe(const facemorph::FrameInfo& info, fm_frame* frame) {
  if (FM_COVERS(frame, fm_frame, time)) frame->time = info.time;
  if (FM_COVERS(frame, fm_frame, vertex_count)) frame->vertex_count = static_cast<uint32_t>(info.vertex_count);
  if (FM_COVERS(frame, fm_frame, triangle_count)) frame->triangle_count = static_cast<uint32_t>(info.triangle_count);
  if (FM_COVERS(frame, fm_frame, texture_size)) frame->texture_size = static_cast<uint32_t>(info.texture_size);
  if (FM_COVERS(frame, fm_frame, iterations)) frame->iterations = static_cast<uint32_t>(info.iterations);
  if (FM_COVERS(frame, fm_frame, fell_back)) frame->fell_back = info.fell_back ? 1 : 0;
  if (FM_COVERS(frame, fm_frame, hole_level_count)) frame->hole_level_count = static_cast<uint32_t>(info.hole_level_count);  // 1.3
}

}  // namespace

extern "C" {

FM_API const char* fm_status_name(fm_status status) {
  if (status < 0 || status >= facemorph::kErrorCodeCount) return "unknown";
  return facemorph::error_code_name(static_cast<ErrorCode>(status));
}

FM_API const char* fm_last_error_message(void) { return last_message().c_str(); }

FM_API const char* fm_version(void) { return FACEMORPH_VERSION; }

FM_API uint32_t fm_version_number(void) { return FACEMORPH_VERSION_NUMBER; }

FM_API fm_status fm_file_open(const char* path, fm_file** file) { return open_path("fm_file_open", path, nullptr, file); }

FM_API fm_status fm_file_open_memory(const void* data, size_t size, fm_file** file) {
  return open_bytes("fm_file_open_memory", data, size, nullptr, file);
}

FM_API fm_status fm_file_open_with_options(const char* path, const fm_decoder_options* options, fm_file** file) {
  return open_path("fm_file_open_with_options", path, options, file);
}

FM_API fm_status fm_file_open_memory_with_options(const void* data, size_t size, const fm_decoder_options* options, fm_file** file) {
  return open_bytes("fm_file_open_memory_with_options", data, size, options, file);
}

FM_API fm_status fm_file_release(fm_file* file) {
  return guarded("fm_file_release", [&] {
    files().remove(file, "file");
    return ok();
  });
}

FM_API void fm_file_close(fm_file* file) {
  if (file != nullptr) (void)fm_file_release(file);
}

FM_API fm_status fm_file_get_info(const fm_file* file, fm_info* info) {
  return guarded("fm_file_get_info", [&] {
    const std::shared_ptr<FileEntry> entry = check_file(file);
    check_pointer(info, "info");
    check_struct_size(info->struct_size, "info");
    const facemorph::FileInfo& in = entry->info;
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
    // The names are the enumerations' tables' (fields.hpp, spline.hpp), each shorter than its field.
    std::strncpy(out.representation, facemorph::representation_name(in.representation), sizeof out.representation - 1);
    std::strncpy(out.spline, facemorph::spline_kind_name(in.spline), sizeof out.spline - 1);
    out.fixed_node_count = static_cast<uint32_t>(in.fixed_node_count);
    // The fields the caller's struct holds (all of them in 1.0), in their order; struct_size stays.
    size_t end = 0;
#define FM_INFO_FIELD(field) \
  if (FM_COVERS(info, fm_info, field)) end = offsetof(fm_info, field) + sizeof out.field;
    FM_INFO_FIELD(fps)
    FM_INFO_FIELD(first_time)
    FM_INFO_FIELD(last_time) FM_INFO_FIELD(duration) FM_INFO_FIELD(range_begin) FM_INFO_FIELD(range_end) FM_INFO_FIELD(keyframe_count)
        FM_INFO_FIELD(grid_n) FM_INFO_FIELD(max_vertex_count) FM_INFO_FIELD(max_triangle_count) FM_INFO_FIELD(grid_vertex_count)
            FM_INFO_FIELD(grid_triangle_count) FM_INFO_FIELD(has_holes) FM_INFO_FIELD(texture_size) FM_INFO_FIELD(units)
                FM_INFO_FIELD(representation) FM_INFO_FIELD(spline) FM_INFO_FIELD(fixed_node_count)
#undef FM_INFO_FIELD
                    const size_t begin = offsetof(fm_info, struct_size) + sizeof out.struct_size;
    if (end > begin) std::memcpy(reinterpret_cast<char*>(info) + begin, reinterpret_cast<const char*>(&out) + begin, end - begin);
    return ok();
  });
}

FM_API fm_status fm_file_get_keyframe_times(const fm_file* file, double* times, size_t capacity, size_t* count) {
  return guarded("fm_file_get_keyframe_times", [&] {
    const std::shared_ptr<FileEntry> entry = check_file(file);
    check_pointer(count, "count");
    const std::vector<double>& keys = entry->info.keyframe_times;
    *count = keys.size();
    if (times == nullptr && capacity == 0) return ok();  // the count alone was asked for: not an error
    if (capacity < keys.size()) {
      throw Error(ErrorCode::kBufferTooSmall, std::to_string(keys.size()) + " keyframe times, room for " + std::to_string(capacity));
    }
    check_pointer(times, "times");
    std::copy(keys.begin(), keys.end(), times);
    return ok();
  });
}

FM_API fm_status fm_decoder_create(const fm_file* file, fm_decoder** decoder) {
  return guarded("fm_decoder_create", [&] {
    check_pointer(decoder, "decoder");
    *decoder = nullptr;
    const std::shared_ptr<FileEntry> entry = check_file(file);
    *decoder = reinterpret_cast<fm_decoder*>(decoders().add(std::make_shared<facemorph::Decoder>(entry->source)));
    return ok();
  });
}

FM_API fm_status fm_decoder_release(fm_decoder* decoder) {
  return guarded("fm_decoder_release", [&] {
    decoders().remove(decoder, "decoder");
    return ok();
  });
}

FM_API void fm_decoder_destroy(fm_decoder* decoder) {
  if (decoder != nullptr) (void)fm_decoder_release(decoder);
}

FM_API fm_status fm_decoder_decode(fm_decoder* decoder, double t, uint32_t flags, fm_frame* frame) {
  return guarded("fm_decoder_decode", [&] {
    const std::shared_ptr<facemorph::Decoder> held = check_decoder(decoder);
    facemorph::Decoder& d = *held;
    check_pointer(frame, "frame");
    check_struct_size(frame->struct_size, "frame");
    const facemorph::FrameOptions options = frame_options(t, flags);
    // Each buffer read once, as far as struct_size reaches (the check for a tiny buffer used to
    // load every pointer and size, those beyond struct_size too: a read past an older caller's struct).
    const auto positions = FM_FRAME_BUFFER(frame, positions);
    const auto normals = FM_FRAME_BUFFER(frame, normals);
    const auto uvs = FM_FRAME_BUFFER(frame, uvs);
    const auto indices = FM_FRAME_BUFFER(frame, indices);
    const auto texture = FM_FRAME_BUFFER(frame, texture);
    const auto positions_f64 = FM_FRAME_BUFFER(frame, positions_f64);  // 1.3
    const auto uvs_f64 = FM_FRAME_BUFFER(frame, uvs_f64);
    const auto hole_levels = FM_FRAME_BUFFER(frame, hole_levels);
    facemorph::FrameBuffers buffers;
    buffers.positions = positions.span();
    buffers.normals = normals.span();
    buffers.uvs = uvs.span();
    buffers.indices = indices.span();
    buffers.texture = texture.span();
    buffers.positions_f64 = positions_f64.span();
    buffers.uvs_f64 = uvs_f64.span();
    buffers.hole_levels = hole_levels.span();
    if (positions.tiny() || normals.tiny() || uvs.tiny() || indices.tiny() || texture.tiny() || positions_f64.tiny() || uvs_f64.tiny() ||
        hole_levels.tiny()) {
      describe(d.frame_info(t, options), frame);
      throw Error(ErrorCode::kBufferTooSmall, "a buffer smaller than one element (sizes are in bytes)");
    }
    const bool wants_nothing = buffers.positions.empty() && buffers.normals.empty() && buffers.uvs.empty() && buffers.indices.empty() &&
                               buffers.texture.empty() && buffers.positions_f64.empty() && buffers.uvs_f64.empty() &&
                               buffers.hole_levels.empty();
    try {
      describe(wants_nothing ? d.frame_info(t, options) : d.decode(t, buffers, options), frame);
    } catch (const Error& e) {
      // The frame was decoded and kept: say what it needs.
      if (e.code() == ErrorCode::kBufferTooSmall) describe(d.frame_info(t, options), frame);
      throw;
    }
    return ok();
  });
}

// ---- API 1.1 ----

FM_API fm_status fm_file_open_memory_borrowed(const void* data, size_t size, const fm_decoder_options* options, fm_file** file) {
  return open_bytes("fm_file_open_memory_borrowed", data, size, options, file, /*borrowed=*/true);
}

FM_API fm_status fm_decoder_get_texture_weights(fm_decoder* decoder, double t, uint32_t flags, uint32_t* keyframes, double* weights,
                                                size_t capacity, size_t* count) {
  return guarded("fm_decoder_get_texture_weights", [&] {
    const std::shared_ptr<facemorph::Decoder> held = check_decoder(decoder);
    check_pointer(count, "count");
    if (capacity > 0) {
      check_pointer(keyframes, "keyframes");
      check_pointer(weights, "weights");
    }
    const facemorph::SplineWeights w = held->texture_weights(t, frame_options(t, flags));
    *count = w.keys.size();
    if (keyframes == nullptr && weights == nullptr && capacity == 0) return ok();  // the count alone
    if (capacity < w.keys.size()) {
      throw Error(ErrorCode::kBufferTooSmall,
                  std::to_string(w.keys.size()) + " keyframes blend at t, room for " + std::to_string(capacity));
    }
    for (size_t i = 0; i < w.keys.size(); ++i) {
      keyframes[i] = static_cast<uint32_t>(w.keys[i]);
      weights[i] = w.weights[i];
    }
    return ok();
  });
}

// ---- API 1.3 ----

FM_API fm_status fm_decoder_set_tolerance(fm_decoder* decoder, double tolerance) {
  return guarded("fm_decoder_set_tolerance", [&] {
    check_decoder(decoder)->set_tolerance(tolerance);
    return ok();
  });
}

}  // extern "C"
