// Where the encoder keeps every frame's registration between stages (spec/method.md §7.15).
//
// Every stage after registering samples each frame through its registration (the selection grid,
// the keyframe fit on G, the keyframes' textures), so each frame's map f stays needed until the
// encode ends. Its thin-plate field holds every landmark and boundary sample as a centre: 4.6 kB a
// frame on ICT (74 landmarks), the largest thing the encoder still kept per frame (0.5 GB for an
// hour at 30 fps). Spilled, each registration goes to a temporary file as it is made and is read
// back (a few kB) by the stage that samples its frame, which holds it while it samples.
#pragma once

#include "codec/encoder/encode/spill_file.hpp"
#include "codec/encoder/registration/registration.hpp"

#include <cstdint>
#include <memory>
#include <vector>

namespace facemorph {

class RegistrationStore {
 public:
  explicit RegistrationStore(SpillMode mode);
  RegistrationStore(const RegistrationStore&) = delete;
  RegistrationStore& operator=(const RegistrationStore&) = delete;

  // Forgets every registration and makes room for `count` (not while put or get run on other
  // threads: the partition is read without a lock). `partition`: the geodesic frame's
  // partition that registrations through it (method kFrame) share, null for other methods; Φ's
  // tables are stored without it and re-attached to it when read back.
  void reset(size_t count, std::shared_ptr<const PartitionMesh> partition);
  size_t size() const { return items_.size(); }
  // Stores frame i's registration (i < size()); thread-safe for different i. Throws kIo when the
  // temporary file cannot be written, kInternal for a Φ on another partition than reset's.
  void put(size_t i, DiskRegistration&& registration);
  // Frame i's registration: read back from the file, or the one in memory. Thread-safe. Throws
  // kInternal for a frame never stored, kIo on a failed read.
  std::shared_ptr<const DiskRegistration> get(size_t i) const { return items_.get(i); }
  // Keeps the registrations at indices `kept` (increasing), renumbered 0.. in that order.
  void keep(const std::vector<size_t>& kept) { items_.keep(kept); }
  uint64_t spilled_bytes() const { return items_.spilled_bytes(); }  // the file's size (0 in memory)

  // The byte form of a registration (its Φ without the partition): what put writes and get reads.
  // Public for the round-trip test: every field and the map at every point come back the same.
  static std::vector<char> serialize(const DiskRegistration& registration);
  // for_check: a registration through a partition may come without it, its Φ unattached (not to
  // be evaluated: to be checked, check below, before the partition is there).
  static DiskRegistration deserialize(const char* bytes, size_t size, const std::shared_ptr<const PartitionMesh>& partition,
                                      bool for_check = false);
  // Throws kCorrupt where a registration read from a file (a part file, spec/part-file.md) is not
  // one the encoder could have made: an unknown method, a Möbius map off the disk, a number not finite.
  static void check(const DiskRegistration& registration);

 private:
  std::shared_ptr<const PartitionMesh> partition_;
  SpilledItems<DiskRegistration> items_;
};

}  // namespace facemorph
