// Joins the segment files of one encode (fmenc --stage assemble --segment S/N) into one .fmv
// without decoding them (fmcat; spec/method.md §7.17): the segments share the header's grid, field
// steps, fixed nodes and intra period, and each codes whole groups of keyframes, so the groups'
// chunks are copied as they are, each with its first keyframe's number moved to its place in the
// whole; the header and index are made again and every checksum computed anew.
#pragma once

#include "codec/core/container/file_metadata.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/encoder/encode/segmented_encode.hpp"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace facemorph {

// Writes a segment's keyframes (assemble_segment) as its segment file: a .fmv of its groups that
// plays on its own, whose settings (metadata.settings, a JSON object or empty) say where its
// keyframes go, and whose textures are laid out as every segment's
// (SequenceFileMetadata::texture_layout_from_settings). Written whole or not at all.
void write_segment_file(const std::filesystem::path& path, const KeyframeSource& segment, SequenceFileMetadata metadata,
                        const SegmentPlacement& placement);

struct JoinReport {
  int segments = 0;
  size_t keyframes = 0;
  uint64_t bytes = 0;  // the joined file's
};

// Joins `segments` (any order) into `output`, written whole or not at all. Each segment is opened
// and checked as a player opens a file (header, index, every chunk's checksum), not decoded.
// kInvalidArgument naming the file where the segments are not all N of one encode, each once (a
// file that is no segment, another encode's, a segment missing or given twice), or where their
// headers differ in anything but what the joined file's makes again; kCorrupt, kTruncated,
// kUnsupported as a player would refuse the file.
// `check_every_keyframe`: also decode every segment's keyframes and textures first, as fminfo
// does (a chunk whose checksum holds but whose stream is damaged is refused; the join itself never
// decodes). The joined header and index are read back as a player reads them before anything is
// written (kInvalidArgument where the whole breaks a limit its segments kept alone: the settings'
// size, the keyframe count, keyframe times too close across a seam).
JoinReport join_segment_files(const std::vector<std::filesystem::path>& segments, const std::filesystem::path& output,
                              bool check_every_keyframe = false);

}  // namespace facemorph
