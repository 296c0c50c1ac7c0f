// The map stage's state: the store, the summaries and the reference's pin (frame_maps.hpp).
#include "codec/encoder/encode/frame_maps.hpp"

#include <algorithm>

namespace facemorph {

void FrameMaps::start(size_t count, FrameStore::Mode mode) {
  store_ = std::make_unique<FrameStore>(mode);
  store_->reset(count);
  pinned_index_ = -1;
  pinned_.reset();
  summaries.clear();
  textures.clear();
}

std::shared_ptr<const MappedFrame> FrameMaps::frame(int i) const {
  if (i == pinned_index_) return pinned_;
  return store_->get(static_cast<size_t>(i));
}

std::shared_ptr<const MappedFrame> FrameMaps::pin(int i) {
  if (pinned_index_ != i) {
    pinned_.reset();  // first: the old one need not be held beside the new
    pinned_ = store_->get(static_cast<size_t>(i));
    pinned_index_ = i;
  }
  return pinned_;
}

void FrameMaps::pin(int i, std::shared_ptr<const MappedFrame> map) {
  pinned_index_ = i;
  pinned_ = std::move(map);
}

bool FrameMaps::has_texture(int i) const {
  const auto index = static_cast<size_t>(i);
  const FrameSummary& f = summaries[index];
  return (!textures[index].empty() && f.has_uvs) || f.has_colours;
}

void FrameMaps::keep(const std::vector<size_t>& kept, size_t before) {
  auto compact = [&](auto& items) {
    if (items.size() != before) return;
    std::remove_reference_t<decltype(items)> out;
    out.reserve(kept.size());
    for (size_t i : kept) out.push_back(std::move(items[i]));
    items = std::move(out);
  };
  compact(summaries);
  if (store_->size() == before) store_->keep(kept);
  if (pinned_index_ >= 0) {
    // The pinned frame keeps its pin under its new index (a dropped one loses it).
    const auto it = std::find(kept.begin(), kept.end(), static_cast<size_t>(pinned_index_));
    pinned_index_ = it == kept.end() ? -1 : static_cast<int>(it - kept.begin());
    if (pinned_index_ < 0) pinned_.reset();
  }
  compact(textures);
}

}  // namespace facemorph
