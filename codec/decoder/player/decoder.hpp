// The decoder behind the player API, private to the library (the public C++ API is the header-only
// wrapper facemorph/decoder.hpp over the C API facemorph.h): open a .fmv file (or its bytes in
// memory), ask what it holds, and decode any time t into arrays the caller owns — positions,
// normals, UVs, triangle indices and the RGBA texture, the layout a GPU vertex buffer and texture
// take as they are. A thin layer over SequenceDecoder (codec/core/sequence/sequence.hpp), which keeps the
// multigrid solver of G's Laplacian and the keyframes' own decoded surfaces between calls. The C API
// (c_api.cpp) is this class behind a plain-C interface; the tools and tests use it directly.
//
// Errors: every function that can fail throws facemorph::Error (format/error.hpp) with a named
// code and a message naming the file and the reason. decode() writes nothing when it throws.
//
// Threads: a Decoder is used by one thread at a time (decode changes its state). Several Decoders
// may share one opened file — `std::shared_ptr<const KeyframeSource>` from open_sequence_file /
// open_sequence_memory, thread-safe — and decode on as many threads at once.
//
// Conventions (spec/method.md §7 and spec/container.md §8):
//   positions  the capture's frame and units (FileInfo::units: "m", "cm" or "mm"), head pose applied;
//   normals    unit, area-weighted vertex normals of the decoded triangles, pointing to the side
//              from which the triangles wind counter-clockwise (zero only for a vertex that touches
//              no triangle of non-zero area);
//   UVs        (u, v) in [0, 1]², one per vertex, UV = (w + 1) / 2 of the vertex's point w of the
//              unit disk, v up as in OBJ and OpenGL (FrameOptions::flip_v: v down, as glTF and
//              Direct3D sample images);
//   indices    three per triangle, counter-clockwise, 0-based vertex numbers;
//   texture    M × M RGBA8 texels, alpha 255, row 0 at the top (v = 1), rows packed without padding.
#pragma once

#include "codec/core/limits/decoder_limits.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "format/error.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace facemorph {

// Opens a .fmv file for decoding on demand (open_sequence_source, codec/decoder/container/sequence_file.hpp):
// the header and index are read and checked, nothing else (spec/container.md §9: kIo, kTruncated, kCorrupt, kUnsupported, each naming the
// file and the chunk; kLimit where a frame needs more than `limits` allow, found from the sizes it states before they are allocated, §10).
// Afterwards keyframes and textures are decoded when a frame needs them, into a cache bounded by limits.max_memory_bytes: memory follows
// what is played, not the file. The result is immutable to its users and thread-safe: share it between decoders and threads.
std::shared_ptr<const KeyframeSource> open_sequence_file(const std::filesystem::path& path,
                                                         const DecoderLimits& limits = kDefaultDecoderLimits);
// The same from bytes in memory. The bytes are copied (and count against the budget): the caller
// may free them at once. `name` names the source in error messages.
std::shared_ptr<const KeyframeSource> open_sequence_memory(std::span<const uint8_t> bytes, const std::string& name = "memory",
                                                           const DecoderLimits& limits = kDefaultDecoderLimits);

// What a file holds, fixed for the file.
struct FileInfo {
  double fps = 0;         // the capture's nominal frame rate (frames per second)
  double first_time = 0;  // the capture's first and last frame times, seconds
  double last_time = 0;
  double duration = 0;  // last_time - first_time, seconds
  // Times decode() serves without FrameOptions::clamp: the keyframes' span extended by one
  // keyframe interval at each end (extrapolation; ±infinity with a single keyframe, which is
  // constant); outside it decode throws kOutOfRange.
  double range_begin = 0;
  double range_end = 0;
  std::vector<double> keyframe_times;  // seconds, strictly increasing
  int grid_n = 0;                      // N of the disk grid G
  // Every decoded frame has at most this many vertices and triangles, so buffers of these sizes
  // always suffice. Without holes (or with FrameOptions::keep_holes_filled) every frame has
  // exactly these counts and the same indices; with holes cut, the counts change from frame to
  // frame (FrameInfo says each frame's) and these bounds are G's nodes plus its edges, and twice
  // its triangles.
  int max_vertex_count = 0;
  int max_triangle_count = 0;
  int grid_vertex_count = 0;  // G's nodes and triangles: every frame's counts when the topology is fixed
  int grid_triangle_count = 0;
  bool has_holes = false;  // eyes and mouth are cut out per frame: the topology changes
  bool has_texture = false;
  int texture_size = 0;  // M, texels per side (0: no texture)
  std::string units;     // "m", "cm" or "mm"
  // How the file stores its keyframes (spec/container.md §5; C API 1.4).
  Representation representation = Representation::kHLT;
  SplineKind spline = SplineKind::kLocalCubic;
  int fixed_node_count = 0;  // G's nodes stored in a boundary frame (hl+t's rim band)
};

// What a sequence holds, without a decoder (no solver built): what a player shows before it
// decodes, and what the C API's fm_file_get_info returns. Throws kInvalidArgument for a sequence
// validate_sequence rejects.
FileInfo file_info(const Sequence& sequence);
FileInfo file_info(const KeyframeSource& source);

struct FrameOptions {
  // Outside [range_begin, range_end]: clamp t into it instead of throwing kOutOfRange.
  bool clamp = false;
  // Keep the filled eyes and mouth instead of cutting them out: the topology is then fixed.
  bool keep_holes_filled = false;
  // UV v pointing down (glTF, Direct3D) instead of up (OBJ, OpenGL): v ↦ 1 − v.
  bool flip_v = false;
};

// Caller-owned outputs. An empty span is not wanted (and not computed: no normals, no texture
// blend). A span that is not empty must hold the whole array — 3 floats per vertex for positions
// and normals, 2 per vertex for UVs, 3 indices per triangle, 4 bytes per texel — or decode throws
// kBufferTooSmall naming the array and the size needed, and writes nothing anywhere.
struct FrameBuffers {
  std::span<float> positions{};
  std::span<float> normals{};
  std::span<float> uvs{};
  std::span<uint32_t> indices{};
  std::span<uint8_t> texture{};
  // API 1.3: positions and UVs as the decoder computes them, in double precision (for tools that
  // write the surface at full precision), and the hole level set, one per node of G (< 0 inside a
  // hole; FrameInfo::hole_level_count, 0 for a file without holes), whether the holes are cut or not.
  std::span<double> positions_f64{};
  std::span<double> uvs_f64{};
  std::span<double> hole_levels{};
};

// What a decode produced.
struct FrameInfo {
  double time = 0;  // the time decoded, seconds (t, or t clamped into the range)
  int vertex_count = 0;
  int triangle_count = 0;
  int texture_size = 0;  // M (0: no texture)
  int iterations = 0;    // reconstruction steps the frame took
  // The reconstruction did not meet its tolerance; the frame is then the spline of the keyframes'
  // own surfaces (always a valid face), which fell_back says.
  bool converged = true;
  bool fell_back = false;
  int hole_level_count = 0;  // G's nodes in a file with holes, else 0
  // Array lengths the frame needs, in elements: floats, indices, bytes.
  size_t positions_size() const { return 3 * static_cast<size_t>(vertex_count); }
  size_t normals_size() const { return 3 * static_cast<size_t>(vertex_count); }
  size_t uvs_size() const { return 2 * static_cast<size_t>(vertex_count); }
  size_t indices_size() const { return 3 * static_cast<size_t>(triangle_count); }
  size_t texture_bytes() const { return 4 * static_cast<size_t>(texture_size) * static_cast<size_t>(texture_size); }
  size_t hole_levels_size() const { return static_cast<size_t>(hole_level_count); }
};

class Decoder {
 public:
  // Throws kInvalidArgument for a null or invalid sequence, kLimit for a source whose budget holds
  // fewer keyframe surfaces than a frame blends.
  explicit Decoder(std::shared_ptr<const Sequence> sequence);
  explicit Decoder(std::shared_ptr<const KeyframeSource> source);
  // open_sequence_file / open_sequence_memory, then a decoder on it.
  static Decoder open(const std::filesystem::path& path, const DecoderLimits& limits = kDefaultDecoderLimits);
  static Decoder open_memory(std::span<const uint8_t> bytes, const std::string& name = "memory",
                             const DecoderLimits& limits = kDefaultDecoderLimits);

  Decoder(Decoder&&) noexcept;
  Decoder& operator=(Decoder&&) noexcept;
  ~Decoder();

  const FileInfo& info() const { return info_; }
  // The opened file, to share with another decoder (on another thread).
  const std::shared_ptr<const KeyframeSource>& source() const { return source_; }

  // Decodes the frame at t (seconds from the capture's first frame) into `out`; every number it
  // writes is finite. Throws
  //   kInvalidArgument  t not finite (only the caller's arguments: never for a fault of the file);
  //   kOutOfRange       t outside [range_begin, range_end] without options.clamp;
  //   kBufferTooSmall   a non-empty span too small (the message says which and what is needed);
  //   kCorrupt          the file decodes to non-finite numbers at t, or a keyframe t needs cannot be
  //                     reconstructed (remembered: the next call that needs it fails at once);
  //   kNumerical, kNotConverged  the reconstruction failed (a corrupt file).
  // The frame is kept: asking again for the same t and options (after kBufferTooSmall, or through
  // frame_info) copies it out again without decoding.
  FrameInfo decode(double t, const FrameBuffers& out, const FrameOptions& options = {});
  // Decodes the frame at t (kept for the next decode) and says its sizes without copying anything:
  // the "ask the size, then hand the buffers" pattern for files with holes.
  FrameInfo frame_info(double t, const FrameOptions& options = {});
  // The keyframes the texture of the frame at t blends and their weights (SplineWeights: keys and
  // weights, in the blend's order; a weight may be 0 or negative), from the frame decoded (and kept)
  // as frame_info does: the blend a player that decodes the keyframes' images itself does (the
  // WebAssembly decoder, spec/web.md). Throws as frame_info.
  SplineWeights texture_weights(double t, const FrameOptions& options = {});
  // The reconstruction stops when a step moves no node more than `tolerance` of the rim's diameter
  // (ReconstructOptions::tolerance, 1e-5 by default); frames decoded afterwards use it. Throws
  // kInvalidArgument outside (0, 0.01].
  void set_tolerance(double tolerance);

 private:
  struct Impl;
  std::shared_ptr<const KeyframeSource> source_;
  FileInfo info_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace facemorph
