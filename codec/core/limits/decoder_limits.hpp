// What a decoder may spend on a file it did not write (spec/container.md §10): the largest grid,
// keyframe count and texture a file may state, and a memory budget. Every size a file states is
// compared with these and with the bytes the file actually has before anything is allocated; a file
// over a limit is refused with kLimit naming the limit (zstd's ZSTD_d_windowLogMax, libavif's
// imageDimensionLimit). The defaults hold every grid and texture size facemorph's encoder chooses
// automatically (N <= 1025, M <= 1024). Keyframes are decoded on demand (open_sequence_source): the
// memory budget sets how many an opened file and a decoder on it keep at once, never fewer than a
// frame blends (§10.1), whatever the file's length. decode_sequence_file, which decodes a file
// whole, holds every keyframe and is refused where they exceed the budget.
#pragma once

#include <cstdint>
#include <string>

namespace facemorph {

struct DecoderLimits {
  int max_grid_n = 1025;                            // N of the disk grid G (the format allows up to 4097)
  uint32_t max_keyframes = 65536;                   // keyframes in one file (the format allows up to 2^20)
  int max_texture_size = 4096;                      // M, texels per side (the format allows up to 16384)
  uint64_t max_memory_bytes = uint64_t{256} << 20;  // what an opened file and one decoder on it may hold, bytes
  // What one decode call may do, in work units (WorkMeter; spec/container.md §10.3): about a second
  // on one core of the reference machine. 0: no bound.
  uint64_t max_work = kDefaultMaxWork;
  static constexpr uint64_t kDefaultMaxWork = 16'000'000;
};

inline constexpr DecoderLimits kDefaultDecoderLimits{};

// The work of one decode call, counted as it is done (spec/container.md §10.3). A unit is about
// 75 ns on one core of the reference machine: a node of G in one reconstruction iteration (a
// multigrid V-cycle and the frames of the right-hand side, 0.25-0.4 µs) is 4, a keyframe's value
// decoded from its group's stream (15-24 ns) 1 and 20 of its decisions beyond 2 a value 1
// (decision_units: residuals near 2^30 take 69), a texture pixel decoded 1 from AVIF (about
// 90 ns, in sequences of 1024²) and 3 from WebP (lossless: about 300 ns). A call that would pass its limit stops before
// the step that would, with kLimit naming max_work; what it finished (keyframes decoded, surfaces
// reconstructed, an interrupted reconstruction's iterate) is kept, so the next call goes on from there.
class WorkMeter {
 public:
  // `limit` 0: no bound. `where` opens the message of the kLimit thrown (the file, t).
  explicit WorkMeter(uint64_t limit, std::string where = {}) : limit_(limit), where_(std::move(where)) {}
  // Units per node and iteration, per decoded array value, per decoded texture pixel.
  static constexpr uint64_t kPerNodeIteration = 4, kPerValue = 1, kPerPixel = 1, kPerWebpPixel = 3;
  // A value's unit covers its first kDecisionsInValue range-coder decisions and direct bits (a
  // residual of |r| <= 1 takes 1-3; an encoder's files stay within 2 a value on average); beyond
  // them, a unit per kDecisionsPerUnit (2.2-3 ns each measured: 20 are 45-60 ns of the unit's 75).
  // A residual near 2^30 takes 69 (charged 4.35 units, measured 2.1-3.1), one near 2^34 at most 79
  // (4.85 units; charged after the keyframe, so a call passes its limit by at most that).
  static constexpr uint64_t kDecisionsInValue = 2, kDecisionsPerUnit = 20;
  // The units of decoding `values` values that took `decisions` decisions and direct bits
  // (RangeDecoder::decisions) beyond the values' own kPerValue: the one rule for a stream's work.
  static constexpr uint64_t decision_units(uint64_t decisions, uint64_t values) {
    const uint64_t covered = values * kDecisionsInValue;
    return decisions <= covered ? 0 : (decisions - covered + kDecisionsPerUnit - 1) / kDecisionsPerUnit;
  }
  // Charges `units` for the step about to be done and returns true, or returns false (charging
  // nothing) where they would take the call past its limit.
  bool afford(uint64_t units) {
    if (limit_ != 0 && (units > limit_ || spent_ > limit_ - units)) return false;
    spent_ += units;
    return true;
  }
  // kLimit: `what` (the step not done) would pass the call's limit. Remembered (stopped()), so
  // that a caller tells this kLimit, after which the next call goes on, from the file's own.
  [[noreturn]] void refuse(const std::string& what);
  bool stopped() const { return stopped_; }
  // afford, or refuse.
  void charge(uint64_t units, const std::string& what) {
    if (!afford(units)) refuse(what);
  }
  // Counts `units` of work already done, which a step learns only as it does it (a stream's
  // decisions): they may take the call past its limit, and then the next step is refused.
  void spend(uint64_t units) { spent_ = units > UINT64_MAX - spent_ ? UINT64_MAX : spent_ + units; }
  uint64_t spent() const { return spent_; }
  uint64_t limit() const { return limit_; }

 private:
  uint64_t limit_ = 0, spent_ = 0;
  std::string where_;
  bool stopped_ = false;
};

// What decoding from a file holds at most, in bytes, from what its header states, with `keyframes`
// keyframes held at once: their fields (`values_per_keyframe` float64 values), textures (RGB8) and
// reconstructed surfaces, G with its multigrid solver, and one decoded frame. An
// estimate that errs high (spec/container.md §10.1 gives the constants); it saturates at
// UINT64_MAX instead of overflowing.
uint64_t estimated_memory_bytes(int grid_n, uint64_t keyframes, int texture_size, uint64_t values_per_keyframe);

// What an opened file holds per keyframe whatever is decoded: its time, pose, index entry and
// byte counts, a decoder's slot for its surface (spec/container.md §10.1: 256 bytes a keyframe).
uint64_t index_memory_bytes(uint64_t keyframes);

// Throws kInvalidArgument for limits a decoder cannot run under (a grid below 5, no keyframe, no
// memory); `what` names the caller's option.
void check_decoder_limits(const DecoderLimits& limits, const std::string& what = "decoder limits");

}  // namespace facemorph
