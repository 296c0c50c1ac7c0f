// The header, HEAD (spec/container.md §5), as the writer lays it out; the reader is
// codec/decoder/container/header_chunk.cpp.
#include "codec/writer/container/chunk_writers.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "format/byte_writer.hpp"

#include <string>

#ifndef FACEMORPH_VERSION
#define FACEMORPH_VERSION "unknown"
#endif

namespace facemorph::file_layout {

using format::ByteWriter;

std::vector<uint8_t> write_header(const SequenceOutline& s, const std::vector<int32_t>& fixed, const SequenceFileMetadata& metadata,
                                  TextureLayout textures) {
  const DiskGridShape shape = disk_grid_shape(s.grid_n);
  ByteWriter w;
  w.write(static_cast<uint32_t>(s.grid_n));
  w.write(static_cast<uint32_t>(kDiskGridRule));
  w.write(grid_facts(s.grid_n)->hash);
  w.write(code_of(kRepresentations, s.representation));
  w.write(code_of(kSplineKinds, s.spline));
  w.write(static_cast<uint8_t>((s.has_texture() ? kHasTexture : 0) | (s.has_holes ? kHasHoles : 0) |
                               (s.has_texture() && textures == TextureLayout::kGroups ? kTextureGroups : 0) |
                               (s.has_texture() && textures == TextureLayout::kSharedStills ? kSharedTextures : 0)));
  w.write(uint8_t{0});
  w.write(static_cast<uint32_t>(s.keyframe_count()));
  w.write(s.fps);
  w.write(s.first_time);
  w.write(s.last_time);
  for (int k = 0; k < 3; ++k) w.write(s.pose_centre[k]);
  w.write(static_cast<uint32_t>(s.texture_size));
  w.write(static_cast<uint32_t>(shape.rim_count));
  w.write(static_cast<uint32_t>(fixed.size()));
  // As differences from the previous node (the first from 0): sorted nodes give small numbers,
  // which the header's zstd packs (Medusa-like noisy frames mark ~9% of the nodes).
  int32_t previous = 0;
  for (int32_t node : fixed) {
    w.write(static_cast<uint32_t>(node - previous));
    previous = node;
  }
  w.string(s.units);
  w.string(metadata.encoder.empty() ? std::string("facemorph ") + FACEMORPH_VERSION : metadata.encoder);
  w.string(metadata.settings);
  w.write(static_cast<uint32_t>(metadata.landmark_names.size()));
  for (const std::string& name : metadata.landmark_names) w.string(name);
  const FieldCoding& coding = metadata.field_coding;
  w.write(static_cast<uint32_t>(coding.intra_period));
  for (double step : coding.steps) w.write(step);
  w.write(coding.rotation_step);
  w.write(coding.translation_step);
  return w.take();
}

}  // namespace facemorph::file_layout
