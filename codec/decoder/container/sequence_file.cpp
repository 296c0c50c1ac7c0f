// The .fmv file of a Sequence read (spec/container.md, format 2.1): the chunks put together. The
// outer layer (preamble, chunks, checksums, zstd) is format/container; each chunk's payload has its
// own reader (header_chunk, index_chunk, keyframe_group_chunk, texture_chunk, texture_group_chunk,
// residual_chunk). This file opens a file for reading: the header and index read and checked,
// every index entry at a chunk of its kind; keyframes and textures decoded when asked for. The
// writer is codec/writer/container/sequence_file_writer.cpp.
#include "codec/decoder/container/sequence_file.hpp"

#include "codec/decoder/container/chunk_readers.hpp"
#include "codec/decoder/container/opened_file.hpp"

#include "codec/core/image/image.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/decoder/image/image_decode.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>

namespace facemorph {

using namespace file_layout;

// ---- A file opened for reading (opened_file.hpp) ----

struct OpenedFile::State {
  // A file of K keyframes has 2 K + 2 chunks at most before its end chunk: the walk stops at twice
  // that for the largest K allowed (room for chunks a later minor version adds), so that its list
  // of chunks (about 80 bytes each) does not grow with a file padded with empty ones.
  State(std::span<const uint8_t> bytes, std::string source_name, const DecoderLimits& limits)
      : reader(bytes, source_name, 4 * uint64_t{limits.max_keyframes} + 64),
        source(std::move(source_name)),
        file_bytes(bytes.size()),
        limits(limits) {}
  format::ContainerReader reader;
  std::string source;
  uint64_t file_bytes = 0;
  DecoderLimits limits;
  std::optional<FileHeader> header;
  std::vector<IndexEntry> index;
  std::vector<RigidPose> poses;
  // Keyframe k shows the texture stored for texture_owner[k]: itself, or in a file of shared
  // textures (format 2.2) the first keyframe whose entry names the same TEXR.
  std::vector<uint32_t> texture_owner;
  // What describe() says of the residual frames and patches, counted at open (take_frames() moves them out).
  size_t residual_frames = 0, frame_patches = 0, patch_nodes = 0;
};

namespace {

// The one chunk of `type` (null: none); two of them are corrupt (a file holds its `what` in one).
const format::ChunkView* single_chunk(const std::vector<format::ChunkView>& chunks, std::string_view type, const std::string& what,
                                      const std::string& source) {
  const format::ChunkView* found = nullptr;
  for (const format::ChunkView& chunk : chunks) {
    if (chunk.type != type) continue;
    if (found) corrupt(source, "two " + std::string(type) + " chunks; a file holds its " + what + " in one");
    found = &chunk;
  }
  return found;
}

}  // namespace

OpenedFile::OpenedFile(std::span<const uint8_t> bytes, std::string source, const DecoderLimits& limits,
                       const KeyframesHeld& keyframes_held) {
  check_decoder_limits(limits);
  state_ = std::make_unique<State>(bytes, std::move(source), limits);
  State& s = *state_;
  const format::ContainerReader& reader = s.reader;
  const std::vector<format::ChunkView>& chunks = reader.chunks();
  if (chunks.size() < 2 || chunks[0].type != kHeaderChunk || chunks[1].type != kIndexChunk) {
    corrupt(s.source, "the file does not start with its header and index chunks");
  }
  for (const format::ChunkView& chunk : chunks) {
    const bool known = chunk.type == kHeaderChunk || chunk.type == kIndexChunk || chunk.type == kKeyframeGroupChunk || chunk.type == kLevelsGroupChunk ||
                       chunk.type == kTextureChunk || chunk.type == kTextureGroupChunk || chunk.type == kResidualChunk ||
                       chunk.type == kPatchChunk;
    if (!known && chunk.critical()) {
      throw Error(ErrorCode::kUnsupported,
                  s.source + ": " + reader.describe(chunk) + " is critical and unknown to this decoder (a newer format?)");
    }
    // Every KGLV, whether an index entry names it or not: a 2.5 decoder refuses the file for any.
    if (chunk.type == kLevelsGroupChunk && reader.minor_version() < kLevelsMinorVersion)
      corrupt(s.source, reader.describe(chunk) + " in a file stamped 2." + std::to_string(reader.minor_version()) +
                            " (the levels predictor's group chunk is 2.6's)");
  }
  // The header and the index decompress to no more than the format lets them hold (§10.2 steps 2
  // and 5): a chunk stating more is corrupt before a byte is decompressed, whatever the budget.
  const uint16_t minor = reader.minor_version();
  const auto bounded_payload = [&](const format::ChunkView& chunk, uint64_t bound, const std::string& what) {
    if (chunk.raw_size > bound) {
      corrupt(s.source, reader.describe(chunk) + " states " + std::to_string(chunk.raw_size) + " bytes; " + what + " holds at most " +
                            std::to_string(bound));
    }
    return reader.payload(chunk, limits.max_memory_bytes);
  };
  if (chunks[0].raw_size > max_header_bytes(limits.max_grid_n) && chunks[0].raw_size <= max_header_bytes(kMaxGridSize)) {
    over_limit(s.source, reader.describe(chunks[0]) + " states " + std::to_string(chunks[0].raw_size) +
                             " bytes, more than a header of a grid within " + std::to_string(limits.max_grid_n) +
                             " holds (max_grid_n, --max-grid)");
  }
  s.header = read_header(bounded_payload(chunks[0], max_header_bytes(kMaxGridSize), "a header"), s.source, limits, keyframes_held, minor);
  const FileHeader& header = *s.header;
  // Texture groups came with format 2.1: a file stamped 2.0 cannot hold them.
  if (header.texture_groups() && reader.minor_version() < 1) {
    corrupt(s.source, "header: texture groups (flag bit 2) in a format " + std::to_string(reader.major_version()) + "." +
                          std::to_string(reader.minor_version()) + " file");
  }
  if (header.shared_textures() && reader.minor_version() < 2) {
    corrupt(s.source, "header: shared textures (flag bit 3) in a format " + std::to_string(reader.major_version()) + "." +
                          std::to_string(reader.minor_version()) + " file");
  }
  s.index =
      read_index(bounded_payload(chunks[1], max_index_bytes(header), "an index of " + std::to_string(header.keyframe_count) + " keyframes"),
                 s.source, header, minor);
  // Shared textures: each TEXR belongs to the first keyframe that names it (its number must say so,
  // §8), and every later keyframe naming it shows that texture. Elsewhere each keyframe owns its
  // entry, and one naming another's TEXR fails by that number when decoded.
  s.texture_owner.resize(s.index.size());
  std::unordered_map<uint64_t, uint32_t> first_to_name;
  for (size_t k = 0; k < s.index.size(); ++k) {
    s.texture_owner[k] = static_cast<uint32_t>(k);
    if (header.shared_textures())
      s.texture_owner[k] = first_to_name.emplace(s.index[k].texture_offset, static_cast<uint32_t>(k)).first->second;
  }
  // Every entry points at a chunk of its kind, before anything is decoded from it.
  for (size_t k = 0; k < s.index.size(); ++k) {
    const std::string name = "keyframe " + std::to_string(k);
    const format::ChunkView& chunk = reader.chunk_at(s.index[k].group_offset, name + "'s index entry");
    if (chunk.type != kKeyframeGroupChunk && chunk.type != kLevelsGroupChunk)
      corrupt(s.source, name + "'s index entry points at a " + chunk.type + " chunk, not " + std::string(kKeyframeGroupChunk));
    // Stored as it is: its stream is the compression (and the bytes fminfo divides among keyframes).
    if (chunk.compressed()) corrupt(s.source, reader.describe(chunk) + " is compressed; a group's chunk never is");
    if (header.texture_groups()) {
      if (k % header.group_size() == 0) {  // the group's entry (its later keyframes share it)
        const format::ChunkView& texture = reader.chunk_at(s.index[k].texture_offset, name + "'s texture group entry");
        if (texture.type != kTextureGroupChunk)
          corrupt(s.source, name + "'s texture group entry points at a " + texture.type + " chunk, not TGOP");
        if (texture.compressed()) corrupt(s.source, reader.describe(texture) + " is compressed; a texture group's chunk never is");
      }
    } else if (header.has_texture()) {
      const format::ChunkView& texture = reader.chunk_at(s.index[k].texture_offset, name + "'s texture entry");
      if (texture.type != kTextureChunk) corrupt(s.source, name + "'s texture entry points at a " + texture.type + " chunk, not TEXR");
      // §8: an image codec's bytes, stored as they are (zstd would only make a small file decompress
      // to a large one: 17 kB holding 300 MB).
      if (texture.compressed()) corrupt(s.source, reader.describe(texture) + " is compressed; a texture's chunk never is");
    } else if (s.index[k].texture_offset != 0) {
      corrupt(s.source, name + " has a texture entry in a file without textures");
    }
  }
  s.poses.reserve(s.index.size());
  for (const IndexEntry& entry : s.index) s.poses.push_back(pose_of(entry.pose, header.metadata.field_coding));
  // Residual frames (format 2.3, §7.4) and frame patches (2.4, §7.5): one chunk of each at most. In
  // a file of an earlier minor version a chunk of that name is skipped, as that version's decoders
  // skip it.
  std::vector<double> key_times;
  key_times.reserve(s.index.size());
  for (const IndexEntry& entry : s.index) key_times.push_back(entry.time);
  if (const format::ChunkView* chunk = minor >= 3 ? single_chunk(chunks, kResidualChunk, "residual frames", s.source) : nullptr) {
    s.header->shape.residuals =
        read_residuals(reader.payload(*chunk, limits.max_memory_bytes), s.source, header.shape, key_times, limits.max_memory_bytes, minor);
  }
  if (const format::ChunkView* chunk = minor >= 4 ? single_chunk(chunks, kPatchChunk, "frame patches", s.source) : nullptr) {
    // Charged against what the residual frames left of the budget: the two are held together, and
    // each alone within the whole budget would let a small file hold twice it before the memory
    // plan refuses it.
    const uint64_t residual_memory = header.shape.residuals.size() * kResidualMemoryBytes;  // ≤ the budget: checked
    s.header->shape.patches = read_patches(reader.payload(*chunk, limits.max_memory_bytes), s.source, header.shape, key_times,
                                           limits.max_memory_bytes - residual_memory, minor);
  }
  s.residual_frames = header.shape.residuals.size();
  s.frame_patches = header.shape.patches.size();
  for (const FramePatch& p : header.shape.patches) s.patch_nodes += p.nodes.size();
}

OpenedFile::~OpenedFile() = default;

const std::string& OpenedFile::source() const { return state_->source; }
const Sequence& OpenedFile::shape() const { return state_->header->shape; }
OpenedFile::Frames OpenedFile::take_frames() {
  Sequence& shape = state_->header->shape;
  Frames frames{std::move(shape.residuals), std::move(shape.patches)};
  shape.residuals.clear();
  shape.patches.clear();
  return frames;
}
const FileHeader& OpenedFile::header() const { return *state_->header; }
const std::vector<IndexEntry>& OpenedFile::index() const { return state_->index; }
const format::ContainerReader& OpenedFile::container() const { return state_->reader; }
size_t OpenedFile::keyframe_count() const { return state_->index.size(); }
double OpenedFile::keyframe_time(size_t k) const { return state_->index.at(k).time; }
const RigidPose& OpenedFile::keyframe_pose(size_t k) const { return state_->poses.at(k); }
size_t OpenedFile::fixed_node_count() const { return state_->header->fixed_nodes.size(); }
bool OpenedFile::has_texture() const { return state_->header->has_texture(); }
bool OpenedFile::has_holes() const { return state_->header->has_holes(); }
int OpenedFile::texture_size() const { return static_cast<int>(state_->header->texture_size); }

uint64_t OpenedFile::values_per_keyframe() const {
  uint64_t values = 0;
  for (size_t length : expected_lengths(*state_->header)) values += length;
  return values;
}

uint64_t OpenedFile::header_bytes() const {
  const FileHeader& h = *state_->header;
  uint64_t bytes = h.shape.units.size() + h.metadata.encoder.size() + h.metadata.settings.size() + 4 * uint64_t{h.fixed_nodes.size()};
  for (const std::string& name : h.metadata.landmark_names) bytes += name.size() + sizeof name;
  return bytes;
}

uint64_t OpenedFile::largest_payload() const {
  uint64_t largest = 0;
  for (const format::ChunkView& chunk : state_->reader.chunks()) {
    if (chunk.type == kKeyframeGroupChunk || chunk.type == kLevelsGroupChunk || chunk.type == kTextureChunk || chunk.type == kTextureGroupChunk)
      largest = std::max(largest, chunk.raw_size);
  }
  return largest;
}

size_t OpenedFile::run_length() const { return state_->header->group_size(); }

size_t OpenedFile::texture_owner(size_t k) const { return state_->texture_owner.at(k); }

size_t OpenedFile::texture_run_length() const { return state_->header->texture_groups() ? state_->header->group_size() : 1; }

uint64_t OpenedFile::texture_decoder_bytes() const {
  return state_->header->texture_groups() ? texture_sequence_decoder_bytes(state_->header->texture_size) : 0;
}

std::unique_ptr<OpenedFile::RunReader<Keyframe>> OpenedFile::read_fields(size_t first) const {
  class FieldRun final : public RunReader<Keyframe> {
   public:
    FieldRun(const State& s, size_t first, size_t count, const format::ChunkView& chunk)
        : s_(s),
          first_(first),
          count_(count),
          framing_(chunk.total_size() - chunk.raw_size),
          group_(s.reader.payload(chunk, s.limits.max_memory_bytes), s.source + ": " + s.reader.describe(chunk), *s.header,
                 static_cast<uint32_t>(first), static_cast<uint32_t>(count), s.reader.minor_version(), chunk.type == kLevelsGroupChunk) {}
    size_t next() const override { return first_ + group_.next(); }
    size_t end() const override { return first_ + count_; }
    std::optional<Keyframe> read(WorkMeter* work, bool, uint64_t& bytes) override {
      const size_t k = next();
      uint64_t end = 0;
      Keyframe key = group_.read(work, end);
      key.time = s_.index[k].time;  // the index holds the time and pose
      key.pose = s_.poses[k];
      // The chunk's framing counts with its first keyframe.
      bytes = end - previous_end_ + (k == first_ ? framing_ : 0);
      previous_end_ = end;
      return key;
    }
    void finish() const override { group_.expect_end(); }

   private:
    const State& s_;
    size_t first_, count_;
    uint64_t framing_, previous_end_ = 0;
    KeyframeGroupReader group_;
  };
  const State& s = *state_;
  if (first % run_length() != 0 || first >= s.index.size()) {
    throw Error(ErrorCode::kInternal, s.source + ": keyframe " + std::to_string(first) + " does not start a run");
  }
  const format::ChunkView& chunk = s.reader.chunk_at(s.index[first].group_offset, "keyframe " + std::to_string(first) + "'s index entry");
  return std::make_unique<FieldRun>(s, first, std::min(run_length(), s.index.size() - first), chunk);
}

void OpenedFile::decode_run(size_t first, size_t last, const std::function<void(size_t, Keyframe&&, uint64_t)>& take,
                            WorkMeter* work) const {
  const std::unique_ptr<RunReader<Keyframe>> run = read_fields(first);
  if (last < first || last >= run->end()) {
    throw Error(ErrorCode::kInternal,
                state_->source + ": keyframes " + std::to_string(first) + ".." + std::to_string(last) + " are not one run's");
  }
  while (run->next() <= last) {
    const size_t k = run->next();
    uint64_t bytes = 0;
    std::optional<Keyframe> key = run->read(work, true, bytes);  // before take's arguments: bytes is set here
    take(k, std::move(*key), bytes);
  }
  if (last + 1 == run->end()) run->finish();
}

const format::ChunkView& OpenedFile::texture_chunk(size_t k) const {
  return state_->reader.chunk_at(state_->index.at(k).texture_offset, "keyframe " + std::to_string(k) + "'s texture entry");
}

std::unique_ptr<OpenedFile::RunReader<Image>> OpenedFile::read_textures(size_t first) const {
  // Each frame's M² pixels are charged before it is decoded (an image decoder cannot be stopped
  // midway), at the cost of its codec (§10.3).
  class TextureRun final : public RunReader<Image> {
   public:
    TextureRun(const OpenedFile& file, size_t first, size_t count, uint64_t pixel_cost)
        : file_(file),
          first_(first),
          count_(count),
          pixels_(uint64_t(file.texture_size()) * uint64_t(file.texture_size())),
          pixel_cost_(pixel_cost) {}
    size_t next() const override { return group_ ? first_ + group_->next() : first_ + (still_read_ ? 1 : 0); }
    size_t end() const override { return first_ + count_; }
    std::optional<Image> read(WorkMeter* work, bool wanted, uint64_t& bytes) override {
      const size_t k = next();
      if (k >= end()) throw Error(ErrorCode::kInternal, file_.source() + ": texture " + std::to_string(k) + " past its run");
      bytes = 0;
      if (work != nullptr) {
        work->charge(pixels_ * pixel_cost_,
                     "decoding keyframe " + std::to_string(k) + "'s texture of " + std::to_string(file_.texture_size()) + "² pixels");
      }
      const State& s = *file_.state_;
      if (!s.header->texture_groups()) {
        still_read_ = true;
        return wanted ? std::optional<Image>(file_.decode_texture(k)) : std::nullopt;
      }
      if (!group_) {
        const format::ChunkView& chunk = file_.texture_chunk(first_);
        group_ = std::make_unique<TextureGroupReader>(s.reader.payload(chunk, s.limits.max_memory_bytes),
                                                      s.source + ": " + s.reader.describe(chunk) + " (keyframes " + std::to_string(first_) +
                                                          ".." + std::to_string(first_ + count_ - 1) + ")",
                                                      static_cast<uint32_t>(first_), static_cast<uint32_t>(count_),
                                                      static_cast<uint32_t>(s.header->texture_size));
      }
      Image image = group_->read(wanted);
      return wanted ? std::optional<Image>(std::move(image)) : std::nullopt;
    }
    void finish() const override {}

   private:
    const OpenedFile& file_;
    size_t first_, count_;
    uint64_t pixels_, pixel_cost_;
    bool still_read_ = false;
    std::unique_ptr<TextureGroupReader> group_;  // made at the first frame (a still reads its own chunk)
  };
  const State& s = *state_;
  const size_t run = texture_run_length();
  if (first % run != 0 || first >= s.index.size()) {
    throw Error(ErrorCode::kInternal, s.source + ": texture " + std::to_string(first) + " does not start a run");
  }
  const uint64_t pixel_cost = texture_codec(first) == TextureCodec::kWebp ? WorkMeter::kPerWebpPixel : WorkMeter::kPerPixel;
  return std::make_unique<TextureRun>(*this, first, std::min(run, s.index.size() - first), pixel_cost);
}

void OpenedFile::decode_textures(size_t first, size_t last, const std::function<bool(size_t)>& wanted,
                                 const std::function<void(size_t, Image&&)>& take, WorkMeter* work) const {
  const std::unique_ptr<RunReader<Image>> run = read_textures(first);
  if (last < first || last >= run->end()) {
    throw Error(ErrorCode::kInternal,
                state_->source + ": textures " + std::to_string(first) + ".." + std::to_string(last) + " are not one run's");
  }
  while (run->next() <= last) {
    const size_t k = run->next();
    uint64_t bytes = 0;
    std::optional<Image> image = run->read(work, wanted(k), bytes);
    if (image) take(k, std::move(*image));
  }
}

void OpenedFile::decode_every_keyframe(const std::function<void(size_t, Keyframe&&, uint64_t)>& take) const {
  for (size_t first = 0; first < keyframe_count(); first += run_length())
    decode_run(first, std::min(first + run_length(), keyframe_count()) - 1, take);
}

void OpenedFile::decode_every_texture(const std::function<void(size_t, Image&&)>& take) const {
  const size_t run = texture_run_length();
  for (size_t first = 0; first < keyframe_count(); first += run) {
    if (texture_owner(first) != first) continue;  // a shared texture, decoded at its owner
    decode_textures(
        first, std::min(first + run, keyframe_count()) - 1, [](size_t) { return true; }, take);
  }
}

Image OpenedFile::decode_texture(size_t k) const {
  const State& s = *state_;
  if (s.header->texture_groups()) {
    Image image;
    const size_t first = k / texture_run_length() * texture_run_length();
    decode_textures(
        first, k, [k](size_t j) { return j == k; }, [&](size_t, Image&& decoded) { image = std::move(decoded); });
    return image;
  }
  const format::ChunkView& chunk = texture_chunk(k);
  const uint32_t owner = s.texture_owner.at(k);
  return read_texture(s.reader.payload(chunk, s.limits.max_memory_bytes),
                      s.source + ": " + s.reader.describe(chunk) + " (keyframe " + std::to_string(owner) + ")", owner,
                      s.header->texture_size);
}

TextureCodec OpenedFile::texture_codec(size_t k) const {
  const State& s = *state_;
  if (s.header->texture_groups()) return TextureCodec::kAvif;  // TGOP's only codec, 3
  const format::ChunkView& chunk = texture_chunk(k);
  // The codec's number is in the payload's first bytes, which a TEXR chunk stores uncompressed.
  const uint32_t owner = s.texture_owner.at(k);
  const std::string where = s.source + ": " + s.reader.describe(chunk) + " (keyframe " + std::to_string(owner) + ")";
  return texture_codec_of(chunk.stored, where, owner);  // never compressed (refused at open)
}

void OpenedFile::verify_checksums() const { state_->reader.verify(); }

SequenceFileInfo OpenedFile::describe(bool split_texture_groups) const {
  const State& s = *state_;
  const FileHeader& header = *s.header;
  SequenceFileInfo info;
  info.major_version = s.reader.major_version();
  info.minor_version = s.reader.minor_version();
  info.file_bytes = s.file_bytes;
  info.grid_hash = header.grid_hash;
  info.grid_rule = static_cast<int>(header.grid_rule);
  info.texture_size = static_cast<int>(header.texture_size);
  info.metadata = header.metadata;
  info.residual_frames = s.residual_frames;
  info.frame_patches = s.frame_patches;
  info.patch_nodes = s.patch_nodes;
  info.metadata.texture_codec = has_texture() ? texture_codec(0) : TextureCodec::kWebp;
  info.metadata.texture_coding = header.texture_groups() ? TextureCoding::kSequence : TextureCoding::kStills;
  info.keyframes.resize(s.index.size());
  if (header.texture_groups()) {
    // Each keyframe its frame's AV1 sample; the group's first also the chunk's framing and the AVIF
    // container. A group whose sequence does not parse (a fault its frames report when decoded)
    // is given whole to its first keyframe.
    const size_t run = texture_run_length();
    for (size_t first = 0; first < s.index.size(); first += run) {
      const format::ChunkView& chunk = texture_chunk(first);
      const auto count = static_cast<uint32_t>(std::min(run, s.index.size() - first));
      std::vector<uint64_t> samples;
      if (split_texture_groups) try {
          samples =
              texture_group_sample_bytes(s.reader.payload(chunk, s.limits.max_memory_bytes), s.source + ": " + s.reader.describe(chunk),
                                         static_cast<uint32_t>(first), count, header.texture_size);
        } catch (const Error&) {
          samples.clear();
        }
      uint64_t shared = chunk.total_size();
      for (size_t j = 1; j < samples.size(); ++j) {
        const uint64_t bytes = std::min(samples[j], shared);
        info.keyframes[first + j].texture = bytes;
        shared -= bytes;
      }
      info.keyframes[first].texture = shared;
    }
  } else if (has_texture()) {  // a shared texture's bytes are its owner's
    for (size_t k = 0; k < s.index.size(); ++k) info.keyframes[k].texture = s.texture_owner[k] == k ? texture_chunk(k).total_size() : 0;
  }
  for (size_t k = 0; k < s.index.size(); ++k) info.distinct_textures += has_texture() && s.texture_owner[k] == k;
  for (size_t first = 0; first < s.index.size(); first += run_length()) {
    const format::ChunkView& chunk = s.reader.chunk_at(s.index[first].group_offset, "keyframe " + std::to_string(first) + "'s index entry");
    info.field_groups.push_back({first, std::min(run_length(), s.index.size() - first), chunk.total_size()});
  }
  for (const format::ChunkView& chunk : s.reader.chunks()) {
    auto it = std::find_if(info.chunks.begin(), info.chunks.end(), [&](const auto& t) { return t.type == chunk.type; });
    if (it == info.chunks.end()) it = info.chunks.insert(info.chunks.end(), {chunk.type, 0, 0, 0, 0});
    ++it->count;
    it->against_dictionary += chunk.against_dictionary() ? 1 : 0;
    it->stored_bytes += chunk.total_size();
    it->raw_bytes += chunk.raw_size;
  }
  return info;
}

void OpenedFile::check_every_keyframe(SequenceFileInfo* info, const std::function<void(size_t, const Keyframe&)>& each) const {
  std::vector<uint64_t> field_bytes(keyframe_count());
  decode_every_keyframe([&](size_t k, Keyframe&& key, uint64_t bytes) {
    field_bytes[k] = bytes;
    if (each) each(k, key);
  });
  if (has_texture()) decode_every_texture([](size_t, Image&&) {});
  verify_checksums();  // chunks no keyframe refers to too
  if (info) {
    *info = describe();
    for (size_t k = 0; k < field_bytes.size(); ++k) info->keyframes[k].fields = field_bytes[k];
  }
}

Sequence decode_sequence_file(std::span<const uint8_t> bytes, const std::string& source, SequenceFileInfo* info,
                              const DecoderLimits& limits) {
  check_decoder_limits(limits);
  if (bytes.size() > limits.max_memory_bytes) {
    throw Error(ErrorCode::kLimit, source + ": " + std::to_string(bytes.size()) + " bytes, over the memory limit of " +
                                       std::to_string(limits.max_memory_bytes));
  }
  // Decoded whole: every keyframe is held at once.
  OpenedFile file(bytes, source, limits, [](uint32_t keyframes, SplineKind) { return uint64_t{keyframes}; });
  OpenedFile::Frames frames = file.take_frames();
  Sequence sequence = file.shape();
  sequence.residuals = std::move(frames.residuals);
  sequence.patches = std::move(frames.patches);
  std::vector<uint64_t> field_bytes(file.keyframe_count());
  file.decode_every_keyframe([&](size_t k, Keyframe&& key, uint64_t bytes_taken) {
    sequence.keyframes.push_back(std::move(key));
    field_bytes[k] = bytes_taken;
  });
  if (file.has_texture()) {
    file.decode_every_texture([&](size_t k, Image&& image) { sequence.keyframes[k].texture = std::move(image); });
    for (size_t k = 0; k < file.keyframe_count(); ++k) {
      if (file.texture_owner(k) != k) sequence.keyframes[k].texture = sequence.keyframes[file.texture_owner(k)].texture;
    }
  }
  file.verify_checksums();
  try {
    validate_sequence(sequence);
  } catch (const Error& e) {
    corrupt(source, e.what());
  }
  if (info) {
    *info = file.describe();
    for (size_t k = 0; k < field_bytes.size(); ++k) info->keyframes[k].fields = field_bytes[k];
  }
  return sequence;
}

SequenceFileInfo inspect_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits) {
  return inspect_sequence_file(path, limits, {}, {});
}

SequenceFileInfo inspect_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits,
                                       const std::function<void(const SequenceFileInfo&)>& opened,
                                       const std::function<void(size_t, const Keyframe&)>& each) {
  check_decoder_limits(limits);
  format::MappedFile mapped(path);
  // One keyframe at a time: what a decoder on demand holds for the frame's keyframes, no more.
  const OpenedFile file(mapped.bytes(), path.string(), limits,
                        [](uint32_t keyframes, SplineKind) { return std::min<uint64_t>(keyframes, 1); });
  if (opened) opened(file.describe());
  SequenceFileInfo info;
  file.check_every_keyframe(&info, each);
  return info;
}

SequenceFileInfo describe_sequence_file(const std::filesystem::path& path, const DecoderLimits& limits) {
  check_decoder_limits(limits);
  format::MappedFile mapped(path);
  const OpenedFile file(mapped.bytes(), path.string(), limits,
                        [](uint32_t keyframes, SplineKind) { return std::min<uint64_t>(keyframes, 1); });
  file.verify_checksums();
  return file.describe();
}

Sequence read_sequence_file(const std::filesystem::path& path, SequenceFileInfo* info, const DecoderLimits& limits) {
  // The file's size against the budget before its bytes are read.
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path, error);
  if (!error && size > limits.max_memory_bytes) {
    throw Error(ErrorCode::kLimit, path.string() + ": " + std::to_string(size) + " bytes, over the memory limit of " +
                                       std::to_string(limits.max_memory_bytes));
  }
  const std::vector<uint8_t> bytes = format::read_file(path);
  return decode_sequence_file(bytes, path.string(), info, limits);
}

}  // namespace facemorph
