// The staged encode's part file (.fms, spec/part-file.md): frames [first, end) of a capture as the
// sample stage left them (SampledFrame), for the assemble stage, which may run on another machine.
//
// A container of the facemorph file's kind (format/container.hpp: chunks with CRC-32s, zstd) under
// its own magic: a header chunk, then one record chunk per frame of the range, in order. A part is
// untrusted on read: every size is checked against what holds it before anything is allocated, and
// every record is checked for what the assemble stage relies on (indices inside their arrays,
// numbers finite, enumerations known) before it is handed out.
#pragma once

#include "codec/encoder/encode/sequence_encoder.hpp"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>

namespace facemorph {

namespace format {
class ContainerReader;
class ContainerWriter;
class MappedFile;
}  // namespace format

inline constexpr uint16_t kPartMajorVersion =
    3;  // 2: frames carry the non-manifold repairs; 3: a found orientation's method and confidence (spec/part-file.md)
inline constexpr uint16_t kPartMinorVersion = 0;
// What a part may hold: frames of a capture (2^24: 155 hours at 30 fps), a header, one frame's record
// (a 256 MiB record is a mesh of ~5M vertices).
inline constexpr int kMaxPartCaptureFrames = 1 << 24;
inline constexpr uint64_t kMaxPartHeaderBytes = uint64_t{16} << 20;
inline constexpr uint64_t kMaxPartRecordBytes = uint64_t{256} << 20;

// Frames [first, end) of a capture, in its own numbering.
struct FrameRange {
  int first = 0, end = 0;
  int size() const { return end - first; }
  bool contains(int i) const { return i >= first && i < end; }
};

struct PartHeader {
  std::string capture_id;  // capture_fingerprint of the capture sampled
  SampledCapture capture;  // what the assembling encoder is told of it
  FrameRange range;        // the frames this part holds, one record each
  std::string settings;    // the options sampled with: write_options(options, OptionsScope::kSample)
  std::string encoder;     // the writer ("facemorph 1.5.0")
  double seconds_mapping = 0, seconds_registration = 0, seconds_selection = 0;
  uint16_t minor_version = kPartMinorVersion;  // on read, the file's
};

// Writes a part: the header now, a record per add, and on finish the file appears whole under its
// name (written to a temporary sibling and renamed); a writer destroyed unfinished, or a throw,
// leaves nothing at `path` but what was there before. Throws kIo naming the file.
class PartWriter {
 public:
  PartWriter(std::filesystem::path path, const PartHeader& header);
  ~PartWriter();
  PartWriter(const PartWriter&) = delete;
  PartWriter& operator=(const PartWriter&) = delete;
  // The next frame of the range (kInternal when it is not the one due).
  void add(const SampledFrame& frame);
  void finish();

 private:
  std::filesystem::path path_, temporary_;
  PartHeader header_;
  std::ofstream out_;
  std::unique_ptr<format::ContainerWriter> writer_;
  int next_ = 0;
  bool finished_ = false;
};

// Reads a part: the constructor maps the file, walks its chunks and reads and checks the header;
// frame(k) reads record k (frame range.first + k) and checks it. Errors name the file (and the
// frame): kCorrupt for damaged or inconsistent bytes, kTruncated for a file cut short, kUnsupported
// for another major version, kLimit past a limit above, kIo when it cannot be read.
class PartReader {
 public:
  explicit PartReader(const std::filesystem::path& path);
  ~PartReader();
  PartReader(const PartReader&) = delete;
  PartReader& operator=(const PartReader&) = delete;
  const PartHeader& header() const { return header_; }
  const std::string& source() const { return source_; }  // the file, as errors name it
  SampledFrame frame(size_t k) const;
  // What gives record k's map bytes again when asked (SampledFrame::map_source), read from the file
  // each time, its checksum checked: the reader must outlive it. For a record frame(k) checked.
  std::function<std::vector<char>()> map_source(size_t k) const;
  // Every record read and checked (what `fmenc --stage check` and a resumed cluster encode ask).
  void verify() const;
  uint64_t file_bytes() const;

 private:
  std::vector<uint8_t> payload(size_t k) const;  // record k's bytes, checked against its CRC

  std::string source_;
  std::unique_ptr<format::MappedFile> file_;
  std::unique_ptr<format::ContainerReader> reader_;
  std::vector<size_t> records_;  // chunk numbers of the frames' records
  size_t selection_nodes_ = 0;   // what a record's selection samples must hold
  PartHeader header_;
};

// What identifies the capture a part was sampled from: its frames (mesh names and times), frame
// rate, units and landmarks (names and points), hashed (FNV-1a, 64 bits, as 16 hex digits). Parts of
// one capture agree; a capture edited between stages does not.
std::string capture_fingerprint(const Capture& capture);

}  // namespace facemorph
