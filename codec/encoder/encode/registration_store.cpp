#include "codec/encoder/encode/registration_store.hpp"

#include "format/error.hpp"

#include "codec/encoder/encode/spill_bytes.hpp"
#include "codec/encoder/registration/partition_map.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace facemorph {

namespace {

using spill::Reader;
using spill::Writer;

void write_step(Writer& w, const ThinPlateDisplacement& step) {
  w.array(step.centres);
  // Column-major, one column per coordinate: rows() doubles each.
  w.array(std::vector<double>(step.weights.data(), step.weights.data() + step.weights.size()));
  w.value(step.offset);
  w.value(step.linear);
}

ThinPlateDisplacement read_step(Reader& r) {
  ThinPlateDisplacement step;
  step.centres = r.array<Vec2>();
  const std::vector<double> weights = r.array<double>();
  if (weights.size() != 2 * step.centres.size())
    throw Error(ErrorCode::kInternal, "registration store: a thin-plate step's weights do not fit its centres");
  step.weights =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 2>>(weights.data(), static_cast<Eigen::Index>(step.centres.size()), 2);
  step.offset = r.value<Vec2>();
  step.linear = r.value<Eigen::Matrix2d>();
  return step;
}

// BijectionCheck holds only numbers: written field by field, so a field added to it must be added
// here too (the round-trip test compares them all).
void write_check(Writer& w, const BijectionCheck& c) {
  for (int v : {c.grid_points, c.refined_points, c.folded_points, c.boundary_samples, c.boundary_order_breaks, c.clamped_points})
    w.value(v);
  for (double v : {c.min_jacobian, c.min_area_ratio, c.max_boundary_radius_error}) w.value(v);
  w.value(c.worst_point);
  w.value(c.stopped);
}

BijectionCheck read_check(Reader& r) {
  BijectionCheck c;
  for (int* v : {&c.grid_points, &c.refined_points, &c.folded_points, &c.boundary_samples, &c.boundary_order_breaks, &c.clamped_points})
    *v = r.value<int>();
  for (double* v : {&c.min_jacobian, &c.min_area_ratio, &c.max_boundary_radius_error}) *v = r.value<double>();
  c.worst_point = r.value<Vec2>();
  c.stopped = r.value<bool>();
  return c;
}

}  // namespace

std::vector<char> RegistrationStore::serialize(const DiskRegistration& f) {
  Writer w;
  w.value(f.method);
  w.value(f.form);
  w.value(f.moebius.a);
  w.value(f.moebius.theta);
  w.value<uint64_t>(f.steps.size());
  for (const ThinPlateDisplacement& step : f.steps) write_step(w, step);
  for (double v : {f.energy_moebius, f.energy, f.smoothing}) w.value(v);
  w.value(f.moebius_iterations);
  w.value(f.moebius_start);
  w.value(f.fallback);
  w.text(f.fallback_reason);
  w.value(f.boundary_samples);
  write_check(w, f.check);
  w.value(f.partition_map != nullptr);
  if (f.partition_map) {
    w.array(f.partition_map->images);
    w.array(f.partition_map->jacobians);
  }
  return w.take();
}

DiskRegistration RegistrationStore::deserialize(const char* bytes, size_t size, const std::shared_ptr<const PartitionMesh>& partition,
                                                bool for_check) {
  Reader r(bytes, size, "registration store: a stored registration");
  DiskRegistration f;
  f.method = r.value<RegistrationMethod>();
  f.form = r.value<GmfForm>();
  f.moebius.a = r.value<Complex>();
  f.moebius.theta = r.value<double>();
  const auto steps = r.value<uint64_t>();
  if (steps > size) throw Error(ErrorCode::kInternal, "registration store: a stored registration is cut short");
  for (uint64_t k = 0; k < steps; ++k) f.steps.push_back(read_step(r));
  for (double* v : {&f.energy_moebius, &f.energy, &f.smoothing}) *v = r.value<double>();
  f.moebius_iterations = r.value<int>();
  f.moebius_start = r.value<MoebiusStart>();
  f.fallback = r.value<RegistrationFallback>();
  f.fallback_reason = r.text();
  f.boundary_samples = r.value<int>();
  f.check = read_check(r);
  if (r.value<bool>()) {
    if (!partition && !for_check)
      throw Error(ErrorCode::kInternal, "registration store: a stored registration through a partition, and no partition to attach it to");
    auto map = std::make_shared<PiecewiseAffineMap>();
    map->partition = partition;
    map->images = r.array<Vec2>();
    map->jacobians = r.array<Eigen::Matrix2d>();
    if (partition && (map->images.size() != partition->vertices().size() || map->jacobians.size() != partition->faces().size())) {
      throw Error(ErrorCode::kInternal, "registration store: a stored registration does not fit the partition");
    }
    f.partition_map = std::move(map);
  }
  if (!r.done()) throw Error(ErrorCode::kInternal, "registration store: a stored registration has bytes left over");
  return f;
}

namespace {

bool step_finite(const ThinPlateDisplacement& step) {
  return spill::all_finite(step.centres) && step.weights.allFinite() && step.offset.allFinite() && step.linear.allFinite();
}

}  // namespace

void RegistrationStore::check(const DiskRegistration& f) {
  const auto bad = [](const std::string& what) { throw Error(ErrorCode::kCorrupt, what); };
  const auto method = static_cast<int>(f.method), form = static_cast<int>(f.form), fallback = static_cast<int>(f.fallback),
             start = static_cast<int>(f.moebius_start);
  if (method < 0 || method > static_cast<int>(RegistrationMethod::kFrame) || form < 0 || form > static_cast<int>(GmfForm::kPaperGrid) ||
      fallback < 0 || fallback > static_cast<int>(RegistrationFallback::kSubsteps) || start < 0 ||
      start > static_cast<int>(MoebiusStart::kAlgebraic)) {
    bad("its registration names an unknown method");
  }
  if (!std::isfinite(f.moebius.a.real()) || !std::isfinite(f.moebius.a.imag()) || !(std::abs(f.moebius.a) < 1) ||
      !std::isfinite(f.moebius.theta)) {
    bad("its registration's Möbius map is not one of the disk");
  }
  if (!std::all_of(f.steps.begin(), f.steps.end(), step_finite)) bad("its registration has a number not finite");
  if (f.partition_map && (!spill::all_finite(f.partition_map->images) || !spill::all_finite(f.partition_map->jacobians)))
    bad("its registration has a number not finite");
}

RegistrationStore::RegistrationStore(SpillMode mode)
    : items_(mode, "the frames' registrations", "registration store: frame", &RegistrationStore::serialize,
             [this](const char* bytes, size_t size) { return deserialize(bytes, size, partition_); }) {}

void RegistrationStore::reset(size_t count, std::shared_ptr<const PartitionMesh> partition) {
  items_.reset(count);
  partition_ = std::move(partition);
}

void RegistrationStore::put(size_t i, DiskRegistration&& registration) {
  if (registration.partition_map && registration.partition_map->partition != partition_) {
    throw Error(ErrorCode::kInternal, "registration store: a registration through another partition than the store's");
  }
  items_.put(i, std::move(registration));
}

}  // namespace facemorph
