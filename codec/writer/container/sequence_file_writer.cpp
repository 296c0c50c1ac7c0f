// A Sequence written as a .fmv file (spec/container.md, format 2.1): every keyframe and texture
// read from its source and coded into its chunk (each chunk's writer is a file of its own:
// header_chunk, index_chunk, keyframe_group_chunk, texture_chunk, residual_chunk), the index laid
// out, the file written at once or streamed through a temporary file. The reader is
// codec/decoder/container/sequence_file.cpp.
#include "codec/writer/container/sequence_file_writer.hpp"

#include "codec/writer/container/chunk_writers.hpp"
#include "format/container.hpp"
#include "format/error.hpp"
#include "format/file_io.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>

namespace facemorph {

using namespace file_layout;

namespace {

// The coding a writer uses where the caller gave no steps: each array's step a 65535th of its range
// over the keyframes (the precision of 16-bit fixed point), at least what keeps its largest value
// within 2²⁹ steps; the intra period and pose steps as given, or facemorph's defaults.
FieldCoding fixed_point_coding(const KeyframeSource& source, FieldCoding coding) {
  coding.steps.assign(kKeyframeArrays, 0);
  std::vector<double> lo(kKeyframeArrays, 0), hi(kKeyframeArrays, 0);
  for (size_t k = 0; k < source.outline().keyframe_count(); ++k) {
    const std::vector<std::vector<double>> arrays = keyframe_arrays(*source.keyframe(k));
    for (size_t a = 0; a < kKeyframeArrays; ++a) {
      for (double v : arrays[a]) {
        lo[a] = std::min(lo[a], v);
        hi[a] = std::max(hi[a], v);
      }
    }
  }
  for (size_t a = 0; a < kKeyframeArrays; ++a) {
    const double largest = std::max(std::abs(lo[a]), std::abs(hi[a]));
    coding.steps[a] = std::max({(hi[a] - lo[a]) / 65535, largest / (1 << 29), std::numeric_limits<double>::min()});
  }
  if (coding.rotation_step == 0 && coding.translation_step == 0) set_default_pose_steps(coding, source.outline().units);
  return coding;
}

// For each keyframe, the first keyframe whose texture is the same pixels (itself where none before
// is): those keyframes store one TEXR. Compared by a hash, then pixel by pixel (the earlier texture
// read again: one or two are held at a time). `hashes`: each keyframe's texture's hash, as computed.
std::vector<size_t> texture_owners(const KeyframeSource& source, std::vector<uint64_t>& hashes) {
  const size_t count = source.outline().keyframe_count();
  std::vector<size_t> owners(count);
  hashes.resize(count);
  std::unordered_multimap<uint64_t, size_t> seen;
  for (size_t k = 0; k < count; ++k) {
    owners[k] = k;
    const std::shared_ptr<const Image> image = source.texture(k);
    const uint64_t hash = hashes[k] = image_content_hash(*image);
    const auto [first, last] = seen.equal_range(hash);
    const auto same = std::find_if(first, last, [&](const auto& entry) {
      const std::shared_ptr<const Image> other = source.texture(entry.second);
      return other->width == image->width && other->height == image->height && other->channels == image->channels &&
             other->pixels == image->pixels;
    });
    if (same != last) {
      owners[k] = same->second;
    } else {
      seen.emplace(hash, k);
    }
  }
  return owners;
}

void check_texture(const SequenceOutline& o, size_t k, const Image& texture) {
  if (texture.width != o.texture_size || texture.height != o.texture_size || texture.channels != 3 ||
      texture.pixels.size() != static_cast<size_t>(texture.width) * static_cast<size_t>(texture.height) * 3) {
    throw Error(ErrorCode::kInvalidArgument, "sequence: keyframe " + std::to_string(k) + ": the texture is not " +
                                                 std::to_string(o.texture_size) + " x " + std::to_string(o.texture_size) + " RGB");
  }
}

}  // namespace

namespace {

// `sequence` as a source that does not own it: for a writer that uses it only within the call.
std::shared_ptr<const KeyframeSource> borrowed_source(const Sequence& sequence) {
  return memory_source(std::shared_ptr<const Sequence>(std::shared_ptr<const Sequence>(), &sequence));
}

}  // namespace

std::vector<uint8_t> encode_sequence_file(const Sequence& sequence, const SequenceFileMetadata& metadata) {
  return encode_sequence_file(*borrowed_source(sequence), metadata);
}

namespace {

// A file laid out: its header and index, and after them the spool's chunks in the file's order,
// each with the offset the index gives it.
struct LaidOutFile {
  format::PreparedChunk header, index;
  std::vector<std::pair<size_t, uint64_t>> chunks;  // (the spool's chunk, its offset)
  uint64_t size = 0;                                // the whole file's, end chunk included
};

// encode_sequence_file's work, up to the bytes: every keyframe and texture read and its chunk
// prepared into `spool` (in memory, spilled, or only its size), and the index laid out.
LaidOutFile lay_out_sequence_file(const KeyframeSource& source, const SequenceFileMetadata& given, format::ChunkSpool& spool,
                                  TextureGroupCache* coded = nullptr) {
  const SequenceOutline& outline = source.outline();
  validate_outline(outline);
  if (given.landmark_names.size() > kMaxLandmarks) throw Error(ErrorCode::kInvalidArgument, "too many landmark names");
  // The header's strings within what a reader takes (spec/container.md §5), or no file a player refuses.
  uint64_t string_bytes = 0;
  const auto check_string = [&string_bytes](const std::string& text, const std::string& what) {
    if (text.size() > kMaxStringBytes)
      throw Error(ErrorCode::kInvalidArgument,
                  what + " of " + std::to_string(text.size()) + " bytes (a file's strings take at most 1 MiB)");
    string_bytes += text.size();
    if (string_bytes > kMaxHeaderStringBytes) {
      throw Error(ErrorCode::kInvalidArgument,
                  what + " brings the header's strings to " + std::to_string(string_bytes) + " bytes (at most 4 MiB together)");
    }
  };
  check_string(given.settings, "settings");
  check_string(given.encoder, "an encoder name");
  check_string(outline.units, "units");
  for (const std::string& name : given.landmark_names) check_string(name, "a landmark name");
  SequenceFileMetadata metadata = given;
  FieldCoding& coding = metadata.field_coding;
  if (coding.steps.empty()) coding = fixed_point_coding(source, coding);
  check_field_coding(coding);
  const size_t count = outline.keyframe_count();
  const std::vector<int>& qualities = metadata.keyframe_texture_qualities;
  if (!qualities.empty()) {
    if (qualities.size() != count) {
      throw Error(ErrorCode::kInvalidArgument,
                  std::to_string(qualities.size()) + " texture qualities for " + std::to_string(count) + " keyframes");
    }
    for (int q : qualities) {
      if (q < 0 || q > 101) throw Error(ErrorCode::kInvalidArgument, "texture quality " + std::to_string(q) + " outside 0..101");
    }
  }
  // Keyframe 0's fixed-frame nodes, which every keyframe shares and the header stores.
  const std::vector<int32_t> fixed_nodes = source.keyframe(0)->fields.fixed_nodes;
  // Every keyframe and texture is read from the source one at a time (a group's keyframes in
  // order), so the writer holds the chunks it has made and one keyframe, not the sequence.
  // How the textures are laid out: one image sequence per group of keyframes (TGOP, format 2.1)
  // for lossy AVIF, or a still each (TEXR); stills of the same pixels stored once and named by
  // every keyframe that shows them (format 2.2). Where both apply, the fewer bytes.
  const bool has_texture = outline.has_texture();
  if (has_texture) {
    for (size_t k = 0; k < count; ++k) check_texture(outline, k, *source.texture(k));
  }
  std::vector<size_t> owners(count);
  for (size_t k = 0; k < count; ++k) owners[k] = k;
  std::vector<uint64_t> texture_hashes;  // each keyframe's texture's (image_content_hash)
  if (has_texture) owners = texture_owners(source, texture_hashes);
  const bool any_shared = std::any_of(owners.begin(), owners.end(), [k = size_t{0}](size_t owner) mutable { return owner != k++; });
  const bool groups_possible = uses_texture_groups(has_texture, metadata);
  const auto quality_of = [&](size_t k) { return qualities.empty() ? metadata.texture_quality : qualities[k]; };
  std::vector<size_t> stills;              // the spool's chunks, one per distinct texture (owner), in keyframe order
  std::vector<size_t> still_of(count, 0);  // keyframe k's chunk in `stills`
  const bool groups_by_settings = metadata.texture_layout_from_settings && groups_possible;
  if (has_texture && !groups_by_settings && (any_shared || !groups_possible)) {
    // An owner's quality is the finest any keyframe showing it asks for.
    std::vector<int> owner_quality(count, -1);
    for (size_t k = 0; k < count; ++k) owner_quality[owners[k]] = std::max(owner_quality[owners[k]], quality_of(k));
    for (size_t k = 0; k < count; ++k) {
      if (owners[k] == k) {
        still_of[k] = stills.size();
        stills.push_back(spool.add(format::prepare_chunk(
            kTextureChunk, write_texture(*source.texture(k), static_cast<uint32_t>(k), metadata.texture_codec, owner_quality[k]), true)));
      } else {
        still_of[k] = still_of[owners[k]];  // an owner comes before the keyframes sharing its texture
      }
    }
  }
  const size_t group = metadata.field_coding.intra_period;
  std::vector<size_t> texture_groups;  // the spool's chunks, one per group of keyframes
  if (groups_possible) {
    for (size_t k = 0; k < count; k += group) {
      const size_t n = std::min(group, count - k);
      // One quantiser for the sequence (libavif 0.11 gives a changed one to every frame still in
      // libaom's look-ahead): the finest its keyframes ask for, so each is at least as fine as its
      // quality asks.
      int quality = metadata.texture_quality;
      if (!qualities.empty())
        quality = *std::max_element(qualities.begin() + static_cast<long>(k), qualities.begin() + static_cast<long>(k + n));
      // The group's key from the hashes texture_owners computed: a cached group's textures are
      // not read again.
      TextureGroupCache::Key key{
          k, quality, {texture_hashes.begin() + static_cast<long>(k), texture_hashes.begin() + static_cast<long>(k + n)}};
      std::optional<std::vector<uint8_t>> payload;
      if (coded) payload = coded->find(key);
      if (!payload) {
        TextureGroupWriter group_textures(k, quality);
        for (size_t j = k; j < k + n; ++j) group_textures.add(*source.texture(j));
        payload = group_textures.finish();
        if (coded) coded->keep(std::move(key), *payload);
      }
      texture_groups.push_back(spool.add(format::prepare_chunk(kTextureGroupChunk, std::move(*payload), true)));
    }
  }
  const auto total = [&](const std::vector<size_t>& chunks) {
    uint64_t bytes = 0;
    for (size_t c : chunks) bytes += spool.total_size(c);
    return bytes;
  };
  TextureLayout texture_layout = any_shared ? TextureLayout::kSharedStills : TextureLayout::kStills;
  if (!texture_groups.empty() && (groups_by_settings || stills.empty() || total(texture_groups) < total(stills)))
    texture_layout = TextureLayout::kGroups;
  const bool grouped_textures = texture_layout == TextureLayout::kGroups;
  const std::vector<size_t>& textures = grouped_textures ? texture_groups : stills;
  const format::PreparedChunk header = format::prepare_chunk(kHeaderChunk, write_header(outline, fixed_nodes, metadata, texture_layout),
                                                             true, 19, format::Dictionary::kHeader);
  FileHeader layout;  // what the index's layout depends on
  layout.keyframe_count = static_cast<uint32_t>(count);
  layout.flags = static_cast<uint8_t>((has_texture ? kHasTexture : 0) | (grouped_textures ? kTextureGroups : 0));
  layout.metadata.field_coding = coding;
  // Every payload first, so the index can hold the offsets of the chunks after it. `groups[g]`:
  // group g's chunk; `textures`: the stills (keyframe k's is still_of[k]) or group g's TGOP.
  const std::shared_ptr<const GridFacts> grid = grid_facts(outline.grid_n);
  std::vector<size_t> groups;  // the spool's chunks
  std::vector<IndexEntry> entries(count);
  std::optional<KeyframeGroupWriter> group_writer;
  for (size_t k = 0; k < count; ++k) {
    const std::shared_ptr<const Keyframe> key = source.keyframe(k);
    validate_keyframe(outline, fixed_nodes, k, *key);
    entries[k].time = key->time;
    entries[k].pose = pose_codes(key->pose, coding);
    if (k % group == 0) group_writer.emplace(k, coding, *grid);
    group_writer->add(*key);
    if (k % group == group - 1 || k + 1 == count) {
      std::vector<uint8_t> payload = group_writer->finish();
      groups.push_back(spool.add(format::prepare_chunk(group_writer->chunk_type(), std::move(payload), true)));
    }
  }
  // Where each chunk goes: the residual frames first (format 2.3: a player reads them at open, with
  // the header and index), then a group's KGOP, then its TGOP, or after each keyframe's fields the
  // still it is the first to show.
  std::vector<PlacedChunk> placed;
  std::vector<size_t> spooled;  // each placed chunk's in the spool
  if (!outline.residuals.empty()) {
    // Not critical: a 2.2 decoder skips it and shows the spline alone (§12.1).
    spooled.push_back(spool.add(format::prepare_chunk(kResidualChunk, write_residuals(outline), false, 19)));
    placed.emplace_back().size = spool.total_size(spooled.back());
  }
  if (!outline.patches.empty()) {
    // Not critical either (format 2.4): a 2.3 decoder skips it and shows the blend alone (§12.1).
    spooled.push_back(spool.add(format::prepare_chunk(kPatchChunk, write_patches(outline), false, 19)));
    placed.emplace_back().size = spool.total_size(spooled.back());
  }
  std::vector<size_t> placed_still(count, 0);  // an owner's still among the placed
  for (size_t k = 0; k < count; ++k) {
    if (k % group == 0) {
      PlacedChunk& c = placed.emplace_back();
      c.size = spool.total_size(groups[k / group]);
      for (size_t j = k; j < std::min(count, k + group); ++j) c.group_of.push_back(static_cast<uint32_t>(j));
      spooled.push_back(groups[k / group]);
    }
    if (textures.empty()) continue;
    if (grouped_textures && k % group == 0) {
      PlacedChunk& c = placed.emplace_back();
      c.size = spool.total_size(textures[k / group]);
      c.texture_of = placed[placed.size() - 2].group_of;  // the group's KGOP, just placed
      spooled.push_back(textures[k / group]);
    } else if (!grouped_textures) {
      if (owners[k] == k) {
        placed_still[k] = placed.size();
        placed.emplace_back().size = spool.total_size(textures[still_of[k]]);
        spooled.push_back(textures[still_of[k]]);
      }
      placed[placed_still[owners[k]]].texture_of.push_back(static_cast<uint32_t>(k));  // an owner comes first
    }
  }
  const IndexLayout laid = lay_out_index(header.total_size(), entries, layout, placed);
  LaidOutFile file{header, laid.index, {}, laid.end + format::ContainerWriter::end_chunk_size()};
  for (size_t c = 0; c < placed.size(); ++c) file.chunks.emplace_back(spooled[c], laid.offsets[c]);
  return file;
}

// The laid-out file's bytes to `writer`, each chunk read back from `spool` in turn; returns what
// the writer's finish() returns (the bytes, or nothing when it streams).
std::vector<uint8_t> write_laid_out_file(const LaidOutFile& file, const format::ChunkSpool& spool, format::ContainerWriter& writer) {
  writer.add(file.header);
  writer.add(file.index);
  for (const auto& [chunk, offset] : file.chunks) {
    if (writer.add(spool.get(chunk)) != offset) throw Error(ErrorCode::kNumerical, "container index out of step");
  }
  std::vector<uint8_t> bytes = writer.finish();
  if (writer.size() != file.size) throw Error(ErrorCode::kNumerical, "container index out of step");
  return bytes;
}

}  // namespace

std::vector<uint8_t> encode_sequence_file(const KeyframeSource& source, const SequenceFileMetadata& metadata) {
  format::ChunkSpool spool(format::ChunkSpool::Keep::kMemory);
  const LaidOutFile file = lay_out_sequence_file(source, metadata, spool);
  format::ContainerWriter writer;
  return write_laid_out_file(file, spool, writer);
}

uint64_t sequence_file_size(const KeyframeSource& source, const SequenceFileMetadata& metadata, TextureGroupCache* coded) {
  format::ChunkSpool spool(format::ChunkSpool::Keep::kSizes);
  return lay_out_sequence_file(source, metadata, spool, coded).size;
}

void write_sequence_file(const std::filesystem::path& path, const Sequence& sequence, const SequenceFileMetadata& metadata) {
  write_sequence_file(path, *borrowed_source(sequence), metadata);
}

void write_sequence_file(const std::filesystem::path& path, const KeyframeSource& source, const SequenceFileMetadata& metadata,
                         TextureGroupCache* coded) {
  // Streamed: the chunks wait in the spool's temporary file until the index is laid out; only then
  // is the file opened under its temporary name, the chunks copied to it one at a time, and the
  // file renamed when whole. Memory holds a keyframe and a chunk; an encode killed while the
  // source is read leaves nothing beside the destination.
  const auto naming_the_file = [&](const auto& step) {
    try {
      step();
    } catch (const Error& e) {
      throw Error(e.code(), path.string() + ": " + e.what());
    }
  };
  format::ChunkSpool spool(format::ChunkSpool::Keep::kSpill);
  LaidOutFile file;
  naming_the_file([&] { file = lay_out_sequence_file(source, metadata, spool, coded); });
  format::write_file_atomically(path, [&](std::ostream& out) {
    naming_the_file([&] {
      format::ContainerWriter writer(out);
      write_laid_out_file(file, spool, writer);
    });
  });
}

}  // namespace facemorph
