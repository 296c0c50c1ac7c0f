#include "codec/encoder/encode/selection_store.hpp"

#include "format/error.hpp"

#include "codec/encoder/encode/spill_bytes.hpp"

#include <algorithm>
#include <string>

namespace facemorph {

SelectionStore::SelectionStore(const std::vector<SelectionFrame>& outlines, SpillMode mode, uint64_t cache_bytes)
    : outlines_(outlines), mode_(mode), file_("the selection's samples") {
  records_.resize(outlines.size());
  stored_.assign(outlines.size(), 0);
  in_memory_.resize(outlines.size());
  cache_bytes_ = cache_bytes;
}

std::shared_ptr<const SelectionFrame> SelectionStore::assemble(size_t i, std::vector<Eigen::Vector3f>&& local,
                                                               std::vector<Eigen::Vector3f>&& normal) const {
  SelectionFrame frame;
  frame.time = outlines_[i].time;
  frame.pose = outlines_[i].pose;
  frame.diagonal = outlines_[i].diagonal;
  frame.local = std::move(local);
  frame.normal = std::move(normal);
  return counted(std::move(frame), std::make_unique<ResidentHold>(count_));
}

void SelectionStore::put(size_t i, std::vector<Eigen::Vector3f>&& local, std::vector<Eigen::Vector3f>&& normal) {
  if (i >= outlines_.size()) throw Error(ErrorCode::kInternal, "selection store: frame " + std::to_string(i) + " is past its size");
  if (mode_ == SpillMode::kMemory) {
    std::shared_ptr<const SelectionFrame> frame = assemble(i, std::move(local), std::move(normal));
    std::lock_guard lock(mutex_);
    in_memory_[i] = std::move(frame);
    stored_[i] = 1;
    return;
  }
  spill::Writer w;
  w.array(local);
  w.array(normal);
  const std::vector<char> bytes = w.take();
  const SpillFile::Record record = file_.append(bytes.data(), bytes.size());
  std::lock_guard lock(mutex_);
  records_[i] = record;
  stored_[i] = 1;
  frame_bytes_ = std::max<uint64_t>(frame_bytes_, bytes.size());
}

std::shared_ptr<const SelectionFrame> SelectionStore::sampled(size_t i) const {
  SpillFile::Record record;
  {
    std::lock_guard lock(mutex_);
    if (i >= outlines_.size() || !stored_[i])
      throw Error(ErrorCode::kInternal, "selection store: frame " + std::to_string(i) + " was never stored");
    if (in_memory_[i]) {
      if (mode_ == SpillMode::kSpill) recent_.splice(recent_.begin(), recent_, where_.at(i));
      return in_memory_[i];
    }
    record = records_[i];
    ++reads_;
  }
  const std::vector<char> bytes = file_.read(record);
  spill::Reader r(bytes.data(), bytes.size(), "selection store: a frame's samples");
  std::vector<Eigen::Vector3f> local = r.array<Eigen::Vector3f>();
  std::vector<Eigen::Vector3f> normal = r.array<Eigen::Vector3f>();
  if (!r.done()) throw Error(ErrorCode::kInternal, "selection store: a frame's samples have bytes left over");
  std::shared_ptr<const SelectionFrame> frame = assemble(i, std::move(local), std::move(normal));
  std::lock_guard lock(mutex_);
  if (in_memory_[i]) return in_memory_[i];  // another thread read it meanwhile
  in_memory_[i] = frame;
  recent_.push_front(i);
  where_[i] = recent_.begin();
  // The cache's size in frames (every frame has the same nodes), at least one.
  const uint64_t limit = std::max<uint64_t>(1, cache_bytes_ / std::max<uint64_t>(frame_bytes_, 1));
  while (recent_.size() > limit) {
    const size_t oldest = recent_.back();
    recent_.pop_back();
    where_.erase(oldest);
    in_memory_[oldest].reset();  // gone once its last user lets go
  }
  return frame;
}

uint64_t SelectionStore::reads() const {
  std::lock_guard lock(mutex_);
  return reads_;
}

}  // namespace facemorph
