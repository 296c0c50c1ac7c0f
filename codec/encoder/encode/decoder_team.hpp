// Decoders for the encoder's fits that decode many frames of a stored sequence (residual_fit.hpp,
// patch_fit.hpp), one per thread: a SequenceDecoder is not thread-safe, several may share one source.
#pragma once

#include "codec/core/util/parallel.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"

#include <algorithm>
#include <functional>
#include <memory>
#include <vector>

namespace facemorph {

// `count` items in contiguous runs, run r on decoders[r], so that each decoder decodes its frames in
// time order and reconstructs the keyframes near them only.
class DecoderTeam {
 public:
  // Up to `threads` decoders (0: one per core), no more than `items`.
  DecoderTeam(const std::shared_ptr<const KeyframeSource>& source, int threads, size_t items) {
    const size_t size = std::max<size_t>(1, std::min(static_cast<size_t>(resolved_threads(threads)), items));
    // Each made on a thread of its own: a decoder's reconstructor builds its multigrid (tens of
    // milliseconds at N = 257), and one after another they were a serial stretch of every candidate
    // the choice by bytes measures (held_out_error). The source is read from any thread.
    decoders_.resize(size);
    parallel_for(static_cast<int>(size), static_cast<int>(size),
                 [&](int r) { decoders_[static_cast<size_t>(r)] = std::make_unique<SequenceDecoder>(source); });
  }
  SequenceDecoder& first() { return *decoders_.front(); }
  // body(decoder, i) for i in [0, count), items of one run on one decoder and thread. The caller
  // decodes each frame as a function of t alone (DecodeOptions::continue_correction off), so the
  // runs' split changes no result.
  void for_each(size_t count, const std::function<void(SequenceDecoder&, size_t)>& body) {
    parallel_runs(count, static_cast<int>(decoders_.size()), [&](size_t run, size_t first, size_t last) {
      for (size_t i = first; i < last; ++i) body(*decoders_[run], i);
    });
  }

 private:
  std::vector<std::unique_ptr<SequenceDecoder>> decoders_;
};

}  // namespace facemorph
