// An opened .fmv file as a KeyframeSource (open_sequence_source, codec/decoder/container/sequence_file.hpp):
// keyframes decoded on demand into a cache bounded by the caller's memory budget, so what a player
// holds follows what it plays, not the file's length (spec/container.md §10.1).
#include "codec/decoder/container/sequence_file.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/decoder/container/opened_file.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <algorithm>
#include <list>
#include <mutex>
#include <variant>

namespace facemorph {

namespace {

// The most keys one frame of a spline kind blends, whatever the times (spec/container.md §10.3):
// the local kinds' windows, and for not-a-knot two rows of second-derivative weights, each cut where
// it has fallen below 2⁻⁶⁰ of its largest, at least 2× a key: at most 61 keys either side.
uint64_t window_bound(SplineKind kind) {
  switch (kind) {
    case SplineKind::kLinear: return 2;
    case SplineKind::kCatmullRom: return 4;
    case SplineKind::kLocalCubic: return 6;
    case SplineKind::kNotAKnot: return 124;
  }
  return 124;
}

// What the source and a decoder on it hold, in bytes (spec/container.md §10.1's terms).
struct MemoryPlan {
  uint64_t fields = 0;          // one keyframe's arrays as decoded (8 V, its fixed nodes, the vectors)
  uint64_t surface = 0;         // one keyframe's reconstructed surface (24 n)
  uint64_t texture = 0;         // one keyframe's RGB texture (3 M²)
  uint64_t in_flight = 0;       // decoding a keyframe: its chunk's payload, its codes, residuals and arrays, the previous one's codes;
                                // with texture groups, the AV1 decoder's reference frames
  uint64_t fixed = 0;           // G, the solver, one frame, the index, the file's bytes where they are copied
  uint64_t keyframes_kept = 0;  // keyframes the budget holds at once: fields, texture and surface each
};

// `window`: the keyframes one frame blends, which a decoder holds for the frame even where the cache
// has dropped them. `spline_bytes`: the rows of the spline a decoder keeps (KeyframeSpline::memory_bytes).
MemoryPlan plan_memory(const OpenedFile& file, uint64_t owned_bytes, uint64_t window, uint64_t spline_bytes, const DecoderLimits& limits) {
  MemoryPlan plan;
  const DiskGridShape shape = disk_grid_shape(file.shape().grid_n);
  const auto nodes = static_cast<uint64_t>(shape.interior_count + shape.rim_count);
  const uint64_t values = file.values_per_keyframe();
  const auto m = static_cast<uint64_t>(file.texture_size());
  plan.fields = 8 * values + 4 * nodes + 1024;
  plan.surface = 24 * nodes;
  plan.texture = 3 * m * m;
  // The payload too: a chunk decompresses to its stated size before it is decoded, and a file may
  // state any size up to the budget, so the largest one is counted, not assumed small.
  plan.in_flight = 24 * values + file.largest_payload() + file.texture_decoder_bytes();
  // A sixteenth of the budget is left to the allocator: memory freed inside the process is not all
  // returned to the system (measured: without it, fmplay peaked 9% over a 128 MiB budget).
  plan.fixed = estimated_memory_bytes(file.shape().grid_n, 0, file.texture_size(), values) + index_memory_bytes(file.keyframe_count()) +
               owned_bytes + spline_bytes + file.header_bytes() + window * (plan.fields + plan.texture) + limits.max_memory_bytes / 16;
  const uint64_t per_keyframe = plan.fields + plan.surface + plan.texture;
  const uint64_t needed = plan.fixed + plan.in_flight;
  plan.keyframes_kept = limits.max_memory_bytes > needed ? (limits.max_memory_bytes - needed) / per_keyframe : 0;
  return plan;
}

class FileSource final : public KeyframeSource {
 public:
  FileSource(std::variant<std::vector<uint8_t>, std::unique_ptr<format::MappedFile>, std::span<const uint8_t>> bytes,
             const std::string& source, const DecoderLimits& limits, SequenceFileInfo* info)
      : bytes_(std::move(bytes)),
        file_(view(), source, limits,
              [](uint32_t keyframes, SplineKind spline) { return std::min<uint64_t>(keyframes, window_bound(spline)); }),
        work_limit_(limits.max_work) {
    const size_t count = file_.keyframe_count();
    // The header's fields as a sequence in memory gives them (the shape has no keyframes: times,
    // poses, holes and texture are the file's, below).
    // The residual frames and patches moved, not copied: held once, as the budget counts them.
    OpenedFile::Frames frames = file_.take_frames();
    outline_ = outline_of(file_.shape());
    outline_.residuals = std::move(frames.residuals);
    outline_.patches = std::move(frames.patches);
    outline_.times.reserve(count);
    for (size_t k = 0; k < count; ++k) outline_.times.push_back(file_.keyframe_time(k));
    const KeyframeSpline spline(outline_.times, file_.shape().spline);
    // With residual frames (format 2.3) a frame may blend a few keys more than the spline alone.
    const auto window = static_cast<uint64_t>(residual_max_keys(spline, outline_.residuals));
    const uint64_t owned = std::holds_alternative<std::vector<uint8_t>>(bytes_) ? view().size() : 0;
    // The spline's rows and the residual frames: what a decoder keeps of the file's timing.
    uint64_t patch_nodes = 0;
    for (const FramePatch& p : outline_.patches) patch_nodes += p.nodes.size();
    const uint64_t timing = spline.memory_bytes() + outline_.residuals.size() * file_layout::kResidualMemoryBytes +
                            outline_.patches.size() * file_layout::kPatchMemoryBytes + patch_nodes * file_layout::kPatchNodeMemoryBytes;
    plan_ = plan_memory(file_, owned, window, timing, limits);
    if (plan_.keyframes_kept < window) {
      const uint64_t needed = plan_.fixed + plan_.in_flight + window * (plan_.fields + plan_.surface + plan_.texture);
      throw Error(ErrorCode::kLimit, source + ": a frame blends up to " + std::to_string(window) +
                                         " keyframes, which with G and its solver need about " + std::to_string(needed >> 20) +
                                         " MiB, over the memory limit of " + std::to_string(limits.max_memory_bytes >> 20) +
                                         " MiB (max_memory_bytes, --max-memory)");
    }
    cache_capacity_ = plan_.keyframes_kept * (plan_.fields + plan_.texture);
    fields_.resize(count, false, plan_.fields);
    textures_.resize(count, true, plan_.texture);
    // The index holds every keyframe's time and pose: nothing is decoded until a frame needs it.
    outline_.has_holes = file_.has_holes();
    outline_.texture_size = file_.texture_size();
    outline_.fixed_node_count = file_.fixed_node_count();
    outline_.poses.reserve(count);
    for (size_t k = 0; k < count; ++k) outline_.poses.push_back(file_.keyframe_pose(k));
    if (info) *info = file_.describe(false);  // no texture payload read at open
    // The walk read every chunk's header from a mapped file; those pages are the page cache's, but
    // they would count in the process's resident memory (and a cgroup's) until reclaimed.
    if (const auto* mapped = std::get_if<std::unique_ptr<format::MappedFile>>(&bytes_)) (*mapped)->release_pages();
  }

  const SequenceOutline& outline() const override { return outline_; }
  size_t surfaces_kept() const override { return static_cast<size_t>(plan_.keyframes_kept); }
  uint64_t bytes_held() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return held_bytes_;
  }

  std::shared_ptr<const Keyframe> keyframe(size_t k) const override { return keyframe(k, nullptr); }
  std::shared_ptr<const Keyframe> keyframe(size_t k, WorkMeter& work) const override { return keyframe(k, &work); }
  std::shared_ptr<const Image> texture(size_t k) const override { return texture(k, nullptr); }
  std::shared_ptr<const Image> texture(size_t k, WorkMeter& work) const override { return texture(k, &work); }
  uint64_t work_limit() const override { return work_limit_; }
  std::string name() const override { return file_.source(); }

 private:
  std::shared_ptr<const Keyframe> keyframe(size_t k, WorkMeter* work) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (k >= fields_.slots.size()) throw Error(ErrorCode::kInvalidArgument, file_.source() + ": no keyframe " + std::to_string(k));
    // A group's stream is read to its exact end (§7) before any of its keyframes is shown: a
    // stream that does not end where its chunk does is not the encoder's, whichever keyframe a
    // frame asks for first. Once it has, a keyframe dropped from the cache decodes only as far as itself.
    return fetch(fields_, k, file_.run_length(), work, true, [&](size_t first) { return file_.read_fields(first); });
  }

  size_t texture_owner(size_t k) const override {
    if (k >= textures_.slots.size()) throw Error(ErrorCode::kInvalidArgument, file_.source() + ": no keyframe " + std::to_string(k));
    return file_.texture_owner(k);
  }

  std::shared_ptr<const Image> texture(size_t k, WorkMeter* work) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (k >= textures_.slots.size() || !outline_.has_texture()) {
      throw Error(ErrorCode::kInvalidArgument, file_.source() + ": no texture for keyframe " + std::to_string(k));
    }
    // A run: one still, or a group's image sequence (format 2.1), decoded from its first frame. A
    // shared still (format 2.2) is held once, in its owner's slot, whichever keyframe asks.
    return fetch(textures_, file_.texture_owner(k), file_.texture_run_length(), work, false,
                 [&](size_t first) { return file_.read_textures(first); });
  }

  struct Entry {
    bool texture = false;
    size_t keyframe = 0;
    uint64_t bytes = 0;
  };
  template <typename T>
  struct Slot {
    std::shared_ptr<const T> value;
    std::list<Entry>::iterator where;
  };

  std::span<const uint8_t> view() const {
    if (const auto* owned = std::get_if<std::vector<uint8_t>>(&bytes_)) return *owned;
    if (const auto* borrowed = std::get_if<std::span<const uint8_t>>(&bytes_)) return *borrowed;
    return std::get<std::unique_ptr<format::MappedFile>>(bytes_)->bytes();
  }

  template <typename T>
  void touch(Slot<T>& slot) const {
    order_.splice(order_.begin(), order_, slot.where);
  }

  // A run a call's work limit stopped: its reader, where the next call goes on, and what it decoded
  // that is to be kept once the run has been read whole (fetch's `held`).
  template <typename T>
  struct Suspended {
    size_t first = 0;
    std::unique_ptr<OpenedFile::RunReader<T>> reader;
    std::vector<std::pair<size_t, std::shared_ptr<const T>>> held;
  };

  // One kind of thing the cache holds, a slot per keyframe: fields or textures.
  template <typename T>
  struct Shelf {
    std::vector<Slot<T>> slots;
    std::vector<std::pair<ErrorCode, std::string>> failures;  // the error and its message
    std::vector<bool> run_read_whole;                         // per run: decoded to its end once, without a fault
    Suspended<T> suspended;                                   // at most one run, the one a stopped call was decoding
    bool texture = false;
    uint64_t bytes_each = 0;  // as the plan counts one
    void resize(size_t count, bool is_texture, uint64_t bytes) {
      slots.resize(count);
      failures.resize(count);
      run_read_whole.resize(count);  // indexed by a run's first keyframe
      texture = is_texture;
      bytes_each = bytes;
    }
  };

  // Keyframe k's item from `shelf`, decoded where it is not held. A run (a group of keyframes, or a
  // keyframe alone) decodes from its first keyframe (`open(first)` gives its reader): the whole run
  // is kept where the cache holds it twice over (playing on needs the next keyframes), else only as
  // far as k. An item that did not decode fails at once the next time (§10.3: time follows the frame).
  // `read_whole`: the run is decoded to its end the first time (keyframes' streams, whose end is
  // checked), and what it hands over is kept only once all of it decoded; a fault anywhere in it
  // then fails every keyframe of the run. Otherwise (textures) a fault past k leaves k standing.
  // A stop by the call's work meter is no fault of the file: the run's reader is kept where it
  // stopped, with what it decoded, and the next call that needs the run goes on from there, so that
  // a run costing more than one call may do still decodes over several. One run is kept so, for
  // both shelves together (what §10.1 counts in flight: one payload and one image decoder's frames).
  template <typename T, typename Open>
  std::shared_ptr<const T> fetch(Shelf<T>& shelf, size_t k, size_t run_length, WorkMeter* work, bool read_whole, const Open& open) const {
    if (shelf.slots[k].value) {
      touch(shelf.slots[k]);
      return shelf.slots[k].value;
    }
    if (!shelf.failures[k].second.empty()) throw Error(shelf.failures[k].first, shelf.failures[k].second);
    const size_t first = k / run_length * run_length;
    const size_t run_end = std::min(first + run_length, shelf.slots.size());
    const bool whole_run = 2 * (run_end - first) * shelf.bytes_each <= cache_capacity_;
    const bool to_the_end = whole_run || (read_whole && !shelf.run_read_whole[first]);
    const size_t last = to_the_end ? run_end - 1 : k;
    Suspended<T>& run = shelf.suspended;
    const auto holds = [&](size_t j) {
      return std::any_of(run.held.begin(), run.held.end(), [j](const auto& item) { return item.first == j; });
    };
    // Another run's, or one that has passed k without keeping it: started again.
    if (run.reader && (run.first != first || (run.reader->next() > k && !holds(k)))) run = {};
    drop_suspended(fields_, &shelf);
    drop_suspended(textures_, &shelf);
    const auto wants = [&](size_t j) { return j == k || (whole_run && !shelf.slots[j].value); };
    // What an earlier call kept for itself is dropped: a run's held items are one call's, as ever.
    std::erase_if(run.held, [&](const auto& item) { return !wants(item.first); });
    std::shared_ptr<const T> wanted;
    for (const auto& [j, item] : run.held) {
      if (j == k) wanted = item;
    }
    try {
      if (!run.reader) {
        run.first = first;
        run.reader = open(first);
      }
      while (run.reader->next() <= last) {
        const size_t j = run.reader->next();
        uint64_t bytes = 0;
        std::optional<T> item = run.reader->read(work, wants(j), bytes);
        if (!item || !wants(j)) continue;
        auto shared = std::make_shared<const T>(std::move(*item));
        if (j == k) wanted = shared;
        if (read_whole) {
          run.held.emplace_back(j, std::move(shared));
        } else {
          remember(shelf, j, std::move(shared));
        }
      }
      if (last + 1 == run.reader->end()) run.reader->finish();
    } catch (const Error& e) {
      if (work != nullptr && work->stopped()) throw;  // the run stays where it stopped
      std::vector<std::pair<size_t, std::shared_ptr<const T>>> held = std::move(run.held);
      run = {};
      if (!read_whole) {
        // Past k, in the rest of a whole run: k stands; the failing keyframe fails when asked for.
        if (wanted) return wanted;
        // kLimit too: the same file under the same limits fails the same way.
        shelf.failures[k] = {e.code(), e.what()};
        throw;
      }
      for (size_t j = first; j < run_end; ++j) {
        if (!shelf.slots[j].value) shelf.failures[j] = {e.code(), e.what()};
      }
      throw;
    }
    if (to_the_end) shelf.run_read_whole[first] = true;
    for (auto& [j, item] : run.held) remember(shelf, j, std::move(item));
    run = {};
    return wanted;
  }

  // Forgets the run a stopped call left on `shelf` unless it is `keep` (fetch: one kept at a time).
  template <typename T, typename Keep>
  void drop_suspended(Shelf<T>& shelf, const Keep* keep) const {
    if (static_cast<const void*>(&shelf) != static_cast<const void*>(keep)) shelf.suspended = {};
  }

  template <typename T>
  void remember(Shelf<T>& shelf, size_t k, std::shared_ptr<const T> item) const {
    Slot<T>& slot = shelf.slots[k];
    if (slot.value) return;
    // The list entry first: if it cannot be allocated, nothing is cached uncounted.
    slot.where = order_.insert(order_.begin(), Entry{shelf.texture, k, shelf.bytes_each});
    slot.value = std::move(item);
    held_bytes_ += shelf.bytes_each;
    evict();
  }

  // Drops the least recently used until the cache is within its capacity (a caller may still hold
  // what is dropped: the decoder, for the frame it is decoding).
  void evict() const {
    while (held_bytes_ > cache_capacity_ && !order_.empty()) {
      const Entry& oldest = order_.back();
      if (oldest.texture) {
        textures_.slots[oldest.keyframe].value.reset();
      } else {
        fields_.slots[oldest.keyframe].value.reset();
      }
      held_bytes_ -= oldest.bytes;
      order_.pop_back();
    }
  }

  std::variant<std::vector<uint8_t>, std::unique_ptr<format::MappedFile>, std::span<const uint8_t>> bytes_;
  OpenedFile file_;
  MemoryPlan plan_;
  SequenceOutline outline_;
  uint64_t cache_capacity_ = 0;  // bytes of fields and textures kept
  uint64_t work_limit_ = 0;      // per decode call (DecoderLimits::max_work)
  mutable std::mutex mutex_;
  mutable Shelf<Keyframe> fields_;
  mutable Shelf<Image> textures_;
  mutable std::list<Entry> order_;  // most recently used first
  mutable uint64_t held_bytes_ = 0;
};

}  // namespace

std::shared_ptr<const KeyframeSource> open_sequence_source(const std::filesystem::path& path, const DecoderLimits& limits,
                                                           SequenceFileInfo* info) {
  check_decoder_limits(limits);
  return std::make_shared<FileSource>(std::make_unique<format::MappedFile>(path), path.string(), limits, info);
}

std::shared_ptr<const KeyframeSource> open_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                           const DecoderLimits& limits, SequenceFileInfo* info) {
  check_decoder_limits(limits);
  if (bytes.size() > limits.max_memory_bytes) {
    throw Error(ErrorCode::kLimit, source + ": " + std::to_string(bytes.size()) + " bytes, over the memory limit of " +
                                       std::to_string(limits.max_memory_bytes));
  }
  return std::make_shared<FileSource>(std::vector<uint8_t>(bytes.begin(), bytes.end()), source, limits, info);
}

std::shared_ptr<const KeyframeSource> open_borrowed_sequence_source(std::span<const uint8_t> bytes, const std::string& source,
                                                                    const DecoderLimits& limits) {
  check_decoder_limits(limits);
  return std::make_shared<FileSource>(bytes, source, limits, nullptr);
}

}  // namespace facemorph
