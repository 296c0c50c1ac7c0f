// The staged encode (spec/part-file.md): an encode's per-frame work split into parts that run
// anywhere (a cluster's array job), then one step that assembles them into the file.
//
//   sample    frames [first, end) of the capture prepared, mapped, registered to the reference and
//             sampled on the selection grid: a part file (part_file.hpp)
//   assemble  the parts that cover the capture: keyframes, N, the keyframes on G and their fit to
//             every frame, field precision, textures: what encode_capture_stored returns, the same
//             numbers, so the same file bytes
//
// Every part registers to the same reference: each settles it as the one-process encode does (the
// frame given, or where it cannot be mapped the nearest in time that can), and finds the up
// direction for frames whose surfaces do not say from the whole capture, as map_frames does.
#pragma once

#include "codec/encoder/encode/part_file.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"

#include <filesystem>
#include <functional>
#include <memory>
#include <vector>

namespace facemorph {

// Samples frames `range` of `capture` into the part file `path` (written whole or not at all).
// Throws kInvalidArgument for a range outside the capture, kUnsupported for options.track_landmarks
// (tracking runs from frame to frame across the whole capture), and what the encode would throw for
// these frames (options.strict) or when the reference and every frame near it cannot be mapped.
// Returns the part's header.
PartHeader encode_part(const Capture& capture, const EncodeOptions& options, FrameRange range, const std::filesystem::path& path);

// Assembles the parts (any order) into the encoded sequence, as encode_capture_stored does from the
// capture. The parts must come from one capture, with the sample settings `options` has
// (same_options of OptionsScope::kSample), and hold each of its frames once: otherwise kInvalidArgument naming the parts
// or the frames missing. The capture's texture images are read from where the parts name them.
// `header`: the first part's header (the capture's fps, units, landmark names).
std::unique_ptr<StoredSequence> assemble_parts(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options,
                                               EncodeReport* report = nullptr, PartHeader* header = nullptr);

// What reading the parts measured: their own stages' seconds, summed (each part's header holds
// its own), and the reading's. A value beside the encoder, not in its report, so that the
// assembler adds it to the report it returns (add_to) and reads nothing back from the encoder.
struct PartsTiming {
  int parts = 0;
  double seconds_mapping = 0, seconds_registration = 0, seconds_selection = 0, seconds_reading = 0;
  void add_to(EncodeReport& report) const;  // into its parts, seconds_mapping, ... seconds_reading_parts
};
struct PartsEncoder {
  PartsEncoder();
  PartsEncoder(PartsEncoder&&) noexcept;
  PartsEncoder& operator=(PartsEncoder&&) noexcept;
  ~PartsEncoder();
  std::vector<std::unique_ptr<PartReader>> parts;  // declared first: destroyed after the encoder
  std::unique_ptr<SequenceEncoder> encoder;
  PartsTiming timing;
};
// assemble_parts's first step: the parts read and checked as it says, and an encoder holding their
// frames as sample_frames leaves them (encode_sampled's input). The encoder reads each frame's map
// from its part when a step needs it, so the parts stay open while it lives.
PartsEncoder encoder_of_parts(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options, PartHeader* header = nullptr);

// Throws kInvalidArgument naming `part` (its file and frames) where it was sampled with other
// sample settings than `options` (same_options of OptionsScope::kSample), both settings shown: the
// assemble and fmenc --stage check refuse such a part alike.
void check_part_settings(const PartReader& part, const EncodeOptions& options);
// The same check against `sample_settings`, write_options(options, OptionsScope::kSample) written
// once for every part of an assemble.
void check_part_settings(const PartReader& part, const std::string& sample_settings);

// The ranges a capture of `frames` frames splits into, `per_part` frames each (the last may hold fewer).
std::vector<FrameRange> part_ranges(int frames, int per_part);

}  // namespace facemorph
