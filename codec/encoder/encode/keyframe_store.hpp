// Where the encoder keeps its keyframes' arrays between steps (spec/method.md §7.15).
//
// At N = 257 a keyframe's surface on G is 1.25 MB and its fields ~1.7 MB, and the steps after the
// selection come back to them: the keyframe fit reads every keyframe's surface twice, the fields
// are made from the fitted surfaces, and the field precision's search decodes every keyframe's exact
// fields once and compares each trial rounding with that surface, on every keyframe, at each of its
// refinements, for each candidate dead zone. Held in memory, they were ~4 MB a keyframe beside the
// output, and the search was where a long encode peaked. Spilled, an array is written to the
// encoder's temporary file when it is made and read back (a copy counted in held() while it lives)
// when a step needs it: memory holds one a thread.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/image/image.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/encoder/encode/spill_file.hpp"

#include <memory>
#include <vector>

namespace facemorph {

// T is std::vector<Vec3> (a surface on G), GridFields, std::vector<double> (a hole level) or Image
// (a texture).
template <typename T>
class KeyframeStore {
 public:
  using Mode = SpillMode;
  // `count` is shared between the stores of one step (the report gives one peak, since the count
  // was made); null: its own.
  explicit KeyframeStore(Mode mode, std::shared_ptr<ResidentCount> count = nullptr);
  KeyframeStore(const KeyframeStore&) = delete;
  KeyframeStore& operator=(const KeyframeStore&) = delete;

  Mode mode() const { return items_.mode(); }
  // Forgets every item and makes room for `count` (the file is emptied; the peak is kept).
  void reset(size_t count) { items_.reset(count); }
  size_t size() const { return items_.size(); }
  // Stores item k (k < size()), replacing what was stored there; may be called from several threads
  // for different k. Throws kInternal for k past the size, kIo when the file cannot be written.
  void put(size_t k, T&& item) { items_.put(k, std::move(item)); }
  // Item k as stored: read back from the file (a copy, counted in held() until its last pointer
  // goes) or the one in memory. Thread-safe. Throws kInternal for an item never stored, kIo on a
  // failed read.
  std::shared_ptr<const T> get(size_t k) const { return items_.get(k); }

  int held() const { return count_->now.load(); }
  int peak_held() const { return count_->peak.load(); }
  uint64_t spilled_bytes() const { return items_.spilled_bytes(); }  // 0 in memory

  // The byte form of an item in the file: what put writes and get reads. Public for the round-trip
  // test; deserialize throws kInternal for bytes cut short or left over.
  static std::vector<char> serialize(const T& item);
  static T deserialize(const char* bytes, size_t size);

 private:
  std::shared_ptr<ResidentCount> count_;  // shared with the items handed out, which may outlive the store
  SpilledItems<T> items_;
};

extern template class KeyframeStore<std::vector<Vec3>>;
extern template class KeyframeStore<GridFields>;
extern template class KeyframeStore<std::vector<double>>;
extern template class KeyframeStore<Image>;

using SurfaceStore = KeyframeStore<std::vector<Vec3>>;
using FieldsStore = KeyframeStore<GridFields>;
using HoleLevelStore = KeyframeStore<std::vector<double>>;
using TextureStore = KeyframeStore<Image>;

}  // namespace facemorph
