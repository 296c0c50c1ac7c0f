#include "codec/encoder/encode/segment_join.hpp"

#include "codec/decoder/container/chunk_readers.hpp"
#include "codec/decoder/container/opened_file.hpp"
#include "codec/encoder/encode/json_fields.hpp"
#include "codec/writer/container/chunk_writers.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cstring>
#include <map>
#include <memory>

namespace facemorph {

using namespace file_layout;

namespace {

constexpr int kMaxSettingsDepth = 8;

// One segment file, opened as a player opens it, and where its keyframes go.
struct Segment {
  std::filesystem::path path;
  std::unique_ptr<format::MappedFile> mapped;
  std::unique_ptr<OpenedFile> file;
  nlohmann::json settings;
  int index = 0, count = 0, first_keyframe = 0, keyframes = 0;
  std::string encode;
};

[[noreturn]] void refuse(const Segment& s, const std::string& why) {
  throw Error(ErrorCode::kInvalidArgument, s.path.string() + ": " + why);
}

Segment open_segment(const std::filesystem::path& path, bool check_every_keyframe) {
  Segment s;
  s.path = path;
  s.mapped = std::make_unique<format::MappedFile>(path);
  // The joiner holds no keyframe: the header and index alone, as opening a file for playing does.
  s.file = std::make_unique<OpenedFile>(s.mapped->bytes(), path.string(), kDefaultDecoderLimits,
                                        [](uint32_t, SplineKind) { return uint64_t{1}; });
  s.file->verify_checksums();
  if (check_every_keyframe) {
    SequenceFileInfo ignored;
    s.file->check_every_keyframe(&ignored);
  }
  const std::string& text = s.file->header().metadata.settings;
  try {
    s.settings = json_fields::parse_object(text, kMaxSettingsDepth, "its settings");
    if (!s.settings.contains("segment")) refuse(s, "it is not a segment (fmenc --stage assemble --segment S/N writes one)");
    const nlohmann::json& placed = s.settings["segment"];
    if (!placed.is_object()) json_fields::bad("its settings' \"segment\" is not an object");
    s.index = json_fields::integer_field(placed, "index", "its segment");
    s.count = json_fields::integer_field(placed, "count", "its segment");
    s.first_keyframe = json_fields::integer_field(placed, "first_keyframe", "its segment");
    s.keyframes = json_fields::integer_field(placed, "keyframes", "its segment");
    s.encode = json_fields::field<std::string>(placed, "encode", "its segment");
  } catch (const Error& e) {
    if (e.code() == ErrorCode::kInvalidArgument) throw;
    refuse(s, std::string("it is not a segment: ") + e.what());
  }
  if (s.count < 1 || s.index < 0 || s.index >= s.count) refuse(s, "its segment number is out of range");
  if (s.first_keyframe < 0 || s.keyframes < 1 || s.first_keyframe >= s.keyframes)
    refuse(s, "its place among the keyframes is out of range");
  return s;
}

// What every segment's header must share with the first's: everything but the keyframe count, the
// settings and whether stills are shared (which the joined header makes again).
void check_same_header(const Segment& first, const Segment& s) {
  const FileHeader &a = first.file->header(), &b = s.file->header();
  const Sequence &x = a.shape, &y = b.shape;
  const FieldCoding &p = a.metadata.field_coding, &q = b.metadata.field_coding;
  const auto differs = [&](bool same, const char* what) {
    if (!same) refuse(s, std::string("its ") + what + " differs from " + first.path.string() + "'s: segments of one encode share it");
  };
  differs(x.grid_n == y.grid_n && a.grid_rule == b.grid_rule && a.grid_hash == b.grid_hash, "grid");
  differs(x.representation == y.representation && x.spline == y.spline, "representation or spline");
  differs((a.flags & ~kSharedTextures) == (b.flags & ~kSharedTextures) && a.texture_size == b.texture_size, "texture layout");
  differs(
      x.fps == y.fps && x.first_time == y.first_time && x.last_time == y.last_time && x.units == y.units && x.pose_centre == y.pose_centre,
      "capture times, units or pose centre");
  differs(a.fixed_nodes == b.fixed_nodes, "fixed nodes");
  differs(p.steps == q.steps && p.intra_period == q.intra_period && p.rotation_step == q.rotation_step &&
              p.translation_step == q.translation_step,
          "field coding");
  differs(a.metadata.landmark_names == b.metadata.landmark_names && a.metadata.encoder == b.metadata.encoder, "landmark names or encoder");
}

// The segments' settings as one: the first's, with each keyframe's entries of every segment, and
// per segment what it chose alone.
std::string joined_settings(const std::vector<Segment>& segments) {
  nlohmann::json joined = segments.front().settings;
  joined.erase("segment");
  nlohmann::json qualities = nlohmann::json::array(), shared = nlohmann::json::array(), each = nlohmann::json::array();
  for (const Segment& s : segments) {
    const nlohmann::json& q =
        s.settings.contains("texture_qualities_chosen") ? s.settings["texture_qualities_chosen"] : nlohmann::json::array();
    const nlohmann::json& w = s.settings.contains("texture_shared_with") ? s.settings["texture_shared_with"] : nlohmann::json::array();
    for (const nlohmann::json& v : q) qualities.push_back(v);
    // An earlier keyframe of the segment moves with it; anything else (-1: its own) stays as it is.
    for (const nlohmann::json& v : w) {
      const bool keyframe = v.is_number_integer() && v.get<int64_t>() >= 0 && v.get<int64_t>() < s.keyframes;
      shared.push_back(keyframe ? nlohmann::json(v.get<int64_t>() + s.first_keyframe) : v);
    }
    each.push_back({{"first_keyframe", s.first_keyframe},
                    {"keyframes", s.file->keyframe_count()},
                    {"inter_dead_zone_chosen",
                     s.settings.contains("inter_dead_zone_chosen") ? s.settings["inter_dead_zone_chosen"] : nlohmann::json(nullptr)}});
  }
  if (joined.contains("texture_qualities_chosen")) joined["texture_qualities_chosen"] = qualities;
  if (joined.contains("texture_shared_with")) joined["texture_shared_with"] = shared;
  joined.erase("inter_dead_zone_chosen");
  joined["segments"] = each;
  return joined.dump();
}

// A group's or texture's chunk with the keyframe number its payload opens with (§7, §8, §8.1)
// moved by `shift`, after checking it is `expected` (the number in the segment).
format::PreparedChunk renumbered(const format::ContainerReader& reader, const format::ChunkView& chunk, uint32_t expected, uint32_t shift) {
  if (chunk.compressed() || chunk.stored.size() < 4)
    throw Error(ErrorCode::kCorrupt, reader.source() + ": " + reader.describe(chunk) + " is compressed or too short");
  format::PreparedChunk out;
  out.type = chunk.type;
  out.flags = chunk.flags;
  out.raw_size = chunk.raw_size;
  out.stored = reader.payload(chunk);
  uint32_t number = 0;
  std::memcpy(&number, out.stored.data(), 4);  // little-endian, as the file (spec/container.md §1)
  if (number != expected) {
    throw Error(ErrorCode::kCorrupt, reader.source() + ": " + reader.describe(chunk) + " names keyframe " + std::to_string(number) +
                                         ", not " + std::to_string(expected));
  }
  number += shift;
  std::memcpy(out.stored.data(), &number, 4);
  return out;
}

}  // namespace

void write_segment_file(const std::filesystem::path& path, const KeyframeSource& segment, SequenceFileMetadata metadata,
                        const SegmentPlacement& placement) {
  if (!metadata.field_coding.predicted()) {
    throw Error(
        ErrorCode::kInvalidArgument,
        path.string() + ": a segment's fields are coded with the steps its measures settled (metadata.field_coding), not the writer's own");
  }
  nlohmann::json settings = metadata.settings.empty() ? nlohmann::json::object() : nlohmann::json::parse(metadata.settings);
  settings["segment"] = {{"index", placement.segment.index},
                         {"count", placement.segment.count},
                         {"first_keyframe", placement.first_keyframe},
                         {"keyframes", placement.keyframes},
                         {"encode", placement.encode}};
  metadata.settings = settings.dump();
  metadata.texture_layout_from_settings = true;
  write_sequence_file(path, segment, metadata);
}

JoinReport join_segment_files(const std::vector<std::filesystem::path>& paths, const std::filesystem::path& output,
                              bool check_every_keyframe) {
  static_assert(std::endian::native == std::endian::little, "the container is little-endian");
  if (paths.empty()) throw Error(ErrorCode::kInvalidArgument, "no segments to join");
  std::vector<Segment> segments;
  for (const std::filesystem::path& path : paths) segments.push_back(open_segment(path, check_every_keyframe));
  std::stable_sort(segments.begin(), segments.end(), [](const Segment& a, const Segment& b) { return a.index < b.index; });
  const Segment& first = segments.front();
  size_t next = 0;
  for (const Segment& s : segments) {
    if (s.count != first.count || s.encode != first.encode || s.keyframes != first.keyframes)
      refuse(s, "it is a segment of another encode than " + first.path.string());
  }
  for (size_t i = 1; i < segments.size(); ++i) {
    if (segments[i].index == segments[i - 1].index)
      refuse(segments[i], "segment " + std::to_string(segments[i].index) + " is given twice (also " + segments[i - 1].path.string() + ")");
  }
  for (size_t i = 0; i < segments.size(); ++i) {
    const Segment& s = segments[i];
    if (s.index != static_cast<int>(i)) {
      throw Error(ErrorCode::kInvalidArgument, "segment " + std::to_string(i) + " of " + std::to_string(first.count) + " is missing (" +
                                                   s.path.string() + " is segment " + std::to_string(s.index) + ")");
    }
    check_same_header(first, s);
    const size_t period = first.file->header().group_size(), count = s.file->keyframe_count();
    if (static_cast<size_t>(s.first_keyframe) != next)
      refuse(s, "it starts at keyframe " + std::to_string(s.first_keyframe) + ", where " + std::to_string(next) + " was due");
    if (i + 1 < static_cast<size_t>(first.count) && count % period != 0) refuse(s, "it holds part of a group of keyframes");
    next += count;
  }
  if (static_cast<int>(segments.size()) != first.count) {
    throw Error(ErrorCode::kInvalidArgument,
                "segment " + std::to_string(segments.size()) + " of " + std::to_string(first.count) + " is missing");
  }
  if (next != static_cast<size_t>(first.keyframes))
    throw Error(ErrorCode::kInvalidArgument,
                "the segments hold " + std::to_string(next) + " keyframes of " + std::to_string(first.keyframes));

  // The joined header and index.
  FileHeader joined = first.file->header();
  joined.keyframe_count = static_cast<uint32_t>(next);
  for (const Segment& s : segments) joined.flags |= s.file->header().flags & kSharedTextures;
  joined.metadata.settings = joined_settings(segments);
  // The header's shape, and what the header states of the keyframes (as an opened file's source makes its outline).
  SequenceOutline outline = outline_of(joined.shape);
  outline.fixed_node_count = joined.fixed_nodes.size();
  outline.has_holes = joined.has_holes();
  outline.texture_size = joined.has_texture() ? static_cast<int>(joined.texture_size) : 0;
  std::vector<IndexEntry> entries;
  for (const Segment& s : segments) {
    for (const IndexEntry& e : s.file->index()) {
      if (!entries.empty() && !(e.time > entries.back().time)) refuse(s, "its keyframes do not follow the previous segment's in time");
      entries.push_back({e.time, e.pose, 0, 0});
      outline.times.push_back(e.time);
    }
  }
  const TextureLayout layout = joined.texture_groups()    ? TextureLayout::kGroups
                               : joined.shared_textures() ? TextureLayout::kSharedStills
                                                          : TextureLayout::kStills;
  std::vector<uint8_t> header_payload = write_header(outline, joined.fixed_nodes, joined.metadata, layout);
  const std::vector<uint8_t> header_read_back = header_payload;
  const format::PreparedChunk header = format::prepare_chunk(kHeaderChunk, std::move(header_payload), true, 19, format::Dictionary::kHeader);

  // Every group's and texture's chunk in the segments' order, with the keyframes naming it.
  struct Source {
    const Segment* segment;
    const format::ChunkView* chunk;
    uint32_t number;  // the keyframe number its payload opens with, in the segment
  };
  std::vector<PlacedChunk> placed;
  std::vector<Source> sources;
  for (const Segment& s : segments) {
    const auto& index = s.file->index();
    std::map<uint64_t, size_t> placed_at;  // a chunk's offset in the segment -> placed
    for (const format::ChunkView& chunk : s.file->container().chunks()) {
      if (chunk.type != kKeyframeGroupChunk && chunk.type != kLevelsGroupChunk && chunk.type != kTextureChunk && chunk.type != kTextureGroupChunk) continue;
      placed_at[chunk.offset] = placed.size();
      placed.push_back({chunk.total_size(), {}, {}});
      sources.push_back({&s, &chunk, UINT32_MAX});
    }
    for (size_t k = 0; k < index.size(); ++k) {
      const auto global = static_cast<uint32_t>(static_cast<size_t>(s.first_keyframe) + k);
      const auto group = placed_at.find(index[k].group_offset);
      if (group == placed_at.end()) refuse(s, "keyframe " + std::to_string(k) + "'s group is not a chunk");
      placed[group->second].group_of.push_back(global);
      if (sources[group->second].number == UINT32_MAX) sources[group->second].number = static_cast<uint32_t>(k);
      if (!joined.has_texture()) continue;
      const auto texture = placed_at.find(index[k].texture_offset);
      if (texture == placed_at.end()) refuse(s, "keyframe " + std::to_string(k) + "'s texture is not a chunk");
      placed[texture->second].texture_of.push_back(global);
      if (sources[texture->second].number == UINT32_MAX) sources[texture->second].number = static_cast<uint32_t>(k);
    }
  }
  // A chunk no keyframe names (a segment's own unknown chunk is not copied; these are of known
  // types) would be dead weight the joined index cannot describe.
  for (size_t c = 0; c < placed.size(); ++c) {
    if (placed[c].group_of.empty() && placed[c].texture_of.empty()) refuse(*sources[c].segment, "a chunk no keyframe names");
  }
  const IndexLayout laid = lay_out_index(header.total_size(), entries, joined, placed);
  // The joined header and index read back as a player reads them: what each segment satisfied alone
  // may not hold of the whole (the settings' size, the keyframe count, times too close across a
  // seam), and a file a player refuses is not written.
  try {
    const FileHeader read = read_header(
        header_read_back, output.string(), kDefaultDecoderLimits, [](uint32_t, SplineKind) { return uint64_t{1}; }, format::kMinorVersion);
    read_index(write_index(entries, joined), output.string(), read, format::kMinorVersion);
  } catch (const Error& e) {
    throw Error(ErrorCode::kInvalidArgument, std::string("the segments do not join into a file a player takes: ") + e.what());
  }
  format::write_file_atomically(output, [&](std::ostream& out) {
    format::ContainerWriter writer(out);
    writer.add(header);
    writer.add(laid.index);
    for (size_t c = 0; c < placed.size(); ++c) {
      const Source& from = sources[c];
      const format::PreparedChunk chunk =
          renumbered(from.segment->file->container(), *from.chunk, from.number, static_cast<uint32_t>(from.segment->first_keyframe));
      if (writer.add(chunk) != laid.offsets[c]) throw Error(ErrorCode::kInternal, "segment join: the index is out of step with the chunks");
    }
    writer.finish();
    if (writer.size() != laid.end + format::ContainerWriter::end_chunk_size())
      throw Error(ErrorCode::kInternal, "segment join: the file is out of step with its index");
  });
  JoinReport report;
  report.segments = static_cast<int>(segments.size());
  report.keyframes = next;
  report.bytes = std::filesystem::file_size(output);
  return report;
}

}  // namespace facemorph
