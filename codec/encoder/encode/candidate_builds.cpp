// The keyframes of the choice by bytes at equal error, built once per N (candidate_builds.hpp).
#include "codec/encoder/encode/candidate_builds.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/util/elapsed.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"

#include <algorithm>
#include <optional>

namespace facemorph {

std::unique_ptr<StoredSequence> CandidateBuilds::copy(const StoredSequence& from, const KeyframeSurfaces& surfaces,
                                                      Representation representation) const {
  Sequence shape = from.shape();
  const bool same = shape.representation == representation;
  shape.representation = representation;
  // G's geometry only where the fields are made anew (as build_keyframes makes them).
  std::shared_ptr<const GridGeometry> geometry;
  if (!same) geometry = shared_grid_geometry(shape.grid_n);
  auto out = std::make_unique<StoredSequence>(std::move(shape), mode_);
  parallel_for(static_cast<int>(from.size()), threads_, [&](int i) {
    const auto k = static_cast<size_t>(i);
    out->put_hole_level(k, std::vector<double>(*from.hole_level(k)));
    out->put_texture(k, Image(*from.texture(k)));
    out->put_fields(k, same ? GridFields(*from.fields(k)) : keyframe_fields(*geometry, *surfaces.surfaces->get(k), representation, surfaces.fixed));
  });
  return out;
}

void CandidateBuilds::keep(const StoredSequence& built, KeyframeSurfaces surfaces, const EncodeReport& report) {
  Kept k;
  k.sequence = copy(built, surfaces, built.shape().representation);
  k.texture_size = report.texture_size;
  k.folds = report.keyframe_folds;
  k.peak_held = surfaces.surfaces->peak_held();
  k.spilled_bytes = surfaces.surfaces->spilled_bytes();
  k.surfaces = std::move(surfaces);
  kept_[built.shape().grid_n] = std::move(k);
}

std::unique_ptr<StoredSequence> CandidateBuilds::get(Representation representation, int n,
                                                     const std::function<std::unique_ptr<StoredSequence>(KeyframeSurfaces*)>& build,
                                                     EncodeReport& report) {
  const auto at = kept_.find(n);
  if (at == kept_.end()) {
    KeyframeSurfaces surfaces;
    std::unique_ptr<StoredSequence> built = build(&surfaces);
    keep(*built, std::move(surfaces), report);
    return built;
  }
  const auto start = std::chrono::steady_clock::now();
  const Kept& k = at->second;
  std::unique_ptr<StoredSequence> made = copy(*k.sequence, k.surfaces, representation);
  // The report as the build would have left it (build_keyframes' figures).
  report.texture_size = k.texture_size;
  report.keyframe_folds = k.folds;
  report.peak_keyframes_in_memory = std::max(report.peak_keyframes_in_memory, k.peak_held);
  report.keyframes_spilled_bytes += k.spilled_bytes;
  report.seconds_keyframes = seconds_since(start);
  return made;
}

}  // namespace facemorph
