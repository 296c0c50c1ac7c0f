#include "codec/writer/container/texture_group_cache.hpp"

namespace facemorph {

std::optional<std::vector<uint8_t>> TextureGroupCache::find(const Key& key) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto found = payloads_.find(key);
  if (found == payloads_.end()) return std::nullopt;
  return found->second;
}

void TextureGroupCache::keep(Key key, std::vector<uint8_t> payload) {
  const std::lock_guard<std::mutex> lock(mutex_);
  payloads_.insert_or_assign(std::move(key), std::move(payload));
}

size_t TextureGroupCache::size() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return payloads_.size();
}

}  // namespace facemorph
