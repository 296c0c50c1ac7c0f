// The assemble stage split by keyframes, for captures too long to assemble on one machine
// (spec/method.md §7.17): segment S of N codes whole groups of the intra period, and the segments'
// files join into one without decoding (file_join.hpp, fmcat). Two things the file's header holds
// are chosen from every keyframe, so the segments settle them together first:
//
//   measure   each segment builds and fits its keyframes (the fit solved over them and a margin of
//             kSegmentFitMargin keyframes each side), and writes where they fold and the field
//             steps its own keyframes need (choose_field_coding): a measure file
//   assemble  with every segment's measure: the fixed nodes are all segments' folds, each field
//             step the finest any segment needs; the segment builds its keyframes again, rounds
//             them to those steps and writes them as a .fmv of its own groups
//
// Every measure stage reads all the parts and makes the same choices of keyframes, N,
// representation and intra period (deterministic, as the one-process encode makes them); the
// assemble stage takes them from the measures.
#pragma once

#include "codec/encoder/encode/part_file.hpp"
#include "codec/encoder/encode/representation_choice.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace facemorph {

// Keyframes fitted beyond each end of a segment: the fit couples keyframes a few apart (the spline's
// band), and its influence across a margin this wide is far under the field steps
// (spec/method.md §7.17 has the measurement).
inline constexpr size_t kSegmentFitMargin = 16;

struct SegmentId {
  int index = 0, count = 1;  // segment `index` of `count`
};
// "S/N": 0 <= S < N <= 4096. kInvalidArgument otherwise.
SegmentId parse_segment(const std::string& text);

// What a segment's measure stage found (a JSON file, spec/part-file.md §8).
struct SegmentMeasure {
  std::string source;  // the file it was read from, for messages (read_segment_measure)
  SegmentId segment;
  std::string capture_id;  // the parts' capture (capture_fingerprint)
  std::string settings;    // the options, write_options(options, OptionsScope::kSegment): the same in every segment of an encode
  int keyframes = 0, intra_period = 0, grid = 0;
  Representation representation = Representation::kHL;
  int first = 0, end = 0;               // the keyframes the segment codes
  std::vector<int32_t> folds;           // where they fold: interior nodes of G, ascending
  std::vector<double> steps;            // the field steps they need, kKeyframeArrayCount
  double target_error = 0;              // the field precision's target
  double inter_dead_zone = 0.5;         // the dead zone its search kept
  std::vector<double> keyframe_errors;  // its keyframes' decoded errors at its steps
  // Set where its keyframes' fields did not reconstruct (build_reconstructable): which keyframe and
  // why. Its steps, dead zone and errors are then those of positions (xyz), and the assemble stage
  // stores every segment's keyframes as positions at the steps of the measures that say so.
  std::string representation_fallback;
  // The keyframes (frame indices), N and representation it chose from every frame
  // (SequenceEncoder::plan), the same in every measure of an encode: the assemble stage takes them rather
  // than choosing again. The selection's history is not kept.
  KeyframeSelection plan;
  BlendComparison blend;
};

// Segment `id`'s keyframes of `keyframes` in groups of `intra_period`: groups split as evenly as
// they go. N is a bound: a capture of G < N groups has one segment a group, and segments G..N-1
// are empty (first = end = keyframes), so one N serves a library of captures of any length.
KeyframeSegment segment_keyframes(size_t keyframes, int intra_period, SegmentId id);

// The measure stage: the parts (as assemble_parts reads them) and segment `id` (empty past the
// capture's groups: no steps, no folds). `report`: the choices and times, without per-frame lines. kUnsupported without predicted fields
// (options.predicted_fields: steps of each file's own range cannot join).
SegmentMeasure measure_segment(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options, SegmentId id,
                               EncodeReport* report = nullptr);
// Written whole or not at all (a temporary name, then a rename).
void write_segment_measure(const std::filesystem::path& path, const SegmentMeasure& measure);
// Checked as read: every number in range, the lengths what the grid allows. kCorrupt naming the
// file; kIo where it cannot be read; kLimit past 64 MiB.
SegmentMeasure read_segment_measure(const std::filesystem::path& path);

// Where a segment's keyframes go in the joined file: what fmenc writes in its file's settings
// ("segment") and join_segment_files reads.
struct SegmentPlacement {
  SegmentId segment;
  int first_keyframe = 0, keyframes = 0;  // its first, of the capture's `keyframes`
  std::string encode;                     // the same in every segment of one encode (from the measures)
};

// The assemble stage of segment `id`: its keyframes coded with what the measures (every segment's,
// any order) settle; null for an empty segment (no file to write). Where a measure's keyframes did
// not reconstruct (SegmentMeasure::representation_fallback), every segment stores positions, at the
// finest steps of the measures that fell back (a position's rounding error is the step's, whatever
// the keyframe), with the report's fallback and warning as the one-process encode gives them. kInvalidArgument where the
// measures are not one encode's N segments, each once, or not this capture's and options' (naming
// the measure at fault). The placement's count is that of the segments that code keyframes.
std::unique_ptr<StoredSequence> assemble_segment(const std::vector<std::filesystem::path>& parts, const EncodeOptions& options,
                                                 SegmentId id, const std::vector<SegmentMeasure>& measures, SegmentPlacement* placement,
                                                 EncodeReport* report = nullptr, PartHeader* header = nullptr);

}  // namespace facemorph
