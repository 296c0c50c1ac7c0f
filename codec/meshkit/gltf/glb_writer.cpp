// glTF 2.0 binary, written directly: a JSON chunk and one binary buffer (the glTF 2.0 specification,
// §4.4 "GLB File Format Specification"). A few hundred lines do not justify a dependency for the
// decoder a player links.
#include "facemorph/meshkit/gltf.hpp"

#include "facemorph/error.hpp"
#include "facemorph/geometry.hpp"
#include "facemorph/image_codec.hpp"
#include "facemorph/meshkit/surface_measures.hpp"

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace facemorph {

namespace {

constexpr int kFloat = 5126, kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

// The binary buffer and the JSON arrays that describe its pieces.
class GlbBuilder {
 public:
  // Appends bytes as a buffer view (4-byte aligned); returns its index.
  int view(const void* data, size_t size, int target) {
    while (bin_.size() % 4 != 0) bin_.push_back(0);
    const size_t offset = bin_.size();
    bin_.resize(offset + size);
    std::memcpy(bin_.data() + offset, data, size);
    std::ostringstream v;
    v << "{\"buffer\":0,\"byteOffset\":" << offset << ",\"byteLength\":" << size;
    if (target) v << ",\"target\":" << target;
    v << "}";
    views_.push_back(v.str());
    return static_cast<int>(views_.size()) - 1;
  }

  // A float accessor of `type` ("VEC3", "VEC2", "SCALAR") over `values`, with min/max when asked.
  int floats(const std::vector<float>& values, int components, const char* type, int target, bool bounds) {
    const int v = view(values.data(), values.size() * sizeof(float), target);
    std::ostringstream a;
    a.precision(9);
    a << "{\"bufferView\":" << v << ",\"componentType\":" << kFloat << ",\"count\":" << values.size() / static_cast<size_t>(components)
      << ",\"type\":\"" << type << "\"";
    if (bounds) {
      std::vector<float> lo(static_cast<size_t>(components), std::numeric_limits<float>::max()), hi(lo.size(), -std::numeric_limits<float>::max());
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
    json += ",\"bufferViews\":" + join(views_) + ",\"accessors\":" + join(accessors_) + ",\"buffers\":[{\"byteLength\":" +
            std::to_string(bin_.size()) + "}]}";
    while (json.size() % 4 != 0) json.push_back(' ');
    std::vector<uint8_t> out;
    auto u32 = [&](uint32_t v) {
      for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
    };
    const uint64_t total = 12 + 8 + json.size() + 8 + bin_.size();
    if (total > std::numeric_limits<uint32_t>::max()) throw Error(ErrorCode::kInvalidArgument, "glTF: the clip exceeds 4 GiB (a .glb's limit): fewer frames or a smaller grid");
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
  std::vector<uint8_t> bin_;
  std::vector<std::string> views_, accessors_;
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
}

std::vector<float> flat(const std::vector<Vec3>& values) {
  std::vector<float> out;
  out.reserve(3 * values.size());
  for (const Vec3& v : values) {
    for (int k = 0; k < 3; ++k) out.push_back(static_cast<float>(v[k]));
  }
  return out;
}

}  // namespace

std::vector<uint8_t> encode_glb(const GltfClip& clip) {
  check_clip(clip);
  GlbBuilder b;
  const size_t frames = clip.times.size();
  const std::vector<Vec3>& base = clip.positions.front();
  const std::vector<Vec3> base_normals = vertex_normals(base, clip.faces);
  const int position = b.floats(flat(base), 3, "VEC3", kArrayBuffer, true);
  const int normal = b.floats(flat(base_normals), 3, "VEC3", kArrayBuffer, false);
  int uv = -1;
  if (!clip.uvs.empty()) {
    std::vector<float> uvs;
    for (const Vec2& t : clip.uvs) {
      uvs.push_back(static_cast<float>(t.x()));
      uvs.push_back(static_cast<float>(1 - t.y()));  // glTF's v runs down the image
    }
    uv = b.floats(uvs, 2, "VEC2", kArrayBuffer, false);
  }
  std::vector<uint32_t> indices;
  for (const Face& f : clip.faces) {
    for (int32_t v : f) indices.push_back(static_cast<uint32_t>(v));
  }
  const int index = b.indices(indices);
  // Morph targets: every frame after the first, as differences from the base.
  std::vector<std::string> targets;
  for (size_t f = 1; f < frames; ++f) {
    std::vector<Vec3> dp(base.size()), dn(base.size());
    const std::vector<Vec3> normals = vertex_normals(clip.positions[f], clip.faces);
    for (size_t v = 0; v < base.size(); ++v) {
      dp[v] = clip.positions[f][v] - base[v];
      dn[v] = normals[v] - base_normals[v];
    }
    const int p = b.floats(flat(dp), 3, "VEC3", kArrayBuffer, true);
    const int n = b.floats(flat(dn), 3, "VEC3", kArrayBuffer, false);
    targets.push_back("{\"POSITION\":" + std::to_string(p) + ",\"NORMAL\":" + std::to_string(n) + "}");
  }
  std::ostringstream json;
  json.precision(9);
  json << "{\"asset\":{\"version\":\"2.0\",\"generator\":\"facemorph fmdec\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
       << "\"nodes\":[{\"mesh\":0,\"name\":\"" << clip.name << "\"}],";
  json << "\"meshes\":[{\"name\":\"" << clip.name << "\",\"primitives\":[{\"attributes\":{\"POSITION\":" << position << ",\"NORMAL\":" << normal;
  if (uv >= 0) json << ",\"TEXCOORD_0\":" << uv;
  json << "},\"indices\":" << index << ",\"material\":0";
  if (!targets.empty()) json << ",\"targets\":" << GlbBuilder::join(targets);
  json << "}]";
  if (!targets.empty()) json << ",\"weights\":" << GlbBuilder::list(std::vector<float>(targets.size(), 0.0f));
  json << "}],";
  // The material: the texture when there is one, a skin-grey otherwise; double-sided, since a face
  // scan is an open surface seen from behind at its rim.
  if (!clip.texture.empty() && uv >= 0) {
    const std::vector<uint8_t> png = encode_png(clip.texture);
    const int image = b.view(png.data(), png.size(), 0);
    json << "\"images\":[{\"bufferView\":" << image << ",\"mimeType\":\"image/png\"}],\"samplers\":[{\"magFilter\":9729,\"minFilter\":9729,"
         << "\"wrapS\":33071,\"wrapT\":33071}],\"textures\":[{\"sampler\":0,\"source\":0}],"
         << "\"materials\":[{\"name\":\"skin\",\"doubleSided\":true,\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0},"
         << "\"metallicFactor\":0,\"roughnessFactor\":0.8}}],";
  } else {
    json << "\"materials\":[{\"name\":\"skin\",\"doubleSided\":true,\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.8,0.8,0.8,1],"
         << "\"metallicFactor\":0,\"roughnessFactor\":0.8}}],";
  }
  if (!targets.empty()) {
    // Weights one-hot at each frame's time (all zero at frame 0, the base), linear between.
    std::vector<float> times, weights;
    for (size_t f = 0; f < frames; ++f) {
      times.push_back(static_cast<float>(clip.times[f] - clip.times.front()));
      for (size_t t = 0; t < targets.size(); ++t) weights.push_back(f >= 1 && t == f - 1 ? 1.0f : 0.0f);
    }
    const int input = b.floats(times, 1, "SCALAR", 0, true);
    const int output = b.floats(weights, 1, "SCALAR", 0, false);
    json << "\"animations\":[{\"name\":\"play\",\"samplers\":[{\"input\":" << input << ",\"output\":" << output
         << ",\"interpolation\":\"LINEAR\"}],\"channels\":[{\"sampler\":0,\"target\":{\"node\":0,\"path\":\"weights\"}}]}],";
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
        if (v < 0 || static_cast<size_t>(v) >= level.size()) throw Error(ErrorCode::kInvalidArgument, "faces_outside_holes: a face index beyond the levels");
        inside = inside && level[static_cast<size_t>(v)] < 0;
      }
      always_inside = always_inside && inside;
    }
    if (!always_inside) kept.push_back(f);
  }
  return kept;
}

}  // namespace facemorph
