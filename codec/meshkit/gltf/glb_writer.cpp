// glTF 2.0 binary, written directly: a JSON chunk and one binary buffer (the glTF 2.0 specification,
// §4.4 "GLB File Format Specification"). A few hundred lines do not justify a dependency for the
// decoder a player links.
#include "codec/meshkit/gltf/gltf.hpp"

#include "codec/core/geometry/differential.hpp"  // area_weighted_normals: the decoder's one normal rule
#include "codec/core/geometry/differential.hpp"
#include "codec/writer/image/image_encode.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#ifdef FACEMORPH_HAVE_MESHOPT
#include <meshoptimizer.h>
#endif

namespace facemorph {

namespace {

constexpr int kFloat = 5126, kUnsignedInt = 5125, kShort = 5122, kUnsignedShort = 5123, kByte = 5120;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

// The binary buffer and the JSON arrays that describe its pieces.
class GlbBuilder {
 public:
  // Appends bytes as a buffer view (4-byte aligned); returns its index. `stride`: the byteStride
  // of a vertex stream whose elements are padded to 4 bytes (0: tightly packed).
  int view(const void* data, size_t size, int target, size_t stride = 0) {
    const size_t offset = append(data, size);
    std::ostringstream v;
    v << "{\"buffer\":0,\"byteOffset\":" << offset << ",\"byteLength\":" << size;
    if (stride) v << ",\"byteStride\":" << stride;
    if (target) v << ",\"target\":" << target;
    v << "}";
    views_.push_back(v.str());
    return static_cast<int>(views_.size()) - 1;
  }

  // The same, compressed by meshoptimizer (EXT_meshopt_compression) where that is smaller: `count`
  // elements of `stride` bytes (a vertex stream, stride a multiple of 4), or with `indices` `count`
  // uint32 triangle corners. The uncompressed bytes' place is in the fallback buffer (buffer 1, no
  // data: the extension is required).
  int view_compressed(const void* data, size_t stride, size_t count, int target, bool indices) {
    const size_t size = stride * count;
#ifdef FACEMORPH_HAVE_MESHOPT
    // Version 0 of the vertex codec and 1 of the index codec: the versions the extension names.
    meshopt_encodeVertexVersion(0);
    meshopt_encodeIndexVersion(1);
    std::vector<unsigned char> packed;
    if (indices) {
      const auto* corners = static_cast<const unsigned int*>(data);
      const size_t vertices = count ? *std::max_element(corners, corners + count) + size_t{1} : 0;
      packed.resize(meshopt_encodeIndexBufferBound(count, vertices));
      packed.resize(meshopt_encodeIndexBuffer(packed.data(), packed.size(), corners, count));
    } else {
      packed.resize(meshopt_encodeVertexBufferBound(count, stride));
      packed.resize(meshopt_encodeVertexBuffer(packed.data(), packed.size(), data, count, stride));
    }
    if (!packed.empty() && packed.size() < size) {
      const size_t offset = append(packed.data(), packed.size());
      while (fallback_ % 4 != 0) ++fallback_;
      const size_t fallback_offset = fallback_;
      fallback_ += size;
      std::ostringstream v;
      v << "{\"buffer\":1,\"byteOffset\":" << fallback_offset << ",\"byteLength\":" << size;
      // A vertex stream's view states its stride; an animation's must not (glTF 2.0 §3.6.2.4).
      if (target == kArrayBuffer) v << ",\"byteStride\":" << stride;
      if (target) v << ",\"target\":" << target;
      v << ",\"extensions\":{\"EXT_meshopt_compression\":{\"buffer\":0,\"byteOffset\":" << offset << ",\"byteLength\":" << packed.size()
        << ",\"byteStride\":" << stride << ",\"count\":" << count << ",\"mode\":\"" << (indices ? "TRIANGLES" : "ATTRIBUTES") << "\"}}}";
      views_.push_back(v.str());
      return static_cast<int>(views_.size()) - 1;
    }
#endif
    return view(data, size, target, target == kArrayBuffer ? stride : 0);
  }

  // An accessor over a view: `components` values of `component_type` per element, `count` elements.
  int accessor(int view_index, int component_type, bool normalized, size_t count, const char* type, const std::string& bounds = "") {
    std::ostringstream a;
    a << "{\"bufferView\":" << view_index << ",\"componentType\":" << component_type;
    if (normalized) a << ",\"normalized\":true";
    a << ",\"count\":" << count << ",\"type\":\"" << type << "\"" << bounds << "}";
    accessors_.push_back(a.str());
    return static_cast<int>(accessors_.size()) - 1;
  }

  bool compressed() const { return fallback_ > 0; }

  // A float accessor of `type` ("VEC3", "VEC2", "SCALAR") over `values`, with min/max when asked.
  int floats(const std::vector<float>& values, int components, const char* type, int target, bool bounds) {
    const int v = view(values.data(), values.size() * sizeof(float), target);
    std::ostringstream a;
    a.precision(9);
    a << "{\"bufferView\":" << v << ",\"componentType\":" << kFloat << ",\"count\":" << values.size() / static_cast<size_t>(components)
      << ",\"type\":\"" << type << "\"";
    if (bounds) {
      std::vector<float> lo(static_cast<size_t>(components), std::numeric_limits<float>::max()),
          hi(lo.size(), -std::numeric_limits<float>::max());
      for (size_t i = 0; i < values.size(); ++i) {
        const size_t c = i % static_cast<size_t>(components);
        lo[c] = std::min(lo[c], values[i]);
        hi[c] = std::max(hi[c], values[i]);
      }
      a << ",\"min\":" << list(lo) << ",\"max\":" << list(hi);
    }
    a << "}";
    accessors_.push_back(a.str());
    return static_cast<int>(accessors_.size()) - 1;
  }

  int indices(const std::vector<uint32_t>& values) {
    const int v = view(values.data(), values.size() * sizeof(uint32_t), kElementArrayBuffer);
    std::ostringstream a;
    a << "{\"bufferView\":" << v << ",\"componentType\":" << kUnsignedInt << ",\"count\":" << values.size() << ",\"type\":\"SCALAR\"}";
    accessors_.push_back(a.str());
    return static_cast<int>(accessors_.size()) - 1;
  }

  static std::string list(const std::vector<float>& values) {
    std::ostringstream out;
    out.precision(9);
    out << "[";
    for (size_t i = 0; i < values.size(); ++i) out << (i ? "," : "") << values[i];
    out << "]";
    return out.str();
  }

  static std::string join(const std::vector<std::string>& items) {
    std::string out = "[";
    for (size_t i = 0; i < items.size(); ++i) out += (i ? "," : "") + items[i];
    return out + "]";
  }

  std::vector<uint8_t> finish(const std::string& json_without_buffers) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    std::string json = json_without_buffers;
    json.pop_back();  // the closing brace
    json += ",\"bufferViews\":" + join(views_) + ",\"accessors\":" + join(accessors_) +
            ",\"buffers\":[{\"byteLength\":" + std::to_string(bin_.size()) + "}";
    if (fallback_ > 0)
      json += ",{\"byteLength\":" + std::to_string(fallback_) + ",\"extensions\":{\"EXT_meshopt_compression\":{\"fallback\":true}}}";
    json += "]}";
    while (json.size() % 4 != 0) json.push_back(' ');
    std::vector<uint8_t> out;
    auto u32 = [&](uint32_t v) {
      for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
    };
    const uint64_t total = 12 + 8 + json.size() + 8 + bin_.size();
    if (total > std::numeric_limits<uint32_t>::max())
      throw Error(ErrorCode::kInvalidArgument, "glTF: the clip exceeds 4 GiB (a .glb's limit): fewer frames or a smaller grid");
    out.reserve(total);
    u32(0x46546C67);  // "glTF"
    u32(2);
    u32(static_cast<uint32_t>(total));
    u32(static_cast<uint32_t>(json.size()));
    u32(0x4E4F534A);  // "JSON"
    out.insert(out.end(), json.begin(), json.end());
    u32(static_cast<uint32_t>(bin_.size()));
    u32(0x004E4942);  // "BIN\0"
    out.insert(out.end(), bin_.begin(), bin_.end());
    return out;
  }

 private:
  size_t append(const void* data, size_t size) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    const size_t offset = bin_.size();
    bin_.resize(offset + size);
    if (size) std::memcpy(bin_.data() + offset, data, size);
    return offset;
  }

  std::vector<uint8_t> bin_;
  std::vector<std::string> views_, accessors_;
  size_t fallback_ = 0;  // bytes of the fallback buffer (the compressed views' uncompressed size)
};

void check_clip(const GltfClip& clip) {
  auto fail = [](const std::string& why) { throw Error(ErrorCode::kInvalidArgument, "glTF clip: " + why); };
  if (clip.times.empty() || clip.positions.size() != clip.times.size()) fail("one time per frame and at least one frame");
  for (size_t i = 1; i < clip.times.size(); ++i) {
    if (!(clip.times[i] > clip.times[i - 1])) fail("times not strictly increasing at frame " + std::to_string(i));
  }
  const size_t n = clip.positions.front().size();
  if (n == 0 || clip.faces.empty()) fail("no vertices or no faces");
  for (size_t f = 0; f < clip.positions.size(); ++f) {
    if (clip.positions[f].size() != n) fail("frame " + std::to_string(f) + " has another vertex count");
    for (const Vec3& p : clip.positions[f]) {
      if (!p.allFinite()) fail("frame " + std::to_string(f) + " has a non-finite position");
    }
  }
  for (const Face& face : clip.faces) {
    for (int32_t v : face) {
      if (v < 0 || static_cast<size_t>(v) >= n) fail("a face index out of range");
    }
  }
  if (!clip.uvs.empty() && clip.uvs.size() != n) fail("one UV per vertex");
  const auto& switched = clip.switched_textures;
  if (switched.size() == 1) fail("one switched texture: give it as the texture");
  for (size_t i = 0; i < switched.size(); ++i) {
    if (switched[i].image.empty()) fail("switched texture " + std::to_string(i) + " is empty");
    if (!std::isfinite(switched[i].start) || (i > 0 && !(switched[i].start > switched[i - 1].start))) {
      fail("switched texture starts not finite and strictly increasing at " + std::to_string(i));
    }
  }
  if (!switched.empty() && !(switched.front().start <= clip.times.front())) fail("the first switched texture starts after the first frame");
  if (!switched.empty() && clip.uvs.empty()) fail("switched textures without UVs");
}

std::vector<float> flat(const std::vector<Vec3>& values) {
  std::vector<float> out;
  out.reserve(3 * values.size());
  for (const Vec3& v : values) {
    for (int k = 0; k < 3; ++k) out.push_back(static_cast<float>(v[k]));
  }
  return out;
}

// A frame's vertex normals as the decoder gives them (fm_frame.normals: area-weighted, unit) over
// the clip's triangles. A vertex on no triangle of non-zero area (one only a dropped hole's
// triangles held) gets +z: the decoder's zero is no direction, and glTF wants unit normals.
std::vector<Vec3> decoder_normals(const std::vector<Vec3>& positions, const std::vector<Face>& faces) {
  std::vector<float> packed(3 * positions.size());
  area_weighted_normals(positions, faces, packed);
  std::vector<Vec3> normals(positions.size());
  for (size_t v = 0; v < normals.size(); ++v) {
    const Vec3 n(packed[3 * v], packed[3 * v + 1], packed[3 * v + 2]);
    normals[v] = n.squaredNorm() > 0 ? n : Vec3::UnitZ();
  }
  return normals;
}

// A unit normal as normalised int8 codes c (read as c / 127). Of the eight codes next to 127 · n
// (each component rounded down or up), the one nearest n in angle whose length is within 0.005 of
// 1: plain rounding can miss unit length by up to √3 · 0.5 / 127 = 0.0068, past the Khronos
// validator's 0.00674 (ACCESSOR_VECTOR3_NON_UNIT), where some neighbour always keeps within it.
std::array<int32_t, 3> normal_code(const Vec3& n) {
  std::array<int32_t, 3> nearest{}, most_unit{};
  double nearest_cosine = -2, smallest_miss = std::numeric_limits<double>::infinity();
  for (int corner = 0; corner < 8; ++corner) {
    std::array<int32_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const double scaled = 127 * std::clamp(n[k], -1.0, 1.0);
      c[static_cast<size_t>(k)] = static_cast<int32_t>((corner >> k) & 1 ? std::ceil(scaled) : std::floor(scaled));
    }
    const Vec3 q(c[0], c[1], c[2]);
    if (q.squaredNorm() == 0) continue;
    const double miss = std::abs(q.norm() / 127 - 1), cosine = q.normalized().dot(n);
    if (miss <= 0.005 && cosine > nearest_cosine) nearest_cosine = cosine, nearest = c;
    if (miss < smallest_miss) smallest_miss = miss, most_unit = c;
  }
  return nearest_cosine > -2 ? nearest : most_unit;
}

// A later frame's normal as codes for its morph target: of each component's two codes next to
// 127 · n (rounded down and up), the one nearer frame 0's code `base`, so the difference stays 0
// while a normal turns by less than a step: within 1/127 a component, like the nearest code, but
// the differences of a face that barely turns are zeros that meshoptimizer packs to almost
// nothing, where rounding to nearest flips codes by ±1 at random from frame to frame.
std::array<int32_t, 3> code_near(const Vec3& n, const std::array<int32_t, 3>& base) {
  std::array<int32_t, 3> c{};
  for (size_t k = 0; k < 3; ++k) {
    const double scaled = 127 * std::clamp(n[static_cast<int>(k)], -1.0, 1.0);
    c[k] = std::clamp(base[k], static_cast<int32_t>(std::floor(scaled)), static_cast<int32_t>(std::ceil(scaled)));
  }
  return c;
}

// The vertex streams, their morph targets and the indices, as accessors of `b`.
struct Streams {
  int position = -1, normal = -1, uv = -1, index = -1;
  std::vector<std::string> targets;  // one {"POSITION":..,"NORMAL":..} per frame after the first
  std::string node_transform;        // compact: the node's scale and translation that undo the quantisation
  double node_scale = 1;             // the scale in node_transform (1 without)
};

// Floats as they are.
Streams float_streams(const GltfClip& clip, GlbBuilder& b) {
  Streams out;
  const size_t frames = clip.times.size();
  const std::vector<Vec3>& base = clip.positions.front();
  const std::vector<Vec3> base_normals = decoder_normals(base, clip.faces);
  out.position = b.floats(flat(base), 3, "VEC3", kArrayBuffer, true);
  if (clip.normals) out.normal = b.floats(flat(base_normals), 3, "VEC3", kArrayBuffer, false);
  if (!clip.uvs.empty()) {
    std::vector<float> uvs;
    for (const Vec2& t : clip.uvs) {
      uvs.push_back(static_cast<float>(t.x()));
      uvs.push_back(static_cast<float>(1 - t.y()));  // glTF's v runs down the image
    }
    out.uv = b.floats(uvs, 2, "VEC2", kArrayBuffer, false);
  }
  std::vector<uint32_t> indices;
  for (const Face& f : clip.faces) {
    for (int32_t v : f) indices.push_back(static_cast<uint32_t>(v));
  }
  out.index = b.indices(indices);
  // Morph targets: every frame after the first, as differences from the base.
  for (size_t f = 1; f < frames; ++f) {
    std::vector<Vec3> dp(base.size());
    for (size_t v = 0; v < base.size(); ++v) dp[v] = clip.positions[f][v] - base[v];
    const int p = b.floats(flat(dp), 3, "VEC3", kArrayBuffer, true);
    if (!clip.normals) {
      out.targets.push_back("{\"POSITION\":" + std::to_string(p) + "}");
      continue;
    }
    const std::vector<Vec3> normals = decoder_normals(clip.positions[f], clip.faces);
    std::vector<Vec3> dn(base.size());
    for (size_t v = 0; v < base.size(); ++v) dn[v] = normals[v] - base_normals[v];
    const int n = b.floats(flat(dn), 3, "VEC3", kArrayBuffer, false);
    out.targets.push_back("{\"POSITION\":" + std::to_string(p) + ",\"NORMAL\":" + std::to_string(n) + "}");
  }
  return out;
}

// KHR_mesh_quantization: positions as int16 codes q = round((p - centre) / step) on one grid for
// the whole clip (the node's scale `step` and translation `centre` undo it), padded to 4 components
// (a vertex attribute's elements are 4-byte aligned); morph targets as the code differences. The
// step is 2⁻¹⁴ of the box's diagonal, so a position moves by at most 0.9 · 2⁻¹⁴ = 5.3·10⁻⁵ of it,
// twenty times below the decoded frames' own error (spec/method.md), and coarse enough that
// meshoptimizer packs the differences to a few bits (larger if a vertex moves more than 32766 steps
// from frame 0, which the codes must hold). Normals: the decoder's (decoder_normals) as normalised
// int8 codes (normal_code), and each morph target's as the code differences, so that frame f reads
// exactly its own codes, within 1/127 a component of the decoder's normals; a target whose
// differences pass ±127 (a normal that turned more than about 60 degrees from frame 0's) holds them
// as floats d / 127, the same values. Without normals a viewer shades each triangle flat (glTF 2.0
// §3.7.2.1): the stair-stepped cheeks of issue 48. UVs as normalised uint16. Each stream compressed
// by meshoptimizer where that is smaller.
Streams compact_streams(const GltfClip& clip, GlbBuilder& b) {
  Streams out;
  const size_t frames = clip.times.size();
  const std::vector<Vec3>& base = clip.positions.front();
  const size_t n = base.size();
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  double moved = 0;
  for (const std::vector<Vec3>& frame : clip.positions) {
    for (size_t v = 0; v < n; ++v) {
      lo = lo.cwiseMin(frame[v]);
      hi = hi.cwiseMax(frame[v]);
      moved = std::max(moved, (frame[v] - base[v]).cwiseAbs().maxCoeff());
    }
  }
  const Vec3 centre = 0.5 * (lo + hi);
  const double step =
      std::max({(hi - lo).norm() / 16384, (hi - lo).maxCoeff() / 65534, moved / 32766, std::numeric_limits<double>::min() * 65536});
  const auto code = [&](const Vec3& p, int k) {
    return static_cast<int32_t>(std::clamp(std::lround((p[k] - centre[k]) / step), -32767L, 32767L));
  };
  const auto shorts = [&](const std::vector<std::array<int32_t, 3>>& values, bool bounds) {
    std::vector<int16_t> packed(4 * values.size(), 0);
    std::array<int32_t, 3> mn{32767, 32767, 32767}, mx{-32767, -32767, -32767};
    for (size_t v = 0; v < values.size(); ++v) {
      for (int k = 0; k < 3; ++k) {
        const int32_t c = std::clamp(values[v][static_cast<size_t>(k)], -32767, 32767);
        packed[4 * v + static_cast<size_t>(k)] = static_cast<int16_t>(c);
        mn[static_cast<size_t>(k)] = std::min(mn[static_cast<size_t>(k)], c);
        mx[static_cast<size_t>(k)] = std::max(mx[static_cast<size_t>(k)], c);
      }
    }
    const int view = b.view_compressed(packed.data(), 8, values.size(), kArrayBuffer, false);
    std::string range;
    if (bounds) {
      range = ",\"min\":[" + std::to_string(mn[0]) + "," + std::to_string(mn[1]) + "," + std::to_string(mn[2]) + "],\"max\":[" +
              std::to_string(mx[0]) + "," + std::to_string(mx[1]) + "," + std::to_string(mx[2]) + "]";
    }
    return b.accessor(view, kShort, false, values.size(), "VEC3", range);
  };
  std::vector<std::array<int32_t, 3>> base_codes(n);
  for (size_t v = 0; v < n; ++v) base_codes[v] = {code(base[v], 0), code(base[v], 1), code(base[v], 2)};
  out.position = shorts(base_codes, true);
  // int8 VEC3 padded to 4 bytes a vertex: a vertex attribute's elements are 4-byte aligned.
  const auto bytes = [&](const std::vector<std::array<int32_t, 3>>& values) {
    std::vector<int8_t> packed(4 * values.size(), 0);
    for (size_t v = 0; v < values.size(); ++v) {
      for (size_t k = 0; k < 3; ++k) packed[4 * v + k] = static_cast<int8_t>(values[v][k]);
    }
    return b.accessor(b.view_compressed(packed.data(), 4, values.size(), kArrayBuffer, false), kByte, true, values.size(), "VEC3");
  };
  std::vector<std::array<int32_t, 3>> base_normal_codes(n);
  if (clip.normals) {
    const std::vector<Vec3> normals = decoder_normals(base, clip.faces);
    for (size_t v = 0; v < n; ++v) base_normal_codes[v] = normal_code(normals[v]);
    out.normal = bytes(base_normal_codes);
  }
  if (!clip.uvs.empty()) {
    std::vector<uint16_t> uvs;
    for (const Vec2& t : clip.uvs) {
      uvs.push_back(static_cast<uint16_t>(std::lround(std::clamp(t.x(), 0.0, 1.0) * 65535)));
      uvs.push_back(static_cast<uint16_t>(std::lround(std::clamp(1 - t.y(), 0.0, 1.0) * 65535)));  // glTF's v runs down
    }
    out.uv = b.accessor(b.view_compressed(uvs.data(), 4, n, kArrayBuffer, false), kUnsignedShort, true, n, "VEC2");
  }
  std::vector<uint32_t> indices;
  for (const Face& f : clip.faces) {
    for (int32_t v : f) indices.push_back(static_cast<uint32_t>(v));
  }
  out.index = b.accessor(b.view_compressed(indices.data(), 4, indices.size(), kElementArrayBuffer, true), kUnsignedInt, false,
                         indices.size(), "SCALAR");
  for (size_t f = 1; f < frames; ++f) {
    std::vector<std::array<int32_t, 3>> dp(n);
    for (size_t v = 0; v < n; ++v) {
      for (int k = 0; k < 3; ++k) dp[v][static_cast<size_t>(k)] = code(clip.positions[f][v], k) - base_codes[v][static_cast<size_t>(k)];
    }
    if (!clip.normals) {
      out.targets.push_back("{\"POSITION\":" + std::to_string(shorts(dp, true)) + "}");
      continue;
    }
    const std::vector<Vec3> normals = decoder_normals(clip.positions[f], clip.faces);
    std::vector<std::array<int32_t, 3>> dn(n);
    bool fits = true;
    for (size_t v = 0; v < n; ++v) {
      const std::array<int32_t, 3> c = code_near(normals[v], base_normal_codes[v]);
      for (size_t k = 0; k < 3; ++k) {
        dn[v][k] = c[k] - base_normal_codes[v][k];
        fits = fits && std::abs(dn[v][k]) <= 127;
      }
    }
    int normal_target;
    if (fits) {
      normal_target = bytes(dn);
    } else {
      std::vector<float> wide(3 * n);
      for (size_t v = 0; v < n; ++v) {
        for (size_t k = 0; k < 3; ++k) wide[3 * v + k] = static_cast<float>(dn[v][k] / 127.0);
      }
      normal_target = b.accessor(b.view_compressed(wide.data(), 12, n, kArrayBuffer, false), kFloat, false, n, "VEC3");
    }
    out.targets.push_back("{\"POSITION\":" + std::to_string(shorts(dp, true)) + ",\"NORMAL\":" + std::to_string(normal_target) + "}");
  }
  std::ostringstream transform;
  transform.precision(17);
  transform << ",\"translation\":[" << centre.x() << "," << centre.y() << "," << centre.z() << "],\"scale\":[" << step << "," << step << ","
            << step << "]";
  out.node_transform = transform.str();
  out.node_scale = step;
  return out;
}

}  // namespace

std::vector<uint8_t> encode_glb(const GltfClip& clip) {
  check_clip(clip);
  GlbBuilder b;
  const size_t frames = clip.times.size();
  const Streams streams = clip.compact ? compact_streams(clip, b) : float_streams(clip, b);
  const int position = streams.position, normal = streams.normal, uv = streams.uv, index = streams.index;
  const std::vector<std::string>& targets = streams.targets;
  std::ostringstream json;
  json.precision(9);
  // One node, mesh and material per texture (switched textures), all sharing every accessor.
  const bool switching = clip.switched_textures.size() > 1 && uv >= 0;
  const size_t copies = switching ? clip.switched_textures.size() : 1;
  const bool webp = switching && clip.compact;
  std::vector<std::string> nodes, node_indices, meshes;
  for (size_t i = 0; i < copies; ++i) {
    nodes.push_back("{\"mesh\":" + std::to_string(i) + ",\"name\":\"" + clip.name + (switching ? "_" + std::to_string(i) : std::string()) +
                    "\"" + streams.node_transform + "}");
    node_indices.push_back(std::to_string(i));
    std::ostringstream mesh;
    mesh << "{\"name\":\"" << clip.name << "\",\"primitives\":[{\"attributes\":{\"POSITION\":" << position;
    if (normal >= 0) mesh << ",\"NORMAL\":" << normal;
    if (uv >= 0) mesh << ",\"TEXCOORD_0\":" << uv;
    mesh << "},\"indices\":" << index << ",\"material\":" << i;
    if (!targets.empty()) mesh << ",\"targets\":" << GlbBuilder::join(targets);
    mesh << "}]";
    if (!targets.empty()) mesh << ",\"weights\":" << GlbBuilder::list(std::vector<float>(targets.size(), 0.0f));
    mesh << "}";
    meshes.push_back(mesh.str());
  }
  json << "{\"asset\":{\"version\":\"2.0\",\"generator\":\"facemorph fmdec\"},\"scene\":0,\"scenes\":[{\"nodes\":"
       << GlbBuilder::join(node_indices) << "}],\"nodes\":" << GlbBuilder::join(nodes) << ",\"meshes\":" << GlbBuilder::join(meshes) << ",";
  // The material: the texture when there is one, a skin-grey otherwise; double-sided, since a face
  // scan is an open surface seen from behind at its rim.
  const auto textured_material = [](size_t texture) {
    return "{\"name\":\"skin\",\"doubleSided\":true,\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":" + std::to_string(texture) +
           "},\"metallicFactor\":0,\"roughnessFactor\":0.8}}";
  };
  if (switching) {
    std::vector<std::string> images, textures, materials;
    for (size_t i = 0; i < copies; ++i) {
      const Image& image = clip.switched_textures[i].image;
      // WebP at quality 90 where the clip is for the web: a PNG of each keyframe's texture would
      // outweigh the geometry many times over.
      const std::vector<uint8_t> bytes = webp ? encode_webp(image, 90) : encode_png(image);
      images.push_back("{\"bufferView\":" + std::to_string(b.view(bytes.data(), bytes.size(), 0)) + ",\"mimeType\":\"image/" +
                       (webp ? "webp" : "png") + "\"}");
      textures.push_back(webp ? "{\"sampler\":0,\"extensions\":{\"EXT_texture_webp\":{\"source\":" + std::to_string(i) + "}}}"
                              : "{\"sampler\":0,\"source\":" + std::to_string(i) + "}");
      materials.push_back(textured_material(i));
    }
    json << "\"images\":" << GlbBuilder::join(images)
         << ",\"samplers\":[{\"magFilter\":9729,\"minFilter\":9729,\"wrapS\":33071,\"wrapT\":33071}],"
         << "\"textures\":" << GlbBuilder::join(textures) << ",\"materials\":" << GlbBuilder::join(materials) << ",";
  } else if (!clip.texture.empty() && uv >= 0) {
    const std::vector<uint8_t> png = encode_png(clip.texture);
    const int image = b.view(png.data(), png.size(), 0);
    json << "\"images\":[{\"bufferView\":" << image << ",\"mimeType\":\"image/png\"}],\"samplers\":[{\"magFilter\":9729,\"minFilter\":9729,"
         << "\"wrapS\":33071,\"wrapT\":33071}],\"textures\":[{\"sampler\":0,\"source\":0}],"
         << "\"materials\":[" << textured_material(0) << "],";
  } else {
    json << "\"materials\":[{\"name\":\"skin\",\"doubleSided\":true,\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.8,0.8,0.8,1],"
         << "\"metallicFactor\":0,\"roughnessFactor\":0.8}}],";
  }
  std::vector<std::string> samplers, channels;
  if (!targets.empty()) {
    // Weights one-hot at each frame's time (all zero at frame 0, the base), linear between; one
    // sampler for every copy of the node.
    std::vector<float> times, weights;
    for (size_t f = 0; f < frames; ++f) {
      times.push_back(static_cast<float>(clip.times[f] - clip.times.front()));
      for (size_t t = 0; t < targets.size(); ++t) weights.push_back(f >= 1 && t == f - 1 ? 1.0f : 0.0f);
    }
    const int input = b.floats(times, 1, "SCALAR", 0, true);
    // One-hot rows: meshoptimizer packs them to almost nothing.
    const int output =
        clip.compact ? b.accessor(b.view_compressed(weights.data(), 4, weights.size(), 0, false), kFloat, false, weights.size(), "SCALAR")
                     : b.floats(weights, 1, "SCALAR", 0, false);
    samplers.push_back("{\"input\":" + std::to_string(input) + ",\"output\":" + std::to_string(output) + ",\"interpolation\":\"LINEAR\"}");
    for (size_t i = 0; i < copies; ++i)
      channels.push_back("{\"sampler\":0,\"target\":{\"node\":" + std::to_string(i) + ",\"path\":\"weights\"}}");
  }
  if (switching) {
    // Each copy at its own scale while its texture is current, at 0 (nothing drawn) otherwise.
    std::vector<float> starts;
    for (const GltfClip::SwitchedTexture& t : clip.switched_textures)
      starts.push_back(static_cast<float>(std::max(0.0, t.start - clip.times.front())));
    const int input = b.floats(starts, 1, "SCALAR", 0, true);
    for (size_t i = 0; i < copies; ++i) {
      std::vector<float> scales;
      for (size_t j = 0; j < copies; ++j) {
        for (int k = 0; k < 3; ++k) scales.push_back(j == i ? static_cast<float>(streams.node_scale) : 0.0f);
      }
      const int output = b.floats(scales, 3, "VEC3", 0, false);
      channels.push_back("{\"sampler\":" + std::to_string(samplers.size()) + ",\"target\":{\"node\":" + std::to_string(i) +
                         ",\"path\":\"scale\"}}");
      samplers.push_back("{\"input\":" + std::to_string(input) + ",\"output\":" + std::to_string(output) + ",\"interpolation\":\"STEP\"}");
    }
  }
  if (!channels.empty()) {
    json << "\"animations\":[{\"name\":\"play\",\"samplers\":" << GlbBuilder::join(samplers)
         << ",\"channels\":" << GlbBuilder::join(channels) << "}],";
  }
  if (clip.compact) {
    const std::string extensions = std::string("[\"KHR_mesh_quantization\"") + (b.compressed() ? ",\"EXT_meshopt_compression\"" : "") +
                                   (webp ? ",\"EXT_texture_webp\"" : "") + "]";
    json << "\"extensionsUsed\":" << extensions << ",\"extensionsRequired\":" << extensions << ",";
  }
  std::string text = json.str();
  text.back() = '}';  // the last comma closes the object
  return b.finish(text);
}

std::vector<Face> faces_outside_holes(const std::vector<Face>& faces, const std::vector<std::vector<double>>& levels) {
  std::vector<Face> kept;
  for (const Face& f : faces) {
    bool always_inside = !levels.empty();
    for (const std::vector<double>& level : levels) {
      bool inside = true;
      for (int32_t v : f) {
        if (v < 0 || static_cast<size_t>(v) >= level.size())
          throw Error(ErrorCode::kInvalidArgument, "faces_outside_holes: a face index beyond the levels");
        inside = inside && level[static_cast<size_t>(v)] < 0;
      }
      always_inside = always_inside && inside;
    }
    if (!always_inside) kept.push_back(f);
  }
  return kept;
}

}  // namespace facemorph
