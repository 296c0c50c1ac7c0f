// The encoder's spill: an unlinked temporary file of byte records (format/spill_file.hpp, which the
// container writer spills to as well), and the count of the records' contents in memory
// (spec/method.md §7.15).
//
// What the encoder makes of every frame or keyframe and needs again at a later stage is written here
// as soon as it is made and read back when a stage asks, so memory holds the few being worked on,
// not the capture's. FrameStore keeps the frames' maps in one, KeyframeStore the keyframes' arrays.
#pragma once

#include "format/spill_file.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace facemorph {

// Where a store keeps its items.
enum class SpillMode {
  kSpill,   // in an unlinked temporary file (in TMPDIR); memory holds those in use
  kMemory,  // in memory: memory grows with the items (what the encoder did before)
};

using format::SpillFile;

// How many items a store has in memory now, and at most since the counter was last reset: the
// tests' and the report's measure that memory does not grow with the capture. A ResidentHold
// counts one while it lives.
struct ResidentCount {
  std::atomic<int> now{0}, peak{0};
  void reset_peak() { peak = now.load(); }
};

class ResidentHold {
 public:
  explicit ResidentHold(std::shared_ptr<ResidentCount> count);
  ~ResidentHold();
  ResidentHold(const ResidentHold&) = delete;
  ResidentHold& operator=(const ResidentHold&) = delete;

 private:
  std::shared_ptr<ResidentCount> count_;
};

// `item` handed out as a pointer that holds `hold` (counted) until its last copy goes.
template <typename T>
std::shared_ptr<const T> counted(T&& item, std::unique_ptr<ResidentHold> hold) {
  struct Held {
    T item;
    std::unique_ptr<ResidentHold> hold;
  };
  auto held = std::make_shared<Held>(Held{std::move(item), std::move(hold)});
  return {held, &held->item};
}

// A record of `file` read back as an item by deserialize(bytes, size), counted in `count` from the
// read on (the bytes are an item's worth too) until its last pointer goes: what every store's get
// does with an item that is not in memory.
template <typename T, typename Deserialize>
std::shared_ptr<const T> read_counted(const SpillFile& file, const SpillFile::Record& record, const std::shared_ptr<ResidentCount>& count,
                                      const Deserialize& deserialize) {
  auto hold = std::make_unique<ResidentHold>(count);
  std::vector<char> bytes = file.read(record);
  T item = deserialize(bytes.data(), bytes.size());
  bytes = {};
  return counted(std::move(item), std::move(hold));
}

}  // namespace facemorph
