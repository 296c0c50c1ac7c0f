// The player's decoder (codec/player/decoder.hpp, behind the C API) on the golden file (N = 33, 3 keyframes, texture
// 64²) and on a copy of it with holes: file and memory agree, buffers are checked before anything
// is written, the arrays keep their conventions, and a keyframe decodes as SequenceDecoder does.
#include "codec/decoder/player/decoder.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/file_io.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>

#ifndef FACEMORPH_TEST_DATA
#error "FACEMORPH_TEST_DATA must name tests/data"
#endif

namespace facemorph {
namespace {

using testing::kGoldenV2_0;

// Every array of one frame, sized for the file's largest frame.
struct Arrays {
  std::vector<float> positions, normals, uvs;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> texture;

  explicit Arrays(const FileInfo& info) {
    const auto v = static_cast<size_t>(info.max_vertex_count), f = static_cast<size_t>(info.max_triangle_count);
    positions.resize(3 * v);
    normals.resize(3 * v);
    uvs.resize(2 * v);
    indices.resize(3 * f);
    texture.resize(4 * static_cast<size_t>(info.texture_size) * static_cast<size_t>(info.texture_size));
  }
  FrameBuffers buffers() { return {positions, normals, uvs, indices, texture}; }
};

TEST(Decoder, DescribesTheGoldenFile) {
  const Decoder decoder = Decoder::open(kGoldenV2_0);
  const FileInfo& info = decoder.info();
  EXPECT_EQ(info.grid_n, 33);
  ASSERT_EQ(info.keyframe_times.size(), 3u);
  EXPECT_DOUBLE_EQ(info.keyframe_times.front(), 0.0);
  EXPECT_NEAR(info.keyframe_times.back(), 11.0 / 30, 1e-12);
  EXPECT_DOUBLE_EQ(info.fps, 30);
  EXPECT_DOUBLE_EQ(info.first_time, 0);
  EXPECT_NEAR(info.duration, 11.0 / 30, 1e-12);
  EXPECT_LT(info.range_begin, info.first_time);  // one keyframe interval of extrapolation each side
  EXPECT_GT(info.range_end, info.last_time);
  EXPECT_FALSE(info.has_holes);
  const DiskGrid grid = make_disk_grid(33);
  EXPECT_EQ(info.max_vertex_count, grid.node_count());
  EXPECT_EQ(info.max_triangle_count, static_cast<int>(grid.faces.size()));
  // Without a decoder, the same description.
  const FileInfo alone = file_info(*decoder.source());
  EXPECT_EQ(alone.keyframe_times, info.keyframe_times);
  EXPECT_EQ(alone.max_triangle_count, info.max_triangle_count);
  EXPECT_EQ(alone.range_end, info.range_end);
  EXPECT_EQ(info.max_vertex_count, info.grid_vertex_count);
  EXPECT_EQ(info.max_triangle_count, info.grid_triangle_count);
  EXPECT_TRUE(info.has_texture);
  EXPECT_EQ(info.texture_size, 64);
  EXPECT_EQ(info.units, "m");
}

TEST(Decoder, FileAndMemoryDecodeTheSame) {
  Decoder from_file = Decoder::open(kGoldenV2_0);
  std::vector<uint8_t> bytes = format::read_file(kGoldenV2_0);
  Decoder from_memory = Decoder::open_memory(bytes, "golden in memory");
  std::fill(bytes.begin(), bytes.end(), uint8_t{0});  // the decoder keeps nothing of them
  bytes.clear();
  bytes.shrink_to_fit();
  Arrays a(from_file.info()), b(from_memory.info());
  for (double t : {0.0, 0.2, 0.3}) {
    const FrameInfo fa = from_file.decode(t, a.buffers());
    const FrameInfo fb = from_memory.decode(t, b.buffers());
    EXPECT_EQ(fa.vertex_count, fb.vertex_count);
    EXPECT_EQ(fa.triangle_count, fb.triangle_count);
    EXPECT_EQ(a.positions, b.positions) << "t = " << t;
    EXPECT_EQ(a.normals, b.normals);
    EXPECT_EQ(a.uvs, b.uvs);
    EXPECT_EQ(a.indices, b.indices);
    EXPECT_EQ(a.texture, b.texture);
  }
}

TEST(Decoder, FramesKeepTheirConventions) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  Arrays a(decoder.info());
  for (double t : {-0.1, 0.0, 0.2, 0.45}) {
    const FrameInfo frame = decoder.decode(t, a.buffers());
    ASSERT_EQ(frame.vertex_count, decoder.info().grid_vertex_count);
    ASSERT_EQ(frame.triangle_count, decoder.info().grid_triangle_count);
    EXPECT_EQ(frame.texture_size, 64);
    EXPECT_GT(frame.iterations, 0);
    for (size_t v = 0; v < static_cast<size_t>(frame.vertex_count); ++v) {
      const double length = std::hypot(a.normals[3 * v], a.normals[3 * v + 1], a.normals[3 * v + 2]);
      EXPECT_NEAR(length, 1.0, 1e-5) << "vertex " << v;
      for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(a.positions[3 * v + static_cast<size_t>(k)]));
      for (int k = 0; k < 2; ++k) {
        EXPECT_GE(a.uvs[2 * v + static_cast<size_t>(k)], 0.0f);
        EXPECT_LE(a.uvs[2 * v + static_cast<size_t>(k)], 1.0f);
      }
    }
    for (size_t i = 0; i < frame.indices_size(); ++i) EXPECT_LT(a.indices[i], static_cast<uint32_t>(frame.vertex_count));
    for (size_t p = 3; p < frame.texture_bytes(); p += 4) ASSERT_EQ(a.texture[p], 255) << "alpha at texel " << p / 4;
  }
}

TEST(Decoder, NormalsPointToTheCounterClockwiseSide) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  Arrays a(decoder.info());
  const FrameInfo frame = decoder.decode(0.2, a.buffers());
  // Each triangle's own normal agrees with its corners' vertex normals (a smooth surface).
  int agree = 0;
  for (size_t f = 0; f < static_cast<size_t>(frame.triangle_count); ++f) {
    Vec3 p[3], n = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = a.indices[3 * f + static_cast<size_t>(k)];
      p[k] = Vec3(a.positions[3 * v], a.positions[3 * v + 1], a.positions[3 * v + 2]);
      n += Vec3(a.normals[3 * v], a.normals[3 * v + 1], a.normals[3 * v + 2]);
    }
    agree += (p[1] - p[0]).cross(p[2] - p[0]).dot(n) > 0;
  }
  EXPECT_EQ(agree, frame.triangle_count);
}

TEST(Decoder, FlipVMirrorsTheUVs) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  Arrays up(decoder.info()), down(decoder.info());
  decoder.decode(0.1, up.buffers());
  FrameOptions options;
  options.flip_v = true;
  decoder.decode(0.1, down.buffers(), options);
  for (size_t v = 0; v < up.uvs.size(); v += 2) {
    EXPECT_EQ(up.uvs[v], down.uvs[v]);
    EXPECT_NEAR(up.uvs[v + 1], 1 - down.uvs[v + 1], 1e-7);
  }
}

TEST(Decoder, TooSmallBuffersAreNamedAndNothingIsWritten) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  const FileInfo& info = decoder.info();
  constexpr float kCanary = -12345.0f;
  constexpr size_t kSlack = 64;  // canaries past the capacity the decoder is told
  const size_t vertices = static_cast<size_t>(info.max_vertex_count);
  std::vector<float> positions(3 * vertices - 1 + kSlack, kCanary), normals(3 * vertices + kSlack, kCanary);
  FrameBuffers out;
  out.positions = std::span<float>(positions).first(3 * vertices - 1);  // one float short
  out.normals = std::span<float>(normals).first(3 * vertices);
  testing::expect_error(ErrorCode::kBufferTooSmall,
                        "positions needs " + std::to_string(3 * vertices) + " floats, has " + std::to_string(3 * vertices - 1),
                        [&] { decoder.decode(0.2, out); });
  // Nothing written anywhere: not in the short buffer, not in the one that was large enough.
  EXPECT_TRUE(std::all_of(positions.begin(), positions.end(), [](float x) { return x == kCanary; }));
  EXPECT_TRUE(std::all_of(normals.begin(), normals.end(), [](float x) { return x == kCanary; }));

  std::vector<uint8_t> texture(4 * 64 * 64 - 1 + kSlack, 0xab);
  std::vector<uint32_t> indices(3 * static_cast<size_t>(info.max_triangle_count) + kSlack, 0xdeadbeef);
  out = FrameBuffers{};
  out.texture = std::span<uint8_t>(texture).first(4 * 64 * 64 - 1);
  out.indices = std::span<uint32_t>(indices).first(3 * static_cast<size_t>(info.max_triangle_count) - 3);
  testing::expect_error(ErrorCode::kBufferTooSmall, "texture needs 16384 bytes", [&] { decoder.decode(0.2, out); });
  EXPECT_TRUE(std::all_of(texture.begin(), texture.end(), [](uint8_t x) { return x == 0xab; }));
  EXPECT_TRUE(std::all_of(indices.begin(), indices.end(), [](uint32_t x) { return x == 0xdeadbeef; }));

  // Exactly large enough: written up to the capacity and not one element further.
  out = FrameBuffers{};
  out.positions = std::span<float>(positions).first(3 * vertices);
  out.indices = std::span<uint32_t>(indices).first(3 * static_cast<size_t>(info.max_triangle_count));
  const FrameInfo frame = decoder.decode(0.2, out);
  EXPECT_EQ(frame.positions_size(), 3 * vertices);
  EXPECT_NE(positions[3 * vertices - 1], kCanary);
  EXPECT_TRUE(std::all_of(positions.begin() + static_cast<ptrdiff_t>(3 * vertices), positions.end(), [](float x) { return x == kCanary; }));
  EXPECT_TRUE(std::all_of(indices.begin() + static_cast<ptrdiff_t>(frame.indices_size()), indices.end(),
                          [](uint32_t x) { return x == 0xdeadbeef; }));
}

TEST(Decoder, KeyframeTimeDecodesAsTheSequenceDecoder) {
  const auto sequence = std::make_shared<const Sequence>(read_sequence_file(kGoldenV2_0));
  SequenceDecoder reference(sequence);
  Decoder decoder(sequence);
  Arrays a(decoder.info());
  for (double t : decoder.info().keyframe_times) {
    const DecodedFrame expected = reference.decode(t);
    const FrameInfo frame = decoder.decode(t, a.buffers());
    EXPECT_DOUBLE_EQ(frame.time, expected.time);
    EXPECT_EQ(frame.iterations, expected.iterations);
    ASSERT_EQ(frame.vertex_count, expected.mesh.vertex_count());
    for (size_t v = 0; v < expected.mesh.positions.size(); ++v) {
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(a.positions[3 * v + static_cast<size_t>(k)], static_cast<float>(expected.mesh.positions[v][k]))
            << "t = " << t << ", vertex " << v;
    }
    ASSERT_EQ(frame.triangle_count, expected.mesh.face_count());
    for (size_t f = 0; f < expected.mesh.faces.size(); ++f) {
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(a.indices[3 * f + static_cast<size_t>(k)], static_cast<uint32_t>(expected.mesh.faces[f][static_cast<size_t>(k)]));
    }
    for (size_t p = 0; p < expected.texture.pixels.size() / 3; ++p) {
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(a.texture[4 * p + static_cast<size_t>(c)], expected.texture.pixels[3 * p + static_cast<size_t>(c)]);
    }
  }
}

TEST(Decoder, OutOfRangeUnlessClamped) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  Arrays a(decoder.info());
  testing::expect_error(ErrorCode::kOutOfRange, "outside the range", [&] { decoder.decode(5.0, a.buffers()); });
  testing::expect_error(ErrorCode::kInvalidArgument, "not finite", [&] { decoder.decode(std::nan(""), a.buffers()); });
  FrameOptions clamp;
  clamp.clamp = true;
  EXPECT_DOUBLE_EQ(decoder.decode(5.0, a.buffers(), clamp).time, decoder.info().range_end);
}

TEST(Decoder, FrameInfoKeepsTheFrameForTheDecode) {
  Decoder decoder = Decoder::open(kGoldenV2_0);
  const FrameInfo asked = decoder.frame_info(0.25);
  EXPECT_EQ(asked.vertex_count, decoder.info().grid_vertex_count);
  std::vector<float> positions(asked.positions_size());
  const FrameInfo decoded = decoder.decode(0.25, {.positions = positions});
  EXPECT_EQ(decoded.vertex_count, asked.vertex_count);
  EXPECT_EQ(decoded.iterations, asked.iterations);
}

TEST(Decoder, DecodersShareOneFileAcrossThreads) {
  const auto sequence = open_sequence_file(kGoldenV2_0);
  std::vector<std::vector<float>> results(2);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < results.size(); ++i) {
    threads.emplace_back([&, i] {
      Decoder decoder(sequence);
      Arrays a(decoder.info());
      for (double t : {0.05, 0.15, 0.25, 0.35}) {
        decoder.decode(t, a.buffers());
        results[i].insert(results[i].end(), a.positions.begin(), a.positions.end());
      }
    });
  }
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(results[0], results[1]);
  EXPECT_EQ(sequence.use_count(), 1);
}

// The golden sequence with a hole (an opening eye) whose radius changes between keyframes, through
// the container: the cut mesh changes from frame to frame.
std::shared_ptr<const KeyframeSource> with_holes() {
  Sequence sequence = read_sequence_file(kGoldenV2_0);
  const DiskGrid grid = make_disk_grid(sequence.grid_n);
  const double radii[] = {0.12, 0.25, 0.05};
  for (size_t k = 0; k < sequence.keyframes.size(); ++k) {
    std::vector<double>& level = sequence.keyframes[k].hole_level;
    level.clear();
    for (const Vec2& w : grid.nodes) level.push_back(std::min((w - Vec2(0.3, 0.2)).norm() - radii[k % 3], kHoleLevelBand));
  }
  const std::vector<uint8_t> bytes = encode_sequence_file(sequence, {});
  return open_sequence_memory(bytes, "golden with holes");
}

TEST(Decoder, HolesChangeTheCountsWithinTheBounds) {
  Decoder decoder(with_holes());
  const FileInfo& info = decoder.info();
  EXPECT_TRUE(info.has_holes);
  EXPECT_GT(info.max_vertex_count, info.grid_vertex_count);
  EXPECT_GT(info.max_triangle_count, info.grid_triangle_count);
  Arrays a(info);
  std::vector<int> counts;
  for (double t : {0.0, 0.1, 0.2, 0.3}) {
    const FrameInfo frame = decoder.decode(t, a.buffers());
    EXPECT_LE(frame.vertex_count, info.max_vertex_count);
    EXPECT_LE(frame.triangle_count, info.max_triangle_count);
    for (size_t i = 0; i < frame.indices_size(); ++i) ASSERT_LT(a.indices[i], static_cast<uint32_t>(frame.vertex_count));
    for (size_t v = 0; v < static_cast<size_t>(frame.vertex_count); ++v) {
      EXPECT_NEAR(std::hypot(a.normals[3 * v], a.normals[3 * v + 1], a.normals[3 * v + 2]), 1.0, 1e-5);
    }
    counts.push_back(frame.vertex_count);
  }
  EXPECT_NE(counts.front(), counts[1]);  // the hole's rim changes: so does the mesh
  EXPECT_TRUE(std::any_of(counts.begin(), counts.end(), [&](int n) { return n != info.grid_vertex_count; }));
  // Kept filled, the topology is G's.
  FrameOptions filled;
  filled.keep_holes_filled = true;
  EXPECT_EQ(decoder.decode(0.1, a.buffers(), filled).vertex_count, info.grid_vertex_count);
  // Buffers of the grid's size are too small for no frame of it without holes, but for the cut
  // frame they are the actual need: ask first, then decode.
  const FrameInfo asked = decoder.frame_info(0.15);
  std::vector<float> exact(asked.positions_size());
  EXPECT_EQ(decoder.decode(0.15, {.positions = exact}).vertex_count, asked.vertex_count);
  std::vector<float> short_by_one(asked.positions_size() - 1);
  testing::expect_error(ErrorCode::kBufferTooSmall, "positions needs", [&] { decoder.decode(0.15, {.positions = short_by_one}); });
}

// API 1.3's arrays are SequenceDecoder's own numbers: positions and UVs in double precision bit for
// bit, the hole levels per node of G whether the holes are cut or not (none in a file without
// holes), and UV v flipped as the float UVs are.
TEST(Decoder, DoubleArraysAndHoleLevelsAreTheSequenceDecoders) {
  for (const bool holes : {false, true}) {
    SCOPED_TRACE(holes ? "with holes" : "golden file");
    const std::shared_ptr<const KeyframeSource> source = holes ? with_holes() : open_sequence_file(kGoldenV2_0);
    SequenceDecoder reference(source);
    Decoder decoder(source);
    for (const bool filled : {false, true}) {
      FrameOptions options;
      options.keep_holes_filled = filled;
      DecodeOptions reference_options;
      reference_options.cut_holes = !filled;
      for (double t : {0.05, 0.17, 0.3}) {
        const DecodedFrame expected = reference.decode(t, reference_options);
        const FrameInfo asked = decoder.frame_info(t, options);
        std::vector<double> positions(asked.positions_size()), uvs(asked.uvs_size()), levels(asked.hole_levels_size(), 7.0);
        const FrameInfo frame = decoder.decode(t, {.positions_f64 = positions, .uvs_f64 = uvs, .hole_levels = levels}, options);
        ASSERT_EQ(frame.vertex_count, expected.mesh.vertex_count());
        for (size_t v = 0; v < expected.mesh.positions.size(); ++v) {
          for (int k = 0; k < 3; ++k) ASSERT_EQ(positions[3 * v + static_cast<size_t>(k)], expected.mesh.positions[v][k]) << "vertex " << v;
          ASSERT_EQ(uvs[2 * v], expected.mesh.uvs[v].x());
          ASSERT_EQ(uvs[2 * v + 1], expected.mesh.uvs[v].y());
        }
        EXPECT_EQ(frame.hole_level_count, holes ? decoder.info().grid_vertex_count : 0);
        EXPECT_EQ(levels, expected.hole_level);
        if (holes) {
          EXPECT_TRUE(std::any_of(levels.begin(), levels.end(), [](double l) { return l < 0; }));
          EXPECT_TRUE(std::any_of(levels.begin(), levels.end(), [](double l) { return l > 0; }));
        }
      }
    }
  }
  Decoder decoder = Decoder::open(kGoldenV2_0);
  FrameOptions flip;
  flip.flip_v = true;
  const FrameInfo asked = decoder.frame_info(0.2);
  std::vector<double> up(asked.uvs_size()), down(asked.uvs_size());
  decoder.decode(0.2, {.uvs_f64 = up});
  decoder.decode(0.2, {.uvs_f64 = down}, flip);
  for (size_t v = 0; v < up.size() / 2; ++v) {
    EXPECT_EQ(down[2 * v], up[2 * v]);
    EXPECT_EQ(down[2 * v + 1], 1 - up[2 * v + 1]);
  }
  std::vector<double> short_by_one(asked.positions_size() - 1);
  testing::expect_error(ErrorCode::kBufferTooSmall, "positions_f64 needs", [&] { decoder.decode(0.2, {.positions_f64 = short_by_one}); });
}

// set_tolerance reaches the reconstruction: frames decode as SequenceDecoder's with that tolerance,
// a coarser one in fewer iterations; a tolerance outside (0, 0.01] is refused.
TEST(Decoder, ToleranceIsTheReconstructions) {
  const auto source = open_sequence_file(kGoldenV2_0);
  SequenceDecoder reference(source);
  Decoder coarse(source), fine(source);
  coarse.set_tolerance(1e-3);
  DecodeOptions reference_options;
  reference_options.reconstruct.tolerance = 1e-3;
  int coarse_iterations = 0, fine_iterations = 0;
  for (double t : {0.05, 0.17, 0.3}) {
    const DecodedFrame expected = reference.decode(t, reference_options);
    std::vector<double> positions(coarse.frame_info(t).positions_size());
    const FrameInfo frame = coarse.decode(t, {.positions_f64 = positions});
    EXPECT_EQ(frame.iterations, expected.iterations);
    for (size_t v = 0; v < expected.mesh.positions.size(); ++v) ASSERT_EQ(positions[3 * v], expected.mesh.positions[v].x());
    coarse_iterations += frame.iterations;
    fine_iterations += fine.frame_info(t).iterations;
  }
  EXPECT_LT(coarse_iterations, fine_iterations);
  for (double bad : {0.0, -1e-5, 0.02, std::nan("")}) {
    testing::expect_error(ErrorCode::kInvalidArgument, "tolerance", [&] { coarse.set_tolerance(bad); });
  }
}

TEST(AreaWeightedNormals, WeightByArea) {
  // Two triangles meeting at vertex 0 at right angles: normal +z with area 2, +y with area 1/2.
  const std::vector<Vec3> p = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, {0, 0, 1}, {1, 0, 0}};
  const std::vector<Face> f = {{0, 1, 2}, {0, 3, 4}};
  std::vector<float> n(3 * p.size());
  area_weighted_normals(p, f, n);
  const Vec3 a = (p[1] - p[0]).cross(p[2] - p[0]), b = (p[3] - p[0]).cross(p[4] - p[0]);
  const Vec3 expected = (a + b).normalized();
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(n[static_cast<size_t>(k)], expected[k], 1e-6);
  EXPECT_NEAR(Vec3(n[3], n[4], n[5]).norm(), 1.0, 1e-6);
  testing::expect_error(ErrorCode::kInvalidArgument, "out of range", [&] {
    const std::vector<Face> bad = {{0, 1, 7}};
    area_weighted_normals(p, bad, n);
  });
}

}  // namespace
}  // namespace facemorph
