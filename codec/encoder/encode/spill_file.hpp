// The encoder's spill: an unlinked temporary file of byte records (format/spill_file.hpp, which the
// container writer spills to as well), and the count of the records' contents in memory
// (spec/method.md §7.15).
//
// What the encoder makes of every frame or keyframe and needs again at a later stage is written here
// as soon as it is made and read back when a stage asks, so memory holds the few being worked on,
// not the capture's. FrameStore keeps the frames' maps in one, KeyframeStore the keyframes' arrays.
#pragma once

#include "format/spill_file.hpp"

#include "format/error.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
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

// Items numbered 0..size()-1, each kept in memory or as a record of a spill file: the bookkeeping
// every store shares whose items are read back whole when a stage asks (FrameStore, KeyframeStore,
// RegistrationStore, the encoder's landmarks). Thread-safe for different items. With a count, every
// item handed out is counted in it while it lives (in memory: from put on).
template <typename T>
class SpilledItems {
 public:
  using Serialize = std::function<std::vector<char>(const T&)>;
  using Deserialize = std::function<T(const char*, size_t)>;
  // `contents` names the file's contents in errors ("the frames' maps"), `item` an item in the
  // store's own errors ("frame store: frame").
  SpilledItems(SpillMode mode, std::string contents, std::string item, Serialize serialize, Deserialize deserialize,
               std::shared_ptr<ResidentCount> count = nullptr)
      : mode_(mode),
        item_(std::move(item)),
        file_(std::move(contents)),
        serialize_(std::move(serialize)),
        deserialize_(std::move(deserialize)),
        count_(std::move(count)) {}
  SpilledItems(const SpilledItems&) = delete;
  SpilledItems& operator=(const SpilledItems&) = delete;

  SpillMode mode() const { return mode_; }
  // Forgets every item and makes room for `count` (the file, if any, is emptied).
  void reset(size_t count) {
    std::lock_guard lock(mutex_);
    entries_.assign(count, {});
    file_.clear();
  }
  size_t size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
  }
  // Stores item i (i < size()), replacing what it was: spilled, the new bytes are appended and the
  // old ones stay in the file until reset. Throws kInternal for i past the size, kIo when the file
  // cannot be written.
  void put(size_t i, T&& item) {
    if (i >= size()) throw Error(ErrorCode::kInternal, item_ + " " + std::to_string(i) + " is past its size");
    Entry entry;
    entry.stored = true;
    if (mode_ == SpillMode::kMemory) {
      entry.item = count_ ? counted(std::move(item), std::make_unique<ResidentHold>(count_)) : std::make_shared<const T>(std::move(item));
    } else {
      const std::vector<char> bytes = serialize_(item);
      entry.record = file_.append(bytes.data(), bytes.size());
    }
    std::lock_guard lock(mutex_);
    entries_[i] = std::move(entry);
  }
  // Stores item i as bytes that `source` gives when asked (each get asks again), in the byte form
  // deserialize reads: an item already kept elsewhere (a part file's record) is not copied here.
  using Source = std::function<std::vector<char>()>;
  void put_source(size_t i, Source source) {
    if (i >= size()) throw Error(ErrorCode::kInternal, item_ + " " + std::to_string(i) + " is past its size");
    Entry entry;
    entry.stored = true;
    entry.source = std::move(source);
    std::lock_guard lock(mutex_);
    entries_[i] = std::move(entry);
  }
  // Item i: the one in memory, or read back (a copy). Throws kInternal for an item never stored,
  // kIo on a failed read.
  std::shared_ptr<const T> get(size_t i) const {
    Entry entry;
    {
      std::lock_guard lock(mutex_);
      if (i >= entries_.size() || !entries_[i].stored)
        throw Error(ErrorCode::kInternal, item_ + " " + std::to_string(i) + " was never stored");
      entry = entries_[i];
    }
    if (entry.item) return entry.item;
    if (entry.source) {
      auto hold = count_ ? std::make_unique<ResidentHold>(count_) : nullptr;
      std::vector<char> bytes = entry.source();
      T item = deserialize_(bytes.data(), bytes.size());
      bytes = {};
      return hold ? counted(std::move(item), std::move(hold)) : std::make_shared<const T>(std::move(item));
    }
    if (count_) return read_counted<T>(file_, entry.record, count_, deserialize_);
    const std::vector<char> bytes = file_.read(entry.record);
    return std::make_shared<const T>(deserialize_(bytes.data(), bytes.size()));
  }
  // Keeps the items at indices `kept` (increasing), renumbered 0.. in that order.
  void keep(const std::vector<size_t>& kept) {
    std::lock_guard lock(mutex_);
    std::vector<Entry> out;
    out.reserve(kept.size());
    for (size_t i : kept) out.push_back(std::move(entries_.at(i)));
    entries_ = std::move(out);
  }
  uint64_t spilled_bytes() const { return file_.size(); }

 private:
  struct Entry {
    SpillFile::Record record;
    std::shared_ptr<const T> item;  // kMemory
    Source source;                  // put_source
    bool stored = false;
  };
  SpillMode mode_;
  std::string item_;
  SpillFile file_;
  Serialize serialize_;
  Deserialize deserialize_;
  std::shared_ptr<ResidentCount> count_;  // shared with the items handed out, which may outlive the store
  mutable std::mutex mutex_;
  std::vector<Entry> entries_;
};

}  // namespace facemorph
