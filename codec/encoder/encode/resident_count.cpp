// Counting a store's items in memory (codec/encoder/encode/spill_file.hpp).
#include "codec/encoder/encode/spill_file.hpp"

namespace facemorph {

ResidentHold::ResidentHold(std::shared_ptr<ResidentCount> count) : count_(std::move(count)) {
  const int now = ++count_->now;
  int peak = count_->peak.load();
  while (now > peak && !count_->peak.compare_exchange_weak(peak, now)) {}
}

ResidentHold::~ResidentHold() { --count_->now; }

}  // namespace facemorph
