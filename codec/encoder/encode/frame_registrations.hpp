// The register stage's state (stages/register_frames.cpp): every frame's registration to the
// reference in its store, the reference's disk reparametrised and (method kFrame) its geodesic
// frame, and which frames were registered without interior landmarks shared with the reference.
// Every later stage samples a frame through it (sample_points).
#pragma once

#include "codec/encoder/density/density_equalising.hpp"
#include "codec/encoder/encode/registration_store.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <memory>
#include <span>
#include <utility>
#include <vector>

namespace facemorph {

class FrameRegistrations {
 public:
  // Forgets every registration, making room for `count` in a store of `mode` whose registrations
  // through a geodesic frame share the one set_reference gave (so: set_reference first).
  void start(size_t count, SpillMode mode);
  bool started() const { return store_ != nullptr; }
  size_t size() const { return store_ ? store_->size() : 0; }
  // Stores frame i's registration (RegistrationStore::put); thread-safe for different i.
  void put(size_t i, DiskRegistration&& registration) { store_->put(i, std::move(registration)); }
  // Frame i's registration, read back from its store and held as long as the pointer is.
  // kInternal before start ("the frames are not registered yet").
  std::shared_ptr<const DiskRegistration> registration(int i) const;
  // Where frame i is sampled for disk points of G: the reference's reparametrisation, then the
  // frame's registration, the points on up to `threads` threads (0: one per hardware thread; the
  // same points on any number, each a function of its node alone).
  std::vector<Vec2> sample_points(int i, std::span<const Vec2> nodes, int threads = 1) const;
  // The reference's geometry every frame is registered and sampled through: its disk
  // reparametrised, its geodesic frame (null but for method kFrame).
  void set_reference(DiskReparametrisation reparametrisation, std::shared_ptr<const GeodesicFrame> geodesic_frame);
  const DiskReparametrisation& reparametrisation() const { return reparametrisation_; }
  // The reference's disk reparametrised otherwise, its geodesic frame kept: the registrations map the
  // conformal disks, so a map of the reference's disk onto itself can be swapped after them
  // (the density-equalised disk chosen by bytes, density_candidate.hpp).
  void set_reparametrisation(DiskReparametrisation reparametrisation) { reparametrisation_ = std::move(reparametrisation); }
  const GeodesicFrame* geodesic_frame() const { return geodesic_frame_.get(); }
  // The partition the registrations through the geodesic frame share (null without one).
  std::shared_ptr<const PartitionMesh> partition() const { return geodesic_frame_ ? geodesic_frame_->partition : nullptr; }
  // Keeps the frames at indices `kept` (increasing) of the `before` frames, renumbered 0.. in that
  // order; parts not made for `before` frames stay as they are.
  void keep(const std::vector<size_t>& kept, size_t before);

  std::vector<char> without_interior;  // per frame: registered without interior landmarks shared with the reference

 private:
  std::unique_ptr<RegistrationStore> store_;
  std::shared_ptr<const GeodesicFrame> geodesic_frame_;
  DiskReparametrisation reparametrisation_;
};

}  // namespace facemorph
