// Texture groups' payloads (TGOP: a group of keyframes' textures as one AV1 image sequence) as a
// layout coded them, kept for a later layout of the same textures: the encoder measures its file's
// size before it writes the file (the density-equalised disk's comparison, spec/method.md §7.11),
// and AV1 is most of a textured encode's cost (spec/method.md §3.3, *Textures coded once*).
#pragma once

#include <compare>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <vector>

namespace facemorph {

class TextureGroupCache {
 public:
  // What decides a group's payload: its first keyframe (the payload names it), the quality its
  // sequence is coded at, and its images' pixels (image_content_hash of each, in order: 64-bit
  // FNV-1a, where two different textures of one encode colliding is a 2⁻⁶⁴ chance a pair).
  struct Key {
    size_t first = 0;
    int quality = 0;
    std::vector<uint64_t> images;
    auto operator<=>(const Key&) const = default;
  };
  // The payload kept for `key`, if any. Called from any thread.
  std::optional<std::vector<uint8_t>> find(const Key& key) const;
  void keep(Key key, std::vector<uint8_t> payload);
  size_t size() const;

 private:
  mutable std::mutex mutex_;
  std::map<Key, std::vector<uint8_t>> payloads_;
};

}  // namespace facemorph
