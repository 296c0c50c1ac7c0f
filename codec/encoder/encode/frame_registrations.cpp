// The register stage's state: the registrations' store and the reference's geometry
// (frame_registrations.hpp).
#include "codec/encoder/encode/frame_registrations.hpp"

#include "codec/core/util/parallel.hpp"
#include "format/error.hpp"

namespace facemorph {

void FrameRegistrations::start(size_t count, SpillMode mode) {
  store_ = std::make_unique<RegistrationStore>(mode);
  store_->reset(count, partition());
}

std::shared_ptr<const DiskRegistration> FrameRegistrations::registration(int i) const {
  if (!store_) throw Error(ErrorCode::kInternal, "the frames are not registered yet");
  return store_->get(static_cast<size_t>(i));
}

std::vector<Vec2> FrameRegistrations::sample_points(int i, std::span<const Vec2> nodes, int threads) const {
  std::vector<Vec2> points = reparametrisation_(nodes);
  const std::shared_ptr<const DiskRegistration> f = registration(i);
  parallel_runs(points.size(), threads,
                [&](size_t, size_t first, size_t last) { f->map_points(std::span<Vec2>(points).subspan(first, last - first), nullptr); });
  return points;
}

void FrameRegistrations::set_reference(DiskReparametrisation reparametrisation, std::shared_ptr<const GeodesicFrame> geodesic_frame) {
  reparametrisation_ = std::move(reparametrisation);
  geodesic_frame_ = std::move(geodesic_frame);
}

void FrameRegistrations::keep(const std::vector<size_t>& kept, size_t before) {
  if (without_interior.size() == before) {
    std::vector<char> out;
    out.reserve(kept.size());
    for (size_t i : kept) out.push_back(without_interior[i]);
    without_interior = std::move(out);
  }
  if (store_ && store_->size() == before) store_->keep(kept);
}

}  // namespace facemorph
