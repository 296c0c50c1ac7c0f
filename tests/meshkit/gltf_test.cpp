// glTF clips: the GLB container's structure, the morph animation's contract (frame f's shape at its
// time), hole collapse, and, where node and the Khronos validator are installed, 0 validator errors.
#include "codec/meshkit/gltf/gltf.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "format/file_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

namespace facemorph {
namespace {

uint32_t u32(const std::vector<uint8_t>& b, size_t at) {
  uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | b[at + static_cast<size_t>(i)];
  return v;
}

GltfClip wave_clip(int frames) {
  const DiskGrid grid = make_disk_grid(9);
  GltfClip clip;
  clip.faces = grid.faces;
  for (const Vec2& w : grid.nodes) clip.uvs.push_back(0.5 * (w + Vec2(1, 1)));
  for (int f = 0; f < frames; ++f) {
    clip.times.push_back(f / 30.0);
    std::vector<Vec3> p;
    for (const Vec2& w : grid.nodes) p.push_back(Vec3(w.x(), w.y(), 0.1 * std::sin(f + 3 * w.x())));
    clip.positions.push_back(std::move(p));
  }
  clip.texture = Image(8, 8, 3);
  return clip;
}

TEST(Gltf, TheBinaryHasAHeaderAJsonChunkAndABinChunk) {
  const GltfClip clip = wave_clip(4);
  const std::vector<uint8_t> glb = encode_glb(clip);
  ASSERT_GE(glb.size(), 28u);
  EXPECT_EQ(u32(glb, 0), 0x46546C67u);  // "glTF"
  EXPECT_EQ(u32(glb, 4), 2u);
  EXPECT_EQ(u32(glb, 8), glb.size());
  const uint32_t json_size = u32(glb, 12);
  EXPECT_EQ(u32(glb, 16), 0x4E4F534Au);  // "JSON"
  EXPECT_EQ(json_size % 4, 0u);
  const std::string json(glb.begin() + 20, glb.begin() + 20 + json_size);
  const size_t bin = 20 + json_size;
  EXPECT_EQ(u32(glb, bin + 4), 0x004E4942u);  // "BIN\0"
  EXPECT_EQ(bin + 8 + u32(glb, bin), glb.size());
  // Three morph targets (frames 1-3 over frame 0), an animation of their weights, the texture.
  size_t targets = 0;
  for (size_t at = json.find("\"POSITION\""); at != std::string::npos; at = json.find("\"POSITION\"", at + 1)) ++targets;
  EXPECT_EQ(targets, 1u + 3u);
  EXPECT_NE(json.find("\"path\":\"weights\""), std::string::npos);
  EXPECT_NE(json.find("\"mimeType\":\"image/png\""), std::string::npos);
  EXPECT_NE(json.find("\"count\":" + std::to_string(clip.faces.size() * 3)), std::string::npos);
}

// The keyframes' textures switched by the animation: a node, mesh and material per texture sharing
// every accessor, each node's scale STEP-animated to its own while its texture is current and to 0
// otherwise; WebP (EXT_texture_webp, required) in a compact clip, PNG in a float one.
TEST(Gltf, SwitchedTexturesAreANodeEachShownInTurn) {
  GltfClip clip = wave_clip(5);
  clip.texture = {};
  for (int i = 0; i < 3; ++i) {
    Image image(8, 8, 3);
    std::fill(image.pixels.begin(), image.pixels.end(), static_cast<uint8_t>(60 * i));
    clip.switched_textures.push_back({i == 0 ? 0.0 : i / 30.0 + 0.01, image});
  }
  for (const bool compact : {false, true}) {
    clip.compact = compact;
    const std::vector<uint8_t> glb = encode_glb(clip);
    const std::string json(glb.begin() + 20, glb.begin() + 20 + u32(glb, 12));
    const auto count = [&](const std::string& what) {
      size_t n = 0;
      for (size_t at = json.find(what); at != std::string::npos; at = json.find(what, at + 1)) ++n;
      return n;
    };
    EXPECT_NE(json.find("\"scenes\":[{\"nodes\":[0,1,2]}]"), std::string::npos) << json;
    EXPECT_EQ(count("\"path\":\"scale\""), 3u);
    EXPECT_EQ(count("\"path\":\"weights\""), 3u);
    EXPECT_EQ(count("\"interpolation\":\"STEP\""), 3u);
    EXPECT_EQ(count("\"baseColorTexture\""), 3u);
    EXPECT_EQ(count(compact ? "\"mimeType\":\"image/webp\"" : "\"mimeType\":\"image/png\""), 3u);
    EXPECT_EQ(json.find("EXT_texture_webp") != std::string::npos, compact);
  }
  clip.switched_textures[2].start = clip.switched_textures[1].start;
  testing::expect_error(ErrorCode::kInvalidArgument, "strictly increasing", [&] { encode_glb(clip); });
  clip.switched_textures.resize(1);
  testing::expect_error(ErrorCode::kInvalidArgument, "one switched texture", [&] { encode_glb(clip); });
}

TEST(Gltf, BadClipsAreNamedErrors) {
  GltfClip clip = wave_clip(3);
  clip.times[2] = clip.times[1];
  testing::expect_error(ErrorCode::kInvalidArgument, "strictly increasing", [&] { encode_glb(clip); });
  clip = wave_clip(3);
  clip.positions[1].pop_back();
  testing::expect_error(ErrorCode::kInvalidArgument, "frame 1", [&] { encode_glb(clip); });
  clip = wave_clip(3);
  clip.faces[0][0] = 10000;
  testing::expect_error(ErrorCode::kInvalidArgument, "out of range", [&] { encode_glb(clip); });
  testing::expect_error(ErrorCode::kInvalidArgument, "at least one frame", [&] { encode_glb(GltfClip{}); });
}

TEST(Gltf, OnlyTrianglesInsideAHoleThroughoutAreDropped) {
  const DiskGrid grid = make_disk_grid(17);
  const auto levels_for = [&](double radius) {
    std::vector<double> level;
    for (const Vec2& w : grid.nodes) level.push_back(w.norm() - radius);
    return level;
  };
  const auto inside = [&](const Face& f, double radius) {
    for (int32_t v : f) {
      if (grid.nodes[static_cast<size_t>(v)].norm() >= radius) return false;
    }
    return true;
  };
  // A hole of radius 0.3 in one frame and 0.5 in the next: what is inside 0.3 goes.
  const std::vector<Face> kept = faces_outside_holes(grid.faces, {levels_for(0.3), levels_for(0.5)});
  size_t expected = 0;
  for (const Face& f : grid.faces) expected += !inside(f, 0.3);
  EXPECT_EQ(kept.size(), expected);
  EXPECT_LT(kept.size(), grid.faces.size());
  for (const Face& f : kept) EXPECT_FALSE(inside(f, 0.3));
  // A frame without the hole keeps every triangle; no frames keep every triangle.
  EXPECT_EQ(faces_outside_holes(grid.faces, {levels_for(0.3), levels_for(-1)}).size(), grid.faces.size());
  EXPECT_EQ(faces_outside_holes(grid.faces, {}).size(), grid.faces.size());
}

// Normals (issue 48 part 4): in the base and every morph target of both kinds of clip, so a viewer
// shades the face smoothly; none with `normals` off (fmdec --glb-flat), which then flat-shades.
// Their values against the decoder's are web/test/gltf_check.mjs's (Web.CompactGltfClipMatchesFloats).
TEST(Gltf, ClipsCarryNormalsUnlessAskedNot) {
  const auto count = [](const std::vector<uint8_t>& glb, const std::string& what) {
    const std::string json(glb.begin() + 20, glb.begin() + 20 + u32(glb, 12));
    size_t n = 0;
    for (size_t at = json.find(what); at != std::string::npos; at = json.find(what, at + 1)) ++n;
    return n;
  };
  for (bool compact : {false, true}) {
    SCOPED_TRACE(compact ? "compact" : "float");
    GltfClip clip = wave_clip(4);
    clip.compact = compact;
    EXPECT_EQ(count(encode_glb(clip), "\"NORMAL\""), 1u + 3u);
    clip.normals = false;
    EXPECT_EQ(count(encode_glb(clip), "\"NORMAL\""), 0u);
    EXPECT_EQ(count(encode_glb(clip), "\"POSITION\""), 1u + 3u);
  }
}

// The Khronos glTF validator (npm gltf-validator) finds no error; skipped without node or the
// validator (in build-web/npm, where tools/install-deps.sh puts it; FACEMORPH_GLTF_VALIDATOR may
// name another folder whose node_modules holds it).
TEST(Gltf, TheKhronosValidatorFindsNoError) {
  const char* given = std::getenv("FACEMORPH_GLTF_VALIDATOR");
  const std::string folder = given ? given : FACEMORPH_NPM_DIR;
  if (std::system("command -v node >/dev/null 2>&1") != 0) GTEST_SKIP() << "node absent";
  const std::filesystem::path modules = std::filesystem::path(folder) / "node_modules" / "gltf-validator";
  if (!std::filesystem::exists(modules)) GTEST_SKIP() << "no gltf-validator in " << folder;
  testing::TempDir dir;
  // A plain clip, and one whose keyframes' textures switch, in floats and compact.
  GltfClip switching = wave_clip(5);
  for (int i = 0; i < 2; ++i) switching.switched_textures.push_back({i / 15.0, Image(8, 8, 3)});
  std::vector<std::pair<std::string, GltfClip>> clips = {{"clip.glb", wave_clip(5)}, {"switching.glb", switching}};
  switching.compact = true;
  clips.emplace_back("switching_compact.glb", switching);
  for (const auto& [name, clip] : clips) {
    SCOPED_TRACE(name);
    format::write_file_atomically(dir.path() / name, encode_glb(clip));
    const std::string script =
        "const v=require('" + modules.string() + "');const b=new Uint8Array(require('fs').readFileSync('" + (dir.path() / name).string() +
        "'));v.validateBytes(b).then(r=>{console.log(JSON.stringify(r.issues.messages));process.exit(r.issues.numErrors?1:0)})"
        ".catch(e=>{console.error(e);process.exit(2)})";
    testing::write_text(dir.path() / "validate.js", script);
    EXPECT_EQ(std::system(("node " + (dir.path() / "validate.js").string()).c_str()), 0);
  }
}

}  // namespace
}  // namespace facemorph
