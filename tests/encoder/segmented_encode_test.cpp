// Segments of a long encode (spec/method.md §7.17): measured, assembled apart and joined without
// decoding, they make one file that decodes close to the one-process encode; measures, segments
// and joins that do not make up one encode, or that were damaged or crafted, are refused by name.
#include "codec/encoder/encode/segmented_encode.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/encode/segment_join.hpp"
#include "codec/encoder/encode/staged_encode.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "format/container.hpp"
#include "format/file_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

namespace facemorph {
namespace {

namespace fs = std::filesystem;
using testing::expect_error;
using testing::write_text;

// 16 frames with 6 keyframes in groups of 2: three groups, so up to three segments.
struct Encode {
  testing::TempDir dir;
  Capture capture;
  EncodeOptions options;
  std::vector<fs::path> parts;

  // `representation` given: the one-process encode does not choose by bytes at equal error.
  explicit Encode(std::optional<Representation> representation = std::nullopt) {
    SynthOptions synth;
    synth.frames = 16;
    synth.vertices = 1200;
    synth.remesh = true;
    synth.noise = 0.0005;
    synth.texture_size = 64;
    synth.head_motion_degrees = 15;
    write_synthetic_capture(dir.path() / "capture", synth);
    capture = read_capture(dir.path() / "capture");
    options.keyframe_fraction = 0.375;
    options.keyframe_error_bound = 0;
    options.texture_size = 64;
    options.threads = 2;
    options.field_precision.intra_period = 2;
    // Segments carry no residual frames (spec/method.md §7.18): the one-process encode they are
    // measured against takes none either.
    options.residual_frames = false;
    options.representation = representation;
    // The conformal disk asked for: the one-process encode would otherwise try the density-equalised
    // disk by bytes (density_candidate.hpp), which the segments do not compare yet (spec/method.md
    // §7.14: the segmented encode does not compare); these tests compare the two paths' keyframes.
    options.density_equalising.radial = 0;
    for (const FrameRange& range : std::vector<FrameRange>{{0, 7}, {7, 16}}) {
      parts.push_back(dir.path() / ("part_" + std::to_string(range.first) + ".fms"));
      encode_part(capture, options, range, parts.back());
    }
  }

  std::vector<SegmentMeasure> measures(int count) const {
    std::vector<SegmentMeasure> all;
    for (int s = 0; s < count; ++s) {
      const fs::path path = dir.path() / ("measure_" + std::to_string(s) + "_" + std::to_string(count) + ".json");
      write_segment_measure(path, measure_segment(parts, options, {s, count}));
      all.push_back(read_segment_measure(path));
    }
    return all;
  }

  // Segment s of the measures' count, written as its file.
  fs::path segment_file(int s, const std::vector<SegmentMeasure>& measures, const std::string& name = "") const {
    const SegmentId id{s, measures.front().segment.count};
    SegmentPlacement placement;
    EncodeReport report;
    const std::unique_ptr<StoredSequence> sequence = assemble_segment(parts, options, id, measures, &placement, &report);
    const fs::path path = dir.path() / (name.empty() ? "segment_" + std::to_string(s) + ".fmv" : name);
    write_segment_file(path, *sequence, metadata_of(report), placement);
    return path;
  }

  // What fmenc writes with an encode: its field coding and texture qualities.
  static SequenceFileMetadata metadata_of(const EncodeReport& report) {
    SequenceFileMetadata metadata;
    metadata.encoder = "test";
    metadata.field_coding = report.field_coding;
    metadata.keyframe_texture_qualities = report.texture_qualities;
    metadata.settings = nlohmann::json{{"texture_qualities_chosen", report.texture_qualities},
                                       {"texture_shared_with", report.texture_shared_with},
                                       {"inter_dead_zone_chosen", report.field_precision.inter_dead_zone}}
                            .dump();
    return metadata;
  }
  void write_one(const fs::path& path) const {
    EncodeReport report;
    const std::unique_ptr<StoredSequence> sequence = assemble_parts(parts, options, &report);
    write_sequence_file(path, *sequence, metadata_of(report));
  }
};

// The largest RMS distance between the two files' decoded surfaces over the capture's frame times,
// as a fraction of the first file's bounding box diagonal there.
double largest_decoded_difference(const fs::path& a, const fs::path& b, const Capture& capture) {
  SequenceDecoder x(open_sequence_source(a)), y(open_sequence_source(b));
  double worst = 0;
  for (const CaptureFrame& frame : capture.frames) {
    const DecodedFrame p = x.decode(frame.time), q = y.decode(frame.time);
    Vec3 lo = p.grid_positions.front(), hi = lo;
    double sum = 0;
    for (size_t n = 0; n < p.grid_positions.size(); ++n) {
      lo = lo.cwiseMin(p.grid_positions[n]);
      hi = hi.cwiseMax(p.grid_positions[n]);
      sum += (p.grid_positions[n] - q.grid_positions[n]).squaredNorm();
    }
    worst = std::max(worst, std::sqrt(sum / static_cast<double>(p.grid_positions.size())) / (hi - lo).norm());
  }
  return worst;
}

// What the file's settings say, as JSON.
nlohmann::json settings_of(const fs::path& path) {
  SequenceFileInfo info;
  read_sequence_file(path, &info);
  return nlohmann::json::parse(info.metadata.settings);
}

// A segment takes the plan's representation and never the choice by bytes (spec/method.md §7.14),
// which the one-process encode makes: the fields asked for, both store them (left to choose, the
// one-process encode of this capture keeps positions, rounded each to its nearest step).
TEST(SegmentedEncode, SegmentsJoinIntoAFileThatDecodesCloseToTheOneProcessEncode) {
  const Encode e(Representation::kHLT);
  const fs::path one = e.dir.path() / "one.fmv";
  e.write_one(one);
  const std::vector<SegmentMeasure> measures = e.measures(3);
  // The segments code whole groups, 2 keyframes each, and every segment settles the same encode.
  for (int s = 0; s < 3; ++s) {
    EXPECT_EQ(measures[static_cast<size_t>(s)].first, 2 * s);
    EXPECT_EQ(measures[static_cast<size_t>(s)].end, 2 * s + 2);
    EXPECT_EQ(measures[static_cast<size_t>(s)].keyframes, 6);
  }
  std::vector<fs::path> segments;
  for (int s : {2, 0, 1}) segments.push_back(e.segment_file(s, measures));
  const fs::path joined = e.dir.path() / "joined.fmv";
  const JoinReport report = join_segment_files(segments, joined);
  EXPECT_EQ(report.segments, 3);
  EXPECT_EQ(report.keyframes, 6u);
  // A file a player takes: every chunk, keyframe and texture checked.
  const SequenceFileInfo info = inspect_sequence_file(joined);
  const SequenceFileInfo one_info = inspect_sequence_file(one);
  EXPECT_EQ(info.keyframes.size(), one_info.keyframes.size());
  // Each step the finest any segment needed; the fixed nodes hold every segment's folds.
  const std::vector<double>& steps = info.metadata.field_coding.steps;
  for (size_t a = 0; a < steps.size(); ++a) {
    double finest = measures[0].steps[a];
    for (const SegmentMeasure& m : measures) finest = std::min(finest, m.steps[a]);
    EXPECT_EQ(steps[a], finest) << "array " << a;
  }
  EXPECT_EQ(info.metadata.field_coding.intra_period, 2);
  // The segments' own keyframes, times and poses are the one-process file's.
  const Sequence a = read_sequence_file(joined), b = read_sequence_file(one);
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  for (size_t k = 0; k < a.keyframes.size(); ++k) {
    EXPECT_EQ(a.keyframes[k].time, b.keyframes[k].time);
    EXPECT_TRUE(a.keyframes[k].pose.rotation.isApprox(b.keyframes[k].pose.rotation, 1e-9));
  }
  // Decoded: within 2.5 times the field precision's target of the one-process file at every frame
  // (each file's keyframes are within 1.25 times the target of their exact fields, each rounded its
  // own way; spec/method.md §7.17).
  const double target = measures.front().target_error;
  const double difference = largest_decoded_difference(joined, one, e.capture);
  EXPECT_LT(difference, 2.5 * target) << "the joined file decodes " << difference
                                      << " of the diagonal from the one-process file, the target " << target;
  // The settings say what each segment chose, and every keyframe's texture quality.
  const nlohmann::json settings = settings_of(joined);
  EXPECT_FALSE(settings.contains("segment"));
  ASSERT_EQ(settings["segments"].size(), 3u);
  EXPECT_EQ(settings["segments"][2]["first_keyframe"], 4);
  EXPECT_EQ(settings["texture_qualities_chosen"].size(), 6u);
  EXPECT_EQ(settings["texture_shared_with"].size(), 6u);
  EXPECT_EQ(settings["segments"][1]["inter_dead_zone_chosen"], measures[1].inter_dead_zone);
  // Segments alone play too: each is a file of its own keyframes.
  EXPECT_EQ(read_sequence_file(segments[0]).keyframes.size(), 2u);
  // N is a bound: asked for 5 segments, the capture's 3 groups make 3, and the 2 past them are
  // empty (no file); the join is the 3 segments' to the byte.
  const std::vector<SegmentMeasure> five = e.measures(5);
  EXPECT_EQ(five[3].first, 6);
  EXPECT_EQ(five[4].end, 6);
  EXPECT_EQ(assemble_segment(e.parts, e.options, {4, 5}, five, nullptr), nullptr);
  const fs::path bounded = e.dir.path() / "bounded.fmv";
  join_segment_files({e.segment_file(0, five, "b0.fmv"), e.segment_file(1, five, "b1.fmv"), e.segment_file(2, five, "b2.fmv")}, bounded);
  EXPECT_TRUE(format::read_file(bounded) == format::read_file(joined)) << "5 segments of 3 groups joined into another file than 3 segments";
}

TEST(SegmentedEncode, OneSegmentIsTheWholeEncodeWithItsOwnSteps) {
  // Segments do not choose by bytes at equal error (spec/method.md §7.14, not done): the one-process
  // encode is given the representation, so it does not either (open, it now keeps the coarser field
  // step's candidate, which a segment does not try).
  const Encode e(Representation::kHLT);
  const std::vector<SegmentMeasure> measures = e.measures(1);
  const fs::path joined = e.dir.path() / "joined.fmv";
  join_segment_files({e.segment_file(0, measures)}, joined);
  EncodeReport report;
  const std::unique_ptr<StoredSequence> one = assemble_parts(e.parts, e.options, &report);
  // One segment measures what the one-process encode chooses: the same steps, the same keyframes.
  const SequenceFileInfo info = inspect_sequence_file(joined);
  EXPECT_EQ(info.metadata.field_coding.steps, report.field_coding.steps);
  const Sequence a = read_sequence_file(joined), b = one->to_sequence();
  ASSERT_EQ(a.keyframes.size(), b.keyframes.size());
  for (size_t k = 0; k < a.keyframes.size(); ++k) {
    const auto x = scalar_arrays(a.keyframes[k].fields), y = scalar_arrays(b.keyframes[k].fields);
    EXPECT_EQ(x, y) << "keyframe " << k;
  }
}

TEST(SegmentedEncode, MeasuresThatAreNotOneEncodesSegmentsAreRefused) {
  const Encode e;
  std::vector<SegmentMeasure> measures = e.measures(3);
  std::vector<SegmentMeasure> missing(measures.begin(), measures.begin() + 2);
  expect_error(ErrorCode::kInvalidArgument, "no measure of segment 2/3", [&] { e.segment_file(0, missing); });
  std::vector<SegmentMeasure> twice = measures;
  twice[2] = twice[1];
  expect_error(ErrorCode::kInvalidArgument, "given twice", [&] { e.segment_file(0, twice); });
  expect_error(ErrorCode::kInvalidArgument, "measure_1_3.json", [&] { e.segment_file(0, twice); });
  // A measure that says its segment is empty though its number has keyframes.
  std::vector<SegmentMeasure> emptied = measures;
  emptied[0].first = emptied[0].end = 6;
  expect_error(ErrorCode::kInvalidArgument, "holds keyframes 6:6, not its segment's 0:2", [&] { e.segment_file(2, emptied); });
  EncodeOptions other = e.options;
  other.keyframe_fit_weight = 2;
  expect_error(ErrorCode::kInvalidArgument, "other settings", [&] { assemble_segment(e.parts, other, {0, 3}, measures, nullptr); });
  std::vector<SegmentMeasure> moved = measures;
  moved[0].first = 2;
  moved[0].end = 4;
  expect_error(ErrorCode::kInvalidArgument, "holds keyframes 2:4, not its segment's 0:2", [&] { e.segment_file(0, moved); });
  std::vector<SegmentMeasure> elsewhere = measures;
  for (SegmentMeasure& m : elsewhere) m.capture_id = "0123456789abcdef";
  expect_error(ErrorCode::kInvalidArgument, "not of these parts", [&] { e.segment_file(0, elsewhere); });

  // A plan of other frames: keyframes past the capture's end.
  std::vector<SegmentMeasure> replanned = measures;
  for (SegmentMeasure& m : replanned) m.plan.keyframes.back() += 5;
  expect_error(ErrorCode::kInvalidArgument, "not a selection of this encode's 16 frames", [&] { e.segment_file(0, replanned); });
  EncodeOptions unpredicted = e.options;
  unpredicted.predicted_fields = false;
  expect_error(ErrorCode::kUnsupported, "predicted fields", [&] { measure_segment(e.parts, unpredicted, {0, 3}); });
}

TEST(SegmentedEncode, ADamagedOrCraftedMeasureIsRefusedByName) {
  testing::TempDir dir;
  SegmentMeasure m;
  m.segment = {1, 3};
  m.capture_id = "0123456789abcdef";
  m.settings = "{\"a\":1}";
  m.keyframes = 6;
  m.intra_period = 2;
  m.grid = 17;
  m.first = 2;
  m.end = 4;
  m.folds = {3, 40};
  m.steps.assign(kKeyframeArrayCount, 0.5);
  m.target_error = 1e-3;
  m.keyframe_errors = {1e-3, 2e-3};
  m.plan.keyframes = {0, 3, 5, 8, 10, 11};
  m.plan.predicted_error.assign(12, 1e-3);
  const fs::path good = dir.path() / "good.json";
  write_segment_measure(good, m);
  const SegmentMeasure back = read_segment_measure(good);
  EXPECT_EQ(back.folds, m.folds);
  EXPECT_EQ(back.steps, m.steps);
  EXPECT_EQ(back.first, 2);
  EXPECT_EQ(back.plan.keyframes, m.plan.keyframes);
  EXPECT_EQ(back.plan.predicted_error, m.plan.predicted_error);
  const std::string text = std::string(reinterpret_cast<const char*>(format::read_file(good).data()), fs::file_size(good));
  const auto crafted = [&](const std::string& from, const std::string& to, ErrorCode code, const std::string& fragment) {
    std::string changed = text;
    const size_t at = changed.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    changed.replace(at, from.size(), to);
    const fs::path path = dir.path() / "crafted.json";
    write_text(path, changed);
    expect_error(code, fragment, [&] { read_segment_measure(path); });
    expect_error(code, path.string(), [&] { read_segment_measure(path); });
  };
  crafted("\"folds\":[3,40]", "\"folds\":[40,3]", ErrorCode::kCorrupt, "not ascending");
  crafted("\"folds\":[3,40]", "\"folds\":[3,1000000]", ErrorCode::kCorrupt, "not an interior node");
  crafted("\"folds\":[3,40]", "\"folds\":[-1,40]", ErrorCode::kCorrupt, "not an interior node");
  crafted("\"grid\":17", "\"grid\":4098", ErrorCode::kCorrupt, "outside");
  crafted("\"steps\":[0.5,", "\"steps\":[-0.5,", ErrorCode::kCorrupt, "not finite and positive");
  crafted("\"steps\":[0.5,", "\"steps\":[", ErrorCode::kCorrupt, "field steps");
  crafted("\"first\":2", "\"first\":1", ErrorCode::kCorrupt, "whole groups");
  crafted("\"end\":4", "\"end\":7", ErrorCode::kCorrupt, "whole groups");
  crafted("\"segment\":1", "\"segment\":3", ErrorCode::kCorrupt, "segment number");
  crafted("\"segment\":1", "\"segment\":1.5", ErrorCode::kCorrupt, "whole number");
  crafted("\"inter_dead_zone\":0.5", "\"inter_dead_zone\":2", ErrorCode::kCorrupt, "dead zone");
  crafted("\"keyframe_errors\":[0.001,0.002]", "\"keyframe_errors\":[0.001]", ErrorCode::kCorrupt, "each of its keyframes");
  crafted("\"version\":1", "\"version\":2", ErrorCode::kUnsupported, "measure version");
  crafted("\"settings\":{\"a\":1}", "\"settings\":{\"a\":[[[[[[1]]]]]]}", ErrorCode::kCorrupt, "nests deeper");
  crafted("{", "[", ErrorCode::kCorrupt, "not JSON");
  crafted("\"keyframes\":[0,3,5,8,10,11]", "\"keyframes\":[0,3,5,8,10]", ErrorCode::kCorrupt, "its plan holds 5 keyframes");
  crafted("\"predicted_error\":[0.001,", "\"predicted_error\":[-0.001,", ErrorCode::kCorrupt, "predicted errors");
  crafted("\"keyframe_errors\":[0.001,0.002]", "\"keyframe_errors\":[0.001,-1]", ErrorCode::kCorrupt, "a keyframe's error");
  crafted("segment measure", "part", ErrorCode::kCorrupt, "not a segment measure");
  // Past the size limit: refused before it is read.
  const fs::path huge = dir.path() / "huge.json";
  { std::ofstream(huge) << std::string((64u << 20) + 1, ' '); }
  expect_error(ErrorCode::kLimit, "huge.json", [&] { read_segment_measure(huge); });
}

TEST(SegmentJoin, SegmentsThatDoNotMakeUpOneEncodeAreRefusedByName) {
  const Encode e;
  const std::vector<SegmentMeasure> three = e.measures(3);
  const fs::path s0 = e.segment_file(0, three), s1 = e.segment_file(1, three), s2 = e.segment_file(2, three);
  const fs::path out = e.dir.path() / "joined.fmv";
  expect_error(ErrorCode::kInvalidArgument, "segment 2 of 3 is missing", [&] { join_segment_files({s0, s1}, out); });
  expect_error(ErrorCode::kInvalidArgument, "segment 1 of 3 is missing", [&] { join_segment_files({s0, s2}, out); });
  expect_error(ErrorCode::kInvalidArgument, "given twice", [&] { join_segment_files({s0, s1, s1, s2}, out); });
  // A segment of the same capture cut in two: another encode.
  const std::vector<SegmentMeasure> two = e.measures(2);
  const fs::path other = e.segment_file(1, two, "other.fmv");
  expect_error(ErrorCode::kInvalidArgument, "another encode", [&] { join_segment_files({s0, s1, other}, out); });
  // A file that is no segment.
  const fs::path plain = e.dir.path() / "plain.fmv";
  e.write_one(plain);
  expect_error(ErrorCode::kInvalidArgument, "not a segment", [&] { join_segment_files({s0, plain, s2}, out); });
  // A damaged segment: a player would refuse it, and so does the join, naming it.
  std::vector<uint8_t> bytes = format::read_file(s1);
  bytes[bytes.size() / 2] ^= 0x40;
  const fs::path damaged = e.dir.path() / "damaged.fmv";
  format::write_file_atomically(damaged, bytes);
  expect_error(ErrorCode::kCorrupt, "damaged.fmv", [&] { join_segment_files({s0, damaged, s2}, out); });
  EXPECT_FALSE(fs::exists(out)) << "a refused join wrote a file";
  // A segment that says it starts elsewhere than where the one before it ends.
  SegmentPlacement placement;
  EncodeReport report;
  const std::unique_ptr<StoredSequence> middle = assemble_segment(e.parts, e.options, {1, 3}, three, &placement, &report);
  placement.first_keyframe = 3;
  const fs::path shifted = e.dir.path() / "shifted.fmv";
  write_segment_file(shifted, *middle, Encode::metadata_of(report), placement);
  expect_error(ErrorCode::kInvalidArgument, "starts at keyframe 3, where 2 was due", [&] { join_segment_files({s0, shifted, s2}, out); });
  // Segments whose whole breaks a limit each kept alone: settings over 1 MiB together.
  {
    EncodeReport r0, r2;
    SegmentPlacement p0, p2;
    const std::unique_ptr<StoredSequence> a = assemble_segment(e.parts, e.options, {0, 3}, three, &p0, &r0);
    const std::unique_ptr<StoredSequence> c = assemble_segment(e.parts, e.options, {2, 3}, three, &p2, &r2);
    SequenceFileMetadata m0 = Encode::metadata_of(r0), m2 = Encode::metadata_of(r2);
    // Each 800 kB (a file's settings may take 1 MiB); the joined settings hold both lists.
    m0.settings = m2.settings = nlohmann::json{{"texture_qualities_chosen", std::vector<int>(200000, 100)}}.dump();
    write_segment_file(e.dir.path() / "big0.fmv", *a, m0, p0);
    write_segment_file(e.dir.path() / "big2.fmv", *c, m2, p2);
    expect_error(ErrorCode::kInvalidArgument, "do not join into a file a player takes", [&] {
      join_segment_files({e.dir.path() / "big0.fmv", s1, e.dir.path() / "big2.fmv"}, out);
    });
    EXPECT_FALSE(fs::exists(out));
  }
  // A segment whose checksums hold but whose keyframe stream is damaged: refused with --check
  // (the join alone copies chunks without decoding them).
  {
    const std::vector<uint8_t> original = format::read_file(s1);
    const format::ContainerReader reader(original, s1.string());
    std::ostringstream crafted;
    {
      format::ContainerWriter writer(crafted);
      for (const format::ChunkView& chunk : reader.chunks()) {
        format::PreparedChunk copy{chunk.type, chunk.flags, chunk.raw_size, std::vector<uint8_t>(chunk.stored.begin(), chunk.stored.end())};
        if (chunk.type == "KGOP" || chunk.type == "KGLV") copy.stored[copy.stored.size() / 2] ^= 0x5a;
        writer.add(copy);
      }
      writer.finish();
    }
    const std::string text = crafted.str();
    const fs::path damaged_stream = e.dir.path() / "stream.fmv";
    format::write_file_atomically(damaged_stream, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    expect_error(ErrorCode::kCorrupt, "stream.fmv", [&] { join_segment_files({s0, damaged_stream, s2}, out, true); });
    EXPECT_FALSE(fs::exists(out));
  }
  // The good three join, in any order.
  join_segment_files({s1, s2, s0}, out);
  EXPECT_EQ(inspect_sequence_file(out).keyframes.size(), 6u);
}

// Issue 47 in segments: a whole head on its conformal disk (no radial spread) gives hl+t keyframes
// that do not reconstruct (whole_head_test.cpp). Each segment's measure takes the driver's fallback
// (build_reconstructable) and says so; the assemble stage stores positions in every segment, the
// report naming the keyframe as the one-process encode's does, and the segments join into a file of
// positions that decodes. The staged assemble takes the same fallback. Letting the failure through
// in measure_segment (building and measuring without build_reconstructable) is the mutation this
// catches.
TEST(SegmentedEncode, KeyframesThatDoNotReconstructAreStoredAsPositionsInEverySegment) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 2;
  synth.vertices = 2000;
  synth.holes = true;
  synth.whole_head = true;
  write_synthetic_capture(dir.path() / "capture", synth);
  const Capture capture = read_capture(dir.path() / "capture");
  EncodeOptions options;
  options.texture = false;
  options.threads = 2;
  options.density_equalising.radial = 0;
  options.grid = 129;  // as WholeHead.AKeyframeThatDoesNotReconstructIsStoredAsPositions: fails alike, in a fifth of the time
  options.field_precision.intra_period = 1;  // two keyframes, two groups: two segments
  const fs::path part = dir.path() / "all.fms";
  encode_part(capture, options, {0, 2}, part);
  std::vector<SegmentMeasure> measures;
  for (int s = 0; s < 2; ++s) {
    const fs::path path = dir.path() / ("measure_" + std::to_string(s) + ".json");
    write_segment_measure(path, measure_segment({part}, options, {s, 2}));
    measures.push_back(read_segment_measure(path));
    const SegmentMeasure& m = measures.back();
    EXPECT_EQ(m.end - m.first, 1);
    EXPECT_NE(m.representation_fallback.find("did not converge"), std::string::npos) << m.representation_fallback;
    EXPECT_NE(m.representation, Representation::kXYZ);  // the plan's: hl+t, as the one-process encode chose
  }
  std::vector<fs::path> files;
  for (int s = 0; s < 2; ++s) {
    SegmentPlacement placement;
    EncodeReport report;
    const std::unique_ptr<StoredSequence> sequence = assemble_segment({part}, options, {s, 2}, measures, &placement, &report);
    ASSERT_NE(sequence, nullptr);
    EXPECT_EQ(sequence->shape().representation, Representation::kXYZ);
    EXPECT_EQ(report.representation, Representation::kXYZ);
    EXPECT_EQ(report.representation_fallback, measures[0].representation_fallback);
    ASSERT_FALSE(report.warnings.empty());
    EXPECT_NE(report.warnings.back().find("every keyframe stored as positions (xyz)"), std::string::npos) << report.warnings.back();
    files.push_back(dir.path() / ("segment_" + std::to_string(s) + ".fmv"));
    write_segment_file(files.back(), *sequence, Encode::metadata_of(report), placement);
  }
  const fs::path joined = dir.path() / "joined.fmv";
  join_segment_files(files, joined, true);
  const Sequence sequence = read_sequence_file(joined);
  EXPECT_EQ(sequence.representation, Representation::kXYZ);
  SequenceDecoder decoder(open_sequence_source(joined));
  for (const CaptureFrame& frame : capture.frames) EXPECT_TRUE(decoder.decode(frame.time).converged) << frame.time;
  // The staged assemble of the same part: the one-process driver's fallback.
  EncodeReport staged;
  EXPECT_EQ(assemble_parts({part}, options, &staged)->shape().representation, Representation::kXYZ);
  EXPECT_NE(staged.representation_fallback.find("did not converge"), std::string::npos) << staged.representation_fallback;
  // Asked for hl+t, the measure still fails: positions were not asked for.
  options.representation = Representation::kHLT;
  expect_error(ErrorCode::kNotConverged, "did not converge", [&] { measure_segment({part}, options, {0, 2}); });
}

// Where one segment's keyframes fall back to positions and the others' reconstruct, the decision
// reaches every segment: all store positions, at the steps of the measure that fell back (each
// step the finest of such measures), and join into a file that decodes as close to the
// one-process encode of positions as segments do to theirs. Segment 1's measure is made so: the
// same encode measured as positions, marked as fallen back, through its file as fmenc reads it.
TEST(SegmentedEncode, OneSegmentsFallbackToPositionsReachesEverySegment) {
  const Encode e;
  std::vector<SegmentMeasure> measures = e.measures(3);
  EncodeOptions positions = e.options;
  positions.representation = Representation::kXYZ;
  const SegmentMeasure measured = measure_segment(e.parts, positions, {1, 3});
  SegmentMeasure fell = measures[1];
  fell.folds = measured.folds;
  fell.steps = measured.steps;
  fell.inter_dead_zone = measured.inter_dead_zone;
  fell.keyframe_errors = measured.keyframe_errors;
  fell.representation_fallback = "keyframe 3: reconstruction did not converge (made by the test)";
  const fs::path path = e.dir.path() / "fell.json";
  write_segment_measure(path, fell);
  measures[1] = read_segment_measure(path);
  EXPECT_EQ(measures[1].representation_fallback, fell.representation_fallback);
  std::vector<fs::path> segments;
  for (int s = 0; s < 3; ++s) {
    SegmentPlacement placement;
    EncodeReport report;
    const std::unique_ptr<StoredSequence> sequence = assemble_segment(e.parts, e.options, {s, 3}, measures, &placement, &report);
    EXPECT_EQ(sequence->shape().representation, Representation::kXYZ) << "segment " << s;
    EXPECT_EQ(report.representation_fallback, fell.representation_fallback);
    EXPECT_EQ(report.field_coding.steps, measured.steps) << "segment " << s;
    EXPECT_EQ(report.field_precision.inter_dead_zone, measured.inter_dead_zone);
    for (double error : report.field_precision.keyframe_errors) EXPECT_LT(error, 1.25 * measured.target_error) << "segment " << s;
    segments.push_back(e.dir.path() / ("fell_" + std::to_string(s) + ".fmv"));
    write_segment_file(segments.back(), *sequence, Encode::metadata_of(report), placement);
  }
  const fs::path joined = e.dir.path() / "joined.fmv";
  join_segment_files(segments, joined, true);
  EXPECT_EQ(read_sequence_file(joined).representation, Representation::kXYZ);
  EncodeReport report;
  const std::unique_ptr<StoredSequence> one = assemble_parts(e.parts, positions, &report);
  const fs::path one_file = e.dir.path() / "one_xyz.fmv";
  write_sequence_file(one_file, *one, Encode::metadata_of(report));
  const double difference = largest_decoded_difference(joined, one_file, e.capture);
  EXPECT_LT(difference, 2.5 * measured.target_error)
      << "the joined file decodes " << difference << " of the diagonal from the one-process file";
  // A measure of positions that says it fell back from positions is no measure fmenc writes.
  fell.representation = Representation::kXYZ;
  write_segment_measure(path, fell);
  expect_error(ErrorCode::kCorrupt, "falls back to positions from positions", [&] { read_segment_measure(path); });
}

}  // namespace
}  // namespace facemorph
