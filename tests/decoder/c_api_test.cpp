// The C API (facemorph.h): statuses and messages for bad handles, NULL arguments and bad files;
// frames equal to the C++ decoder's; buffer sizes in bytes, checked before anything is written.
#include "facemorph.h"

#include "tests/decoder/c_api_opened.hpp"
#include "tests/test_util.hpp"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/player/decoder.hpp"
#include "format/container.hpp"
#include "format/file_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#ifndef FACEMORPH_TEST_DATA
#error "FACEMORPH_TEST_DATA must name tests/data"
#endif

namespace {

using facemorph::testing::CApiOpened;
using facemorph::testing::kGoldenV2_0;

bool message_has(const std::string& fragment) { return std::string(fm_last_error_message()).find(fragment) != std::string::npos; }

// Owns a file and a decoder on it for one test.
TEST(CApi, VersionAndStatusNames) {
  EXPECT_STREQ(fm_version(), "0.8.0");
  EXPECT_EQ(fm_version_number(), static_cast<uint32_t>(FACEMORPH_VERSION_NUMBER));
  EXPECT_STREQ(fm_status_name(FM_OK), "ok");
  EXPECT_STREQ(fm_status_name(FM_ERROR_TRUNCATED), "truncated");
  EXPECT_STREQ(fm_status_name(FM_ERROR_BUFFER_TOO_SMALL), "buffer-too-small");
  EXPECT_STREQ(fm_status_name(FM_ERROR_INTERNAL), "internal");
  EXPECT_STREQ(fm_status_name(static_cast<fm_status>(999)), "unknown");
  EXPECT_STREQ(fm_status_name(FM_STATUS_FORCE_32BIT), "unknown");
  for (int s = FM_OK; s <= FM_ERROR_CLOSED_HANDLE; ++s) {  // the same names as the C++ codes, every one
    EXPECT_STREQ(fm_status_name(static_cast<fm_status>(s)), facemorph::error_code_name(static_cast<facemorph::ErrorCode>(s)));
  }
  EXPECT_STREQ(fm_status_name(static_cast<fm_status>(FM_ERROR_CLOSED_HANDLE + 1)), "unknown");
  EXPECT_EQ(facemorph::kErrorCodeCount, FM_ERROR_CLOSED_HANDLE + 1);
}

// API 1.4: fm_info says how the file stores its keyframes, as the container's reader reads it.
TEST(CApi, InfoOfApi1_4IsTheContainersOutline) {
  for (const std::string& path : {kGoldenV2_0, facemorph::testing::kGoldenV2_1}) {
    CApiOpened o(path);
    const auto source = facemorph::open_sequence_source(path);  // kept: outline() is a reference into it
    const facemorph::SequenceOutline& outline = source->outline();
    EXPECT_STREQ(o.info.representation, facemorph::representation_name(outline.representation)) << path;
    EXPECT_STREQ(o.info.spline, facemorph::spline_kind_name(outline.spline)) << path;
    EXPECT_EQ(o.info.fixed_node_count, outline.fixed_node_count) << path;
  }
  CApiOpened o(kGoldenV2_0);
  EXPECT_STREQ(o.info.representation, "hl+t");  // as fminfo has always described golden_v2_0.fmv
  EXPECT_STREQ(o.info.spline, "catmull-rom");
  EXPECT_GT(o.info.fixed_node_count, 0u);  // hl+t's rim band
}

TEST(CApi, OpensAndDescribesTheGoldenFile) {
  CApiOpened o(kGoldenV2_0);
  EXPECT_STREQ(fm_last_error_message(), "");
  EXPECT_EQ(o.info.grid_n, 33u);
  EXPECT_EQ(o.info.keyframe_count, 3u);
  EXPECT_EQ(o.info.texture_size, 64u);
  EXPECT_EQ(o.info.has_holes, 0u);
  EXPECT_EQ(o.info.max_vertex_count, o.info.grid_vertex_count);
  EXPECT_STREQ(o.info.units, "m");
  EXPECT_DOUBLE_EQ(o.info.fps, 30);
  size_t count = 0;
  // The count alone: a success that leaves no error message behind.
  EXPECT_EQ(fm_file_get_keyframe_times(o.file, nullptr, 0, &count), FM_OK);
  EXPECT_EQ(count, 3u);
  EXPECT_STREQ(fm_last_error_message(), "");
  double times[3] = {-1, -1, -1};
  count = 0;
  EXPECT_EQ(fm_file_get_keyframe_times(o.file, times, 2, &count), FM_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(count, 3u);
  EXPECT_EQ(times[0], -1);  // nothing copied
  EXPECT_EQ(fm_file_get_keyframe_times(o.file, times, 3, &count), FM_OK);
  EXPECT_DOUBLE_EQ(times[0], 0);
  EXPECT_GT(times[2], times[1]);
}

TEST(CApi, NullArgumentsAndBadHandles) {
  fm_file* file = reinterpret_cast<fm_file*>(0x1);
  EXPECT_EQ(fm_file_open(nullptr, &file), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(file, nullptr);  // cleared on failure
  EXPECT_TRUE(message_has("fm_file_open: path is NULL")) << fm_last_error_message();
  EXPECT_EQ(fm_file_open(kGoldenV2_0.c_str(), nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_file_open_memory(nullptr, 10, &file), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("data is NULL"));
  fm_info info;
  fm_info_init(&info);
  EXPECT_EQ(fm_file_get_info(nullptr, &info), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("file is NULL"));
  fm_decoder* decoder = nullptr;
  EXPECT_EQ(fm_decoder_create(nullptr, &decoder), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(decoder, nullptr);
  fm_frame frame;
  fm_frame_init(&frame);
  EXPECT_EQ(fm_decoder_decode(nullptr, 0.1, 0, &frame), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("decoder is NULL"));

  CApiOpened o(kGoldenV2_0);
  EXPECT_EQ(fm_file_get_info(o.file, nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_decoder_create(o.file, nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_decoder_decode(o.decoder, 0.1, 0, nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("frame is NULL"));
  // The wrong kind of handle is refused, not used.
  EXPECT_EQ(fm_decoder_decode(reinterpret_cast<fm_decoder*>(o.file), 0.1, 0, &frame), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("not an fm_decoder handle")) << fm_last_error_message();
  EXPECT_EQ(fm_file_get_info(reinterpret_cast<const fm_file*>(o.decoder), &info), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("not an fm_file handle")) << fm_last_error_message();
  fm_decoder_destroy(reinterpret_cast<fm_decoder*>(o.file));  // ignored: not a decoder
  fm_file_close(reinterpret_cast<fm_file*>(o.decoder));       // ignored: not a file
  fm_file_close(nullptr);
  fm_decoder_destroy(nullptr);
  // Bad values.
  EXPECT_EQ(fm_decoder_decode(o.decoder, std::nan(""), 0, &frame), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("not finite"));
  EXPECT_EQ(fm_decoder_decode(o.decoder, 0.1, 0x80, &frame), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("unknown decode flags"));
  EXPECT_EQ(fm_decoder_decode(o.decoder, 9.0, 0, &frame), FM_ERROR_OUT_OF_RANGE);
  EXPECT_TRUE(message_has("outside the range"));
  EXPECT_EQ(fm_decoder_decode(o.decoder, 9.0, FM_DECODE_CLAMP, &frame), FM_OK);
  EXPECT_DOUBLE_EQ(frame.time, o.info.range_end);
  EXPECT_STREQ(fm_last_error_message(), "");  // a success clears the message
}

TEST(CApi, BadFilesReturnTheirStatus) {
  fm_file* file = nullptr;
  EXPECT_EQ(fm_file_open("/nonexistent/face.fmv", &file), FM_ERROR_IO);
  EXPECT_TRUE(message_has("/nonexistent/face.fmv")) << fm_last_error_message();
  const std::vector<uint8_t> bytes = facemorph::format::read_file(kGoldenV2_0);
  EXPECT_EQ(fm_file_open_memory(bytes.data(), bytes.size() / 2, &file), FM_ERROR_TRUNCATED);
  EXPECT_EQ(file, nullptr);
  EXPECT_NE(std::string(fm_last_error_message()), "");
  EXPECT_EQ(fm_file_open_memory(bytes.data(), 0, &file), FM_ERROR_TRUNCATED);
  // A flip in the index (read at open) is refused at open; one in a keyframe's chunk when the
  // keyframe is decoded (opening reads the header and index only).
  const facemorph::format::ContainerReader reader(bytes, "golden");
  std::vector<uint8_t> flipped = bytes;
  flipped[reader.chunks()[1].offset + facemorph::format::kChunkHeaderBytes] ^= 0x10;
  EXPECT_EQ(fm_file_open_memory(flipped.data(), flipped.size(), &file), FM_ERROR_CORRUPT);
  EXPECT_TRUE(message_has("checksum mismatch in chunk KIDX")) << fm_last_error_message();
  facemorph::testing::TempDir dir;
  const std::string cut = (dir / "cut.fmv").string();
  facemorph::format::write_file_atomically(cut, std::span<const uint8_t>(bytes).first(bytes.size() - 3));
  EXPECT_EQ(fm_file_open(cut.c_str(), &file), FM_ERROR_TRUNCATED);
  EXPECT_TRUE(message_has("cut.fmv")) << fm_last_error_message();
  EXPECT_EQ(fm_file_open_memory(bytes.data(), bytes.size(), &file), FM_OK);
  fm_file_close(file);
}

TEST(CApi, DecodesAsTheCppDecoder) {
  CApiOpened o(kGoldenV2_0);
  facemorph::Decoder cpp = facemorph::Decoder::open(kGoldenV2_0);
  const size_t v = o.info.max_vertex_count, f = o.info.max_triangle_count, texels = size_t{o.info.texture_size} * o.info.texture_size;
  std::vector<float> positions(3 * v), normals(3 * v), uvs(2 * v), cpp_positions(3 * v), cpp_normals(3 * v), cpp_uvs(2 * v);
  std::vector<uint32_t> indices(3 * f), cpp_indices(3 * f);
  std::vector<uint8_t> texture(4 * texels), cpp_texture(4 * texels);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.positions = positions.data();
  frame.positions_bytes = positions.size() * sizeof(float);
  frame.normals = normals.data();
  frame.normals_bytes = normals.size() * sizeof(float);
  frame.uvs = uvs.data();
  frame.uvs_bytes = uvs.size() * sizeof(float);
  frame.indices = indices.data();
  frame.indices_bytes = indices.size() * sizeof(uint32_t);
  frame.texture = texture.data();
  frame.texture_bytes = texture.size();
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.2, FM_DECODE_FLIP_V, &frame), FM_OK) << fm_last_error_message();
  facemorph::FrameOptions options;
  options.flip_v = true;
  const facemorph::FrameInfo info = cpp.decode(0.2, {cpp_positions, cpp_normals, cpp_uvs, cpp_indices, cpp_texture}, options);
  EXPECT_EQ(frame.vertex_count, static_cast<uint32_t>(info.vertex_count));
  EXPECT_EQ(frame.triangle_count, static_cast<uint32_t>(info.triangle_count));
  EXPECT_EQ(frame.texture_size, 64u);
  EXPECT_EQ(frame.iterations, static_cast<uint32_t>(info.iterations));
  EXPECT_EQ(frame.fell_back, 0u);
  EXPECT_DOUBLE_EQ(frame.time, 0.2);
  EXPECT_EQ(positions, cpp_positions);
  EXPECT_EQ(normals, cpp_normals);
  EXPECT_EQ(uvs, cpp_uvs);
  EXPECT_EQ(indices, cpp_indices);
  EXPECT_EQ(texture, cpp_texture);
}

TEST(CApi, BufferTooSmallSaysWhatIsNeededAndWritesNothing) {
  CApiOpened o(kGoldenV2_0);
  const size_t v = o.info.max_vertex_count;
  std::vector<float> positions(3 * v + 16, -7.0f);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.positions = positions.data();
  frame.positions_bytes = (3 * v - 1) * sizeof(float);  // one float short
  EXPECT_EQ(fm_decoder_decode(o.decoder, 0.2, 0, &frame), FM_ERROR_BUFFER_TOO_SMALL);
  EXPECT_TRUE(message_has("positions needs " + std::to_string(3 * v) + " floats")) << fm_last_error_message();
  EXPECT_EQ(frame.vertex_count, static_cast<uint32_t>(v));  // what is needed
  EXPECT_TRUE(std::all_of(positions.begin(), positions.end(), [](float x) { return x == -7.0f; }));
  frame.positions_bytes = 2;  // not even one float: too small, not "not wanted"
  EXPECT_EQ(fm_decoder_decode(o.decoder, 0.2, 0, &frame), FM_ERROR_BUFFER_TOO_SMALL);
  EXPECT_TRUE(std::all_of(positions.begin(), positions.end(), [](float x) { return x == -7.0f; }));
  // Ask with no buffers, then decode with exactly the sizes asked.
  fm_frame ask;
  fm_frame_init(&ask);
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.3, 0, &ask), FM_OK);
  EXPECT_EQ(ask.vertex_count, static_cast<uint32_t>(v));
  frame.positions_bytes = 3 * sizeof(float) * ask.vertex_count;
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.3, 0, &frame), FM_OK);
  EXPECT_NE(positions[3 * v - 1], -7.0f);
  EXPECT_TRUE(std::all_of(positions.begin() + static_cast<ptrdiff_t>(3 * v), positions.end(), [](float x) { return x == -7.0f; }));
}

TEST(CApi, FileMayCloseBeforeItsDecoders) {
  fm_file* file = nullptr;
  ASSERT_EQ(fm_file_open(kGoldenV2_0.c_str(), &file), FM_OK);
  fm_decoder* decoder = nullptr;
  ASSERT_EQ(fm_decoder_create(file, &decoder), FM_OK);
  fm_file_close(file);
  fm_frame frame;
  fm_frame_init(&frame);
  EXPECT_EQ(fm_decoder_decode(decoder, 0.1, 0, &frame), FM_OK);
  EXPECT_GT(frame.vertex_count, 0u);
  fm_decoder_destroy(decoder);
}

// The growth rule of API 1.0 (spec/api.md §3): struct_size 0 is the caller's error; a caller
// compiled against a shorter struct (an older header) has only its own fields read and written.
TEST(CApi, StructsAreReadAndWrittenOnlyAsFarAsTheirStructSize) {
  CApiOpened o(kGoldenV2_0);
  fm_info info;
  fm_info_init(&info);
  info.struct_size = 0;
  EXPECT_EQ(fm_file_get_info(o.file, &info), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_TRUE(message_has("info->struct_size is 0")) << fm_last_error_message();
  // An fm_info that ends before texture_size and units: they stay as the caller left them.
  std::memset(&info, 0x5a, sizeof info);
  info.struct_size = offsetof(fm_info, texture_size);
  ASSERT_EQ(fm_file_get_info(o.file, &info), FM_OK);
  EXPECT_EQ(info.grid_n, o.info.grid_n);
  EXPECT_EQ(info.has_holes, o.info.has_holes);
  EXPECT_EQ(info.texture_size, 0x5a5a5a5au);
  EXPECT_EQ(info.units[0], 0x5a);
  EXPECT_EQ(info.struct_size, offsetof(fm_info, texture_size));  // never rewritten

  fm_frame frame;
  fm_frame_init(&frame);
  frame.struct_size = 0;
  EXPECT_EQ(fm_decoder_decode(o.decoder, 0.2, 0, &frame), FM_ERROR_INVALID_ARGUMENT);
  // An fm_frame that holds positions but ends before the outputs: positions written, counts not.
  std::vector<float> positions(3 * static_cast<size_t>(o.info.max_vertex_count), -7.0f);
  fm_frame_init(&frame);
  frame.positions = positions.data();
  frame.positions_bytes = sizeof(float) * positions.size();
  frame.normals = positions.data();  // beyond struct_size: never read
  frame.normals_bytes = 4;
  frame.vertex_count = 12345;
  frame.struct_size = offsetof(fm_frame, normals);
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.2, 0, &frame), FM_OK) << fm_last_error_message();
  EXPECT_EQ(frame.vertex_count, 12345u);
  EXPECT_NE(positions[3 * 850 - 1], -7.0f);
  // A newer caller's larger struct: the fields this library knows are served.
  struct Newer {
    fm_frame frame;
    uint64_t appended;
  } newer{};
  fm_frame_init(&newer.frame);
  newer.frame.struct_size = sizeof newer;
  newer.appended = 99;
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.2, 0, &newer.frame), FM_OK);
  EXPECT_EQ(newer.frame.vertex_count, 850u);
  EXPECT_EQ(newer.appended, 99u);
}

// Every call that fills a caller's buffer answers the count query with NULL buffers, as FM_OK.
TEST(CApi, CountQueriesSucceedWithNullBuffers) {
  CApiOpened o(kGoldenV2_0);
  size_t count = 0;
  EXPECT_EQ(fm_file_get_keyframe_times(o.file, nullptr, 0, &count), FM_OK);
  EXPECT_EQ(count, o.info.keyframe_count);
  EXPECT_STREQ(fm_last_error_message(), "");
  EXPECT_EQ(fm_file_get_keyframe_times(o.file, nullptr, 4, &count), FM_ERROR_INVALID_ARGUMENT);  // room claimed, no buffer
  fm_frame frame;
  fm_frame_init(&frame);
  ASSERT_EQ(fm_decoder_decode(o.decoder, 0.2, FM_DECODE_CLAMP, &frame), FM_OK);
  EXPECT_EQ(frame.vertex_count, 850u);
  EXPECT_GT(frame.triangle_count, 0u);
  EXPECT_EQ(frame.texture_size, o.info.texture_size);
  EXPECT_STREQ(fm_last_error_message(), "");
}

}  // namespace
