// The player's decoder (codec/player/decoder.hpp, private): SequenceDecoder's frames copied into caller-owned
// arrays of the layout a GPU takes, with the sizes checked before anything is written.
#include "codec/decoder/player/decoder.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/sequence/spline.hpp"
#include "codec/decoder/container/sequence_file.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>

namespace facemorph {

std::shared_ptr<const KeyframeSource> open_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits) {
  return open_sequence_source(path, limits);
}

std::shared_ptr<const KeyframeSource> open_sequence_memory(std::span<const uint8_t> bytes, const std::string& name,
                                                           const DecoderLimits& limits) {
  return open_sequence_source(bytes, name, limits);
}

struct Decoder::Impl {
  explicit Impl(std::shared_ptr<const KeyframeSource> source) : decoder(std::move(source)) {}

  SequenceDecoder decoder;
  // The last frame, kept so that asking its size first (frame_info) or again after
  // kBufferTooSmall costs no second decode.
  struct Key {
    double t = 0;
    bool clamp = false, keep_holes_filled = false, texture = false;
  };
  std::optional<Key> key;
  double tolerance = ReconstructOptions{}.tolerance;
  DecodedFrame frame;
  FrameInfo info;

  // `texture`: the texture must be blended; `any`: a kept frame with or without it will do (for
  // sizes only), and a new one is decoded with the texture the caller will most likely ask for next.
  const DecodedFrame& decode(double t, const FrameOptions& options, bool texture, bool any = false) {
    if (key && key->t == t && key->clamp == options.clamp && key->keep_holes_filled == options.keep_holes_filled &&
        (key->texture || !texture || any)) {
      return frame;
    }
    key.reset();  // a throw below leaves no stale frame behind
    DecodeOptions decode_options;
    decode_options.cut_holes = !options.keep_holes_filled;
    decode_options.texture = texture;
    decode_options.clamp_to_sane_range = options.clamp;
    decode_options.reconstruct.tolerance = tolerance;
    if (!std::isfinite(t)) throw Error(ErrorCode::kInvalidArgument, "decode: t is not finite");
    try {
      frame = decoder.decode(t, decode_options);
    } catch (const Error& e) {
      // t and the options are checked above: anything else that calls itself an argument error
      // here (a spline weight, a field, a pose the decoder computed) is the file's fault.
      if (e.code() == ErrorCode::kInvalidArgument) throw Error(ErrorCode::kCorrupt, e.what());
      throw;
    }
    info = FrameInfo{};
    info.time = frame.time;
    info.vertex_count = frame.mesh.vertex_count();
    info.triangle_count = frame.mesh.face_count();
    info.texture_size = decoder.outline().texture_size;
    info.iterations = frame.iterations;
    info.converged = frame.converged;
    info.fell_back = frame.fell_back;
    info.hole_level_count = static_cast<int>(frame.hole_level.size());
    key = Key{t, options.clamp, options.keep_holes_filled, texture};
    return frame;
  }
};

namespace {

FileInfo describe(const SequenceOutline& sequence) {
  FileInfo info;
  info.fps = sequence.fps;
  info.first_time = sequence.first_time;
  info.last_time = sequence.last_time;
  info.duration = sequence.last_time - sequence.first_time;
  info.keyframe_times = sequence.times;
  const TimeRange range = KeyframeSpline(info.keyframe_times, sequence.spline).sane_range();
  info.range_begin = range.begin;
  info.range_end = range.end;
  info.grid_n = sequence.grid_n;
  // G triangulates the disk with every rim node on its boundary: F = 2 I + B − 2 (Euler), without
  // building it (the decoder builds it once, with its solver).
  const DiskGridShape shape = disk_grid_shape(sequence.grid_n);
  info.grid_vertex_count = shape.interior_count + shape.rim_count;
  info.grid_triangle_count = 2 * shape.interior_count + shape.rim_count - 2;
  info.has_holes = sequence.has_holes;
  if (info.has_holes) {
    // A cut frame's vertices are kept nodes and one crossing per cut edge (G is a disk: E = V + F − 1);
    // each of G's triangles leaves at most two (a quad split in two).
    info.max_vertex_count = info.grid_vertex_count + (info.grid_vertex_count + info.grid_triangle_count - 1);
    info.max_triangle_count = 2 * info.grid_triangle_count;
  } else {
    info.max_vertex_count = info.grid_vertex_count;
    info.max_triangle_count = info.grid_triangle_count;
  }
  info.has_texture = sequence.has_texture();
  info.texture_size = sequence.texture_size;
  info.units = sequence.units;
  info.representation = sequence.representation;
  info.spline = sequence.spline;
  info.fixed_node_count = static_cast<int>(sequence.fixed_node_count);
  return info;
}

template <typename T>
void check_size(const char* what, std::span<T> buffer, size_t needed, const char* unit, std::string& problems) {
  if (!buffer.empty() && buffer.size() < needed) {
    if (!problems.empty()) problems += "; ";
    problems += std::string(what) + " needs " + std::to_string(needed) + " " + unit + ", has " + std::to_string(buffer.size());
  }
}

}  // namespace

FileInfo file_info(const Sequence& sequence) {
  validate_sequence(sequence);
  return describe(outline_of(sequence));
}

FileInfo file_info(const KeyframeSource& source) { return describe(source.outline()); }

Decoder::Decoder(std::shared_ptr<const Sequence> sequence) : Decoder(memory_source(std::move(sequence))) {}

Decoder::Decoder(std::shared_ptr<const KeyframeSource> source) {
  if (!source) throw Error(ErrorCode::kInvalidArgument, "decoder: no source");
  impl_ = std::make_unique<Impl>(source);
  source_ = std::move(source);
  info_ = describe(source_->outline());
  // The counts above follow from N; the grid the decoder built must have them.
  const DiskGrid& grid = impl_->decoder.geometry().grid();
  if (grid.node_count() != info_.grid_vertex_count || static_cast<int>(grid.faces.size()) != info_.grid_triangle_count) {
    throw Error(ErrorCode::kInternal, "decoder: G has " + std::to_string(grid.node_count()) + " nodes and " +
                                          std::to_string(grid.faces.size()) + " triangles, not " + std::to_string(info_.grid_vertex_count) +
                                          " and " + std::to_string(info_.grid_triangle_count));
  }
}

Decoder Decoder::open(const std::filesystem::path& path, const DecoderLimits& limits) { return Decoder(open_sequence_file(path, limits)); }

Decoder Decoder::open_memory(std::span<const uint8_t> bytes, const std::string& name, const DecoderLimits& limits) {
  return Decoder(open_sequence_memory(bytes, name, limits));
}

Decoder::Decoder(Decoder&&) noexcept = default;
Decoder& Decoder::operator=(Decoder&&) noexcept = default;
Decoder::~Decoder() = default;

FrameInfo Decoder::frame_info(double t, const FrameOptions& options) {
  impl_->decode(t, options, info_.has_texture, /*any=*/true);
  return impl_->info;
}

SplineWeights Decoder::texture_weights(double t, const FrameOptions& options) {
  // The weights do not depend on the texture: a new frame is decoded without it (a decoder built
  // without image codecs, whose player blends the images itself, could not make it).
  // Each keyframe named by the one whose stored texture it shows (format 2.2's shared textures), so
  // that a player finds its image in that keyframe's TEXR; one named twice keeps both its weights,
  // summed in the same order as the decoder sums them.
  SplineWeights w = impl_->decode(t, options, /*texture=*/false, /*any=*/true).weights;
  for (int32_t& k : w.keys) k = static_cast<int32_t>(source_->texture_owner(static_cast<size_t>(k)));
  return w;
}

void Decoder::set_tolerance(double tolerance) {
  if (!(tolerance > 0 && tolerance <= 0.01)) throw Error(ErrorCode::kInvalidArgument, "the tolerance must be in (0, 0.01]");
  impl_->tolerance = tolerance;
  impl_->key.reset();  // a kept frame was reconstructed to the old tolerance
}

FrameInfo Decoder::decode(double t, const FrameBuffers& out, const FrameOptions& options) {
  const DecodedFrame& frame = impl_->decode(t, options, !out.texture.empty());
  const FrameInfo& info = impl_->info;
  std::string problems;
  check_size("positions", out.positions, info.positions_size(), "floats", problems);
  check_size("normals", out.normals, info.normals_size(), "floats", problems);
  check_size("uvs", out.uvs, info.uvs_size(), "floats", problems);
  check_size("indices", out.indices, info.indices_size(), "indices", problems);
  check_size("texture", out.texture, info.texture_bytes(), "bytes", problems);
  check_size("positions_f64", out.positions_f64, info.positions_size(), "doubles", problems);
  check_size("uvs_f64", out.uvs_f64, info.uvs_size(), "doubles", problems);
  check_size("hole_levels", out.hole_levels, info.hole_levels_size(), "doubles", problems);
  if (!problems.empty()) {
    char when[64];
    std::snprintf(when, sizeof when, "t = %.6g s: ", info.time);
    throw Error(ErrorCode::kBufferTooSmall, when + problems + " (" + std::to_string(info.vertex_count) + " vertices, " +
                                                std::to_string(info.triangle_count) + " triangles)");
  }

  const TriangleMesh& mesh = frame.mesh;
  const auto vertices = static_cast<size_t>(info.vertex_count);
  if (mesh.uvs.size() != vertices || (!out.texture.empty() && frame.texture.pixels.size() != 3 * info.texture_bytes() / 4)) {
    throw Error(ErrorCode::kInternal, "decoder: the decoded frame's UVs or texture do not match its mesh");
  }
  if (!out.positions.empty()) {
    for (size_t v = 0; v < vertices; ++v) {
      for (int k = 0; k < 3; ++k) out.positions[3 * v + static_cast<size_t>(k)] = static_cast<float>(mesh.positions[v][k]);
    }
  }
  if (!out.positions_f64.empty()) {
    for (size_t v = 0; v < vertices; ++v) {
      for (int k = 0; k < 3; ++k) out.positions_f64[3 * v + static_cast<size_t>(k)] = mesh.positions[v][k];
    }
  }
  if (!out.uvs_f64.empty()) {
    for (size_t v = 0; v < vertices; ++v) {
      out.uvs_f64[2 * v] = mesh.uvs[v].x();
      out.uvs_f64[2 * v + 1] = options.flip_v ? 1 - mesh.uvs[v].y() : mesh.uvs[v].y();
    }
  }
  if (!out.hole_levels.empty()) std::copy(frame.hole_level.begin(), frame.hole_level.end(), out.hole_levels.begin());
  if (!out.normals.empty()) area_weighted_normals(mesh.positions, mesh.faces, out.normals.first(info.normals_size()));
  if (!out.uvs.empty()) {
    // Decoded meshes carry one UV per vertex (uv_faces == faces).
    for (size_t v = 0; v < vertices; ++v) {
      const Vec2& uv = mesh.uvs[v];
      out.uvs[2 * v] = static_cast<float>(uv.x());
      out.uvs[2 * v + 1] = static_cast<float>(options.flip_v ? 1 - uv.y() : uv.y());
    }
  }
  if (!out.indices.empty()) {
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      for (int k = 0; k < 3; ++k)
        out.indices[3 * f + static_cast<size_t>(k)] = static_cast<uint32_t>(mesh.faces[f][static_cast<size_t>(k)]);
    }
  }
  if (!out.texture.empty() && info.texture_size > 0) {
    const Image& texture = frame.texture;
    const size_t texels = static_cast<size_t>(texture.width) * static_cast<size_t>(texture.height);
    for (size_t p = 0; p < texels; ++p) {
      std::memcpy(&out.texture[4 * p], &texture.pixels[3 * p], 3);
      out.texture[4 * p + 3] = 255;
    }
  }
  return info;
}

}  // namespace facemorph
