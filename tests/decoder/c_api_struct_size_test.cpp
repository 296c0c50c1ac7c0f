// The growth rule of the C API (facemorph.h, spec/api.md §3) at every size a caller may pass: each
// struct that crosses the API (fm_frame, fm_info, fm_decoder_options) handed in with struct_size
// from 8 (struct_size alone) up to sizeof, laid out where a byte read or written past struct_size
// is caught. The review of issue 46 found fm_decoder_decode reading fm_frame fields beyond an 8- or
// 16-byte struct (valgrind: 5 invalid reads of 8 bytes); these tests fail on that.
#include "facemorph.h"

#include "tests/decoder/c_api_opened.hpp"
#include "tests/test_util.hpp"

#include "format/file_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#if defined(__unix__) || defined(__APPLE__)
#include <sys/mman.h>
#include <unistd.h>
#define FM_TEST_GUARD_PAGE 1
#endif

#ifndef FACEMORPH_TEST_DATA
#error "FACEMORPH_TEST_DATA must name tests/data"
#endif

namespace {

using facemorph::testing::CApiOpened;
using facemorph::testing::kGoldenV2_0;

// A field of a struct of the API: where it lies.
struct Field {
  const char* name;
  size_t offset, size;
  // Whether a caller's struct of `struct_size` bytes holds all of it (spec/api.md §3, rule 2).
  bool inside(size_t struct_size) const { return struct_size >= offset + size; }
};
#define FM_FIELD(type, field) \
  Field { #field, offsetof(type, field), sizeof(type::field) }

constexpr size_t round_up(size_t n, size_t alignment) { return (n + alignment - 1) / alignment * alignment; }

// The sizes API 1.0 and 1.1 compiled these structs to (tests/consumer/api-1.0/facemorph.h; 1.1
// appended functions only): each ended at the field named here, sizeof rounding it up to the
// struct's alignment. They are among the sizes every test below runs (8 up to today's sizeof), and
// stay so when fields are appended.
constexpr size_t kFrameSize1_0 = round_up(offsetof(fm_frame, fell_back) + sizeof(uint32_t), alignof(fm_frame));
constexpr size_t kInfoSize1_0 = round_up(offsetof(fm_info, units) + sizeof(fm_info::units), alignof(fm_info));
constexpr size_t kOptionsSize1_0 = round_up(offsetof(fm_decoder_options, max_memory_bytes) + sizeof(uint64_t), alignof(fm_decoder_options));
static_assert(kFrameSize1_0 <= sizeof(fm_frame) && kInfoSize1_0 <= sizeof(fm_info) && kOptionsSize1_0 <= sizeof(fm_decoder_options));

// Every struct_size from one that holds struct_size alone (8 and 16 among them, as in the review)
// to today's sizeof: each field's start and end, the sizes that cut a field in two, and the 1.0
// and 1.1 sizes.
std::vector<size_t> every_size(size_t full) {
  std::vector<size_t> sizes;
  for (size_t s = sizeof(size_t); s <= full; ++s) sizes.push_back(s);
  return sizes;
}

// What one call left in the caller's struct_size bytes, and its status.
struct Outcome {
  std::string placement;
  fm_status status = FM_OK;
  std::vector<unsigned char> bytes;
};

constexpr unsigned char kGuard = 0xA5;
constexpr size_t kGuardBytes = 64;

// Runs `call(Struct*)` (which returns the fm_status of the API call) on `prototype` with
// struct_size `size`, the struct placed three ways so that a byte touched past struct_size is
// caught:
//   heap: the first `size` bytes in a heap block of exactly `size` bytes. AddressSanitizer (the CI's
//     clang ASan + UBSan run) and valgrind (Valgrind.CApiHandleMisuse runs CApi.*) report any read
//     or write past it.
//   guarded: the whole prototype (its fields beyond struct_size set to values the library must not
//     act on) and kGuardBytes of kGuard after it: every byte from struct_size on must come back as
//     it was, in every build.
//   page end (POSIX, sizes that keep the struct aligned): the struct ends where a page that may not
//     be touched begins, so a read past it faults in every build, sanitizers or not.
// Returns each placement's outcome.
template <typename Struct, typename Call>
std::vector<Outcome> run_placed(const Struct& prototype, size_t size, Call&& call) {
  // The bytes the caller hands in: the prototype as it lies in memory (padding included), struct_size set.
  std::vector<unsigned char> image(sizeof(Struct));
  std::memcpy(image.data(), &prototype, sizeof(Struct));
  std::memcpy(image.data(), &size, sizeof size);  // struct_size is the first field (offset 0)
  std::vector<Outcome> outcomes;

  {
    SCOPED_TRACE("heap block of exactly struct_size bytes");
    const std::unique_ptr<unsigned char[]> block(new unsigned char[size]);  // aligned for any fundamental type
    std::memcpy(block.get(), image.data(), size);
    const fm_status status = call(reinterpret_cast<Struct*>(block.get()));
    outcomes.push_back({"heap", status, std::vector<unsigned char>(block.get(), block.get() + size)});
  }
  {
    SCOPED_TRACE("struct followed by guard bytes");
    struct alignas(Struct) Guarded {
      unsigned char bytes[sizeof(Struct) + kGuardBytes];
    } guarded;
    std::memcpy(guarded.bytes, image.data(), sizeof(Struct));
    std::memset(guarded.bytes + sizeof(Struct), kGuard, kGuardBytes);
    const Guarded before = guarded;
    const fm_status status = call(reinterpret_cast<Struct*>(guarded.bytes));
    size_t touched = 0;
    for (size_t i = size; i < sizeof guarded.bytes; ++i) touched += guarded.bytes[i] != before.bytes[i];
    EXPECT_EQ(touched, 0u) << touched << " bytes past struct_size " << size << " were written";
    outcomes.push_back({"guarded", status, std::vector<unsigned char>(guarded.bytes, guarded.bytes + size)});
  }
#ifdef FM_TEST_GUARD_PAGE
  if (size % alignof(Struct) == 0) {
    SCOPED_TRACE("struct ending where an inaccessible page begins");
    const size_t page = static_cast<size_t>(sysconf(_SC_PAGESIZE));
    void* const mapped = mmap(nullptr, 2 * page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    EXPECT_NE(mapped, MAP_FAILED);
    if (mapped != MAP_FAILED) {
      auto* const base = static_cast<unsigned char*>(mapped);
      EXPECT_EQ(mprotect(base + page, page, PROT_NONE), 0);
      unsigned char* const at = base + page - size;
      std::memcpy(at, image.data(), size);
      const fm_status status = call(reinterpret_cast<Struct*>(at));
      outcomes.push_back({"page end", status, std::vector<unsigned char>(at, at + size)});
      munmap(mapped, 2 * page);
    }
  }
#endif
  return outcomes;
}

// The bytes a caller's struct of `size` bytes should hold after the call: the prototype's, with
// struct_size set and each of `written` that lies wholly inside taken from `filled`.
template <typename Struct>
std::vector<unsigned char> expected_bytes(const Struct& prototype, size_t size, const Struct& filled, const std::vector<Field>& written) {
  std::vector<unsigned char> bytes(sizeof(Struct));
  std::memcpy(bytes.data(), &prototype, sizeof(Struct));
  std::memcpy(bytes.data(), &size, sizeof size);
  for (const Field& f : written) {
    if (f.inside(size)) std::memcpy(bytes.data() + f.offset, reinterpret_cast<const unsigned char*>(&filled) + f.offset, f.size);
  }
  bytes.resize(size);
  return bytes;
}

// Names the first byte where two images differ, and the field it belongs to.
std::string first_difference(const std::vector<unsigned char>& got, const std::vector<unsigned char>& want,
                             const std::vector<Field>& fields) {
  for (size_t i = 0; i < got.size() && i < want.size(); ++i) {
    if (got[i] == want[i]) continue;
    std::string where = "padding";
    for (const Field& f : fields) {
      if (i >= f.offset && i < f.offset + f.size) where = f.name;
    }
    return "byte " + std::to_string(i) + " (" + where + ")";
  }
  return got.size() == want.size() ? "" : "sizes differ";
}

const std::vector<Field> kFrameFields = {FM_FIELD(fm_frame, positions),
                                         FM_FIELD(fm_frame, positions_bytes),
                                         FM_FIELD(fm_frame, normals),
                                         FM_FIELD(fm_frame, normals_bytes),
                                         FM_FIELD(fm_frame, uvs),
                                         FM_FIELD(fm_frame, uvs_bytes),
                                         FM_FIELD(fm_frame, indices),
                                         FM_FIELD(fm_frame, indices_bytes),
                                         FM_FIELD(fm_frame, texture),
                                         FM_FIELD(fm_frame, texture_bytes),
                                         FM_FIELD(fm_frame, time),
                                         FM_FIELD(fm_frame, vertex_count),
                                         FM_FIELD(fm_frame, triangle_count),
                                         FM_FIELD(fm_frame, texture_size),
                                         FM_FIELD(fm_frame, iterations),
                                         FM_FIELD(fm_frame, fell_back),
                                         FM_FIELD(fm_frame, positions_f64),
                                         FM_FIELD(fm_frame, positions_f64_bytes),
                                         FM_FIELD(fm_frame, uvs_f64),
                                         FM_FIELD(fm_frame, uvs_f64_bytes),
                                         FM_FIELD(fm_frame, hole_levels),
                                         FM_FIELD(fm_frame, hole_levels_bytes),
                                         FM_FIELD(fm_frame, hole_level_count)};
// What fm_decoder_decode writes (on FM_OK and FM_ERROR_BUFFER_TOO_SMALL).
const std::vector<Field> kFrameOutputs = {
    FM_FIELD(fm_frame, time),       FM_FIELD(fm_frame, vertex_count), FM_FIELD(fm_frame, triangle_count),  FM_FIELD(fm_frame, texture_size),
    FM_FIELD(fm_frame, iterations), FM_FIELD(fm_frame, fell_back),    FM_FIELD(fm_frame, hole_level_count)};

// The caller's buffers (1.3's double arrays too), each filled with a pattern the decode overwrites
// where it writes.
struct Buffers {
  std::vector<float> positions, normals, uvs;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> texture;
  std::vector<double> positions_f64, uvs_f64;
  explicit Buffers(const fm_info& info)
      : positions(3 * size_t{info.max_vertex_count}),
        normals(3 * size_t{info.max_vertex_count}),
        uvs(2 * size_t{info.max_vertex_count}),
        indices(3 * size_t{info.max_triangle_count}),
        texture(4 * size_t{info.texture_size} * info.texture_size),
        positions_f64(3 * size_t{info.max_vertex_count}),
        uvs_f64(2 * size_t{info.max_vertex_count}) {
    reset();
  }
  // Back to the pattern, in place: the pointers handed out stay valid.
  void reset() {
    std::fill(positions.begin(), positions.end(), -7.0f);
    std::fill(normals.begin(), normals.end(), -7.0f);
    std::fill(uvs.begin(), uvs.end(), -7.0f);
    std::fill(indices.begin(), indices.end(), 0xA5A5A5A5u);
    std::fill(texture.begin(), texture.end(), kGuard);
    std::fill(positions_f64.begin(), positions_f64.end(), -7.0);
    std::fill(uvs_f64.begin(), uvs_f64.end(), -7.0);
  }
  void hand_to(fm_frame& frame) {
    frame.positions = positions.data();
    frame.positions_bytes = positions.size() * sizeof(float);
    frame.normals = normals.data();
    frame.normals_bytes = normals.size() * sizeof(float);
    frame.uvs = uvs.data();
    frame.uvs_bytes = uvs.size() * sizeof(float);
    frame.indices = indices.data();
    frame.indices_bytes = indices.size() * sizeof(uint32_t);
    frame.texture = texture.empty() ? nullptr : texture.data();
    frame.texture_bytes = texture.size();
    frame.positions_f64 = positions_f64.data();
    frame.positions_f64_bytes = positions_f64.size() * sizeof(double);
    frame.uvs_f64 = uvs_f64.data();
    frame.uvs_f64_bytes = uvs_f64.size() * sizeof(double);
  }
};

// fm_decoder_decode reads the buffers (pointer and size) and writes the frame's description only as
// far as struct_size reaches: a buffer whose pointer or size lies beyond is not wanted (left as it
// was), an output beyond keeps the caller's bytes; and in a struct cut anywhere, nothing past it is
// read or written. Also with a buffer smaller than one element, the FM_ERROR_BUFFER_TOO_SMALL path.
TEST(CApi, FrameIsReadAndWrittenOnlyWithinStructSizeAtEverySize) {
  CApiOpened o(kGoldenV2_0);
  ASSERT_NE(o.decoder, nullptr);
  ASSERT_GT(o.info.texture_size, 0u) << "the golden file has a texture: every buffer is exercised";
  const double t = 0.2;
  // The reference: today's whole struct, every buffer wanted.
  Buffers reference(o.info);
  fm_frame full;
  fm_frame_init(&full);
  reference.hand_to(full);
  ASSERT_EQ(fm_decoder_decode(o.decoder, t, 0, &full), FM_OK) << fm_last_error_message();
  ASSERT_EQ(full.vertex_count, 850u);

  for (const bool tiny : {false, true}) {
    for (const size_t size : every_size(sizeof(fm_frame))) {
      SCOPED_TRACE("struct_size " + std::to_string(size) + (tiny ? ", positions_bytes smaller than a float" : ""));
      Buffers buffers(o.info);
      // Every buffer given and every output set to a value the decode never writes: what lies
      // beyond struct_size must neither be used (the guarded placement holds it there) nor change.
      fm_frame prototype;
      fm_frame_init(&prototype);
      buffers.hand_to(prototype);
      if (tiny) prototype.positions_bytes = 3;
      prototype.time = -1234.5;
      prototype.vertex_count = prototype.triangle_count = prototype.texture_size = 0x5A5A5A5Au;
      prototype.iterations = prototype.fell_back = prototype.hole_level_count = 0x5A5A5A5Au;
      const bool positions_wanted = FM_FIELD(fm_frame, positions_bytes).inside(size);
      const fm_status want_status = tiny && positions_wanted ? FM_ERROR_BUFFER_TOO_SMALL : FM_OK;
      // A buffer is filled where struct_size holds its pointer and its size, and nothing is written
      // to any buffer when one is too small.
      auto filled = [&](const Field& bytes_field) { return want_status == FM_OK && bytes_field.inside(size); };

      const std::vector<Outcome> outcomes = run_placed(prototype, size, [&](fm_frame* frame) {
        buffers.reset();  // each placement starts from the pattern
        const fm_status status = fm_decoder_decode(o.decoder, t, 0, frame);
        const Buffers untouched(o.info);
        // Compared whole (the part past the frame's counts stays the pattern in both), named, not printed.
        auto check = [&](const char* name, const auto& got, const Field& bytes_field, const auto& decoded, const auto& pattern) {
          const bool wanted = filled(bytes_field);
          EXPECT_TRUE(got == (wanted ? decoded : pattern)) << name << (wanted ? " is not the decoded frame's" : " was written, not wanted");
        };
        check("positions", buffers.positions, FM_FIELD(fm_frame, positions_bytes), reference.positions, untouched.positions);
        check("normals", buffers.normals, FM_FIELD(fm_frame, normals_bytes), reference.normals, untouched.normals);
        check("uvs", buffers.uvs, FM_FIELD(fm_frame, uvs_bytes), reference.uvs, untouched.uvs);
        check("indices", buffers.indices, FM_FIELD(fm_frame, indices_bytes), reference.indices, untouched.indices);
        check("texture", buffers.texture, FM_FIELD(fm_frame, texture_bytes), reference.texture, untouched.texture);
        check("positions_f64", buffers.positions_f64, FM_FIELD(fm_frame, positions_f64_bytes), reference.positions_f64,
              untouched.positions_f64);
        check("uvs_f64", buffers.uvs_f64, FM_FIELD(fm_frame, uvs_f64_bytes), reference.uvs_f64, untouched.uvs_f64);
        return status;
      });
      const std::vector<unsigned char> want = expected_bytes(prototype, size, full, kFrameOutputs);
      for (const Outcome& out : outcomes) {
        EXPECT_EQ(out.status, want_status) << out.placement << ": " << fm_last_error_message();
        EXPECT_EQ(first_difference(out.bytes, want, kFrameFields), "") << out.placement;
      }
    }
  }
}

const std::vector<Field> kInfoFields = {FM_FIELD(fm_info, fps),
                                        FM_FIELD(fm_info, first_time),
                                        FM_FIELD(fm_info, last_time),
                                        FM_FIELD(fm_info, duration),
                                        FM_FIELD(fm_info, range_begin),
                                        FM_FIELD(fm_info, range_end),
                                        FM_FIELD(fm_info, keyframe_count),
                                        FM_FIELD(fm_info, grid_n),
                                        FM_FIELD(fm_info, max_vertex_count),
                                        FM_FIELD(fm_info, max_triangle_count),
                                        FM_FIELD(fm_info, grid_vertex_count),
                                        FM_FIELD(fm_info, grid_triangle_count),
                                        FM_FIELD(fm_info, has_holes),
                                        FM_FIELD(fm_info, texture_size),
                                        FM_FIELD(fm_info, units),
                                        FM_FIELD(fm_info, representation),
                                        FM_FIELD(fm_info, spline),
                                        FM_FIELD(fm_info, fixed_node_count)};

// fm_file_get_info fills the fields wholly inside struct_size with the file's values and leaves
// every other byte (a field cut by struct_size, and all past it) as the caller left it.
TEST(CApi, InfoIsWrittenOnlyWithinStructSizeAtEverySize) {
  CApiOpened o(kGoldenV2_0);
  ASSERT_NE(o.file, nullptr);
  ASSERT_EQ(o.info.max_vertex_count, 850u);
  fm_info prototype;
  std::memset(&prototype, 0x5A, sizeof prototype);
  for (const size_t size : every_size(sizeof(fm_info))) {
    SCOPED_TRACE("struct_size " + std::to_string(size));
    const std::vector<Outcome> outcomes = run_placed(prototype, size, [&](fm_info* info) { return fm_file_get_info(o.file, info); });
    const std::vector<unsigned char> want = expected_bytes(prototype, size, o.info, kInfoFields);
    for (const Outcome& out : outcomes) {
      EXPECT_EQ(out.status, FM_OK) << out.placement << ": " << fm_last_error_message();
      EXPECT_EQ(first_difference(out.bytes, want, kInfoFields), "") << out.placement;
    }
  }
}

// Each limit of fm_decoder_options is applied where struct_size holds it and keeps its default
// where it does not (the guarded placement holds the refusing value beyond struct_size: read, it
// would refuse the file), through all three calls that take options; the options are never written.
TEST(CApi, OptionsAreReadOnlyWithinStructSizeAtEverySize) {
  CApiOpened o(kGoldenV2_0);
  ASSERT_NE(o.file, nullptr);
  ASSERT_GE(o.info.keyframe_count, 2u);
  ASSERT_GE(o.info.grid_n, 6u);
  ASSERT_GE(o.info.texture_size, 2u);
  const std::vector<uint8_t> bytes = facemorph::format::read_file(kGoldenV2_0);
  const std::vector<Field> fields = {FM_FIELD(fm_decoder_options, max_grid_n), FM_FIELD(fm_decoder_options, max_keyframes),
                                     FM_FIELD(fm_decoder_options, max_texture_size), FM_FIELD(fm_decoder_options, max_memory_bytes)};
  struct Opener {
    const char* name;
    fm_status (*open)(const std::string& path, const std::vector<uint8_t>& bytes, const fm_decoder_options* options, fm_file** file);
  };
  const Opener openers[] = {
      {"fm_file_open_with_options", [](const std::string& path, const std::vector<uint8_t>&, const fm_decoder_options* options,
                                       fm_file** file) { return fm_file_open_with_options(path.c_str(), options, file); }},
      {"fm_file_open_memory_with_options",
       [](const std::string&, const std::vector<uint8_t>& data, const fm_decoder_options* options, fm_file** file) {
         return fm_file_open_memory_with_options(data.data(), data.size(), options, file);
       }},
      {"fm_file_open_memory_borrowed",
       [](const std::string&, const std::vector<uint8_t>& data, const fm_decoder_options* options, fm_file** file) {
         return fm_file_open_memory_borrowed(data.data(), data.size(), options, file);
       }},
  };
  for (const Field& limit : fields) {
    // The defaults, and this one limit just below what the golden file needs.
    fm_decoder_options prototype;
    fm_decoder_options_init(&prototype);
    if (std::string(limit.name) == "max_grid_n") prototype.max_grid_n = o.info.grid_n - 1;
    if (std::string(limit.name) == "max_keyframes") prototype.max_keyframes = o.info.keyframe_count - 1;
    if (std::string(limit.name) == "max_texture_size") prototype.max_texture_size = o.info.texture_size - 1;
    if (std::string(limit.name) == "max_memory_bytes") prototype.max_memory_bytes = 64;  // not even the header's chunk
    for (const Opener& opener : openers) {
      for (const size_t size : every_size(sizeof(fm_decoder_options))) {
        SCOPED_TRACE(std::string(opener.name) + ", " + limit.name + " below the file's need, struct_size " + std::to_string(size));
        const std::vector<Outcome> outcomes = run_placed(prototype, size, [&](fm_decoder_options* options) {
          fm_file* file = nullptr;
          const fm_status status = opener.open(kGoldenV2_0, bytes, options, &file);
          fm_file_close(file);
          return status;
        });
        std::vector<unsigned char> want(sizeof prototype);
        std::memcpy(want.data(), &prototype, sizeof prototype);
        std::memcpy(want.data(), &size, sizeof size);
        want.resize(size);
        for (const Outcome& out : outcomes) {
          EXPECT_EQ(out.status, limit.inside(size) ? FM_ERROR_LIMIT : FM_OK) << out.placement << ": " << fm_last_error_message();
          EXPECT_EQ(first_difference(out.bytes, want, fields), "") << out.placement << ": the options were written";
        }
      }
    }
  }
}

}  // namespace
