#include "codec/encoder/encode/field_precision.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/geometry_trial_source.hpp"
#include "codec/encoder/encode/keyframe_store.hpp"
#include "codec/encoder/encode/reconstructor_pool.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>

namespace facemorph {

namespace {

// The groups of scalar_arrays that share a step: H; log λ; a and b; the band vectors; positions;
// the boundary curve. (The hole level, array 13, does not move the surface.)
const std::vector<std::vector<size_t>> kGroups = {{0}, {1}, {2, 3}, {4, 5, 6}, {7, 8, 9}, {10, 11, 12}};
constexpr size_t kFirstPosition = 7;  // scalar_arrays' order: H, log λ, a, b, the band (3), positions (3), the rim (3)
constexpr double kHoleStepPerCell = 1.0 / 16.0;
constexpr double kTolerance = 1.25;  // a keyframe may exceed the target by this factor before steps shrink
constexpr int kMaxRefinements = 8;
constexpr int kCalibrationProbes = 5;   // a group's probes of keyframe 0 at most (choose_steps)
constexpr double kFitContradicted = 4;  // a fit this far under a step that met its share is not kept (calibrated_step)

ReconstructOptions tight() {
  ReconstructOptions o;
  o.tolerance = 1e-8;  // far under the errors measured (1e-5 .. 1e-3 of the diagonal)
  o.max_iterations = 400;
  return o;
}

double diagonal(const std::vector<Vec3>& points) {
  Vec3 lo = points.front(), hi = points.front();
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).norm();
}

double rms_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]).squaredNorm();
  return std::sqrt(sum / static_cast<double>(a.size()));
}

// The keyframe's surface decoded from its exact fields, and from them rounded to `steps`
// (starting there: the two differ by the rounding only).
struct Decoded {
  std::vector<Vec3> exact;
  double diagonal = 0;
};

Decoded decode_exact(Reconstructor& reconstructor, const GridFields& fields) {
  Decoded d;
  d.exact = decode_keyframe_exactly(reconstructor, fields);
  d.diagonal = diagonal(d.exact);
  return d;
}

void check_dead_zone(double inter_dead_zone) {
  if (!(inter_dead_zone >= 0.5 && inter_dead_zone < 1)) {
    throw Error(ErrorCode::kInvalidArgument, "field precision: the inter dead zone must lie in [0.5, 1) steps");
  }
}

std::vector<Vec3> decode_rounded(Reconstructor& reconstructor, const GridFields& rounded, const std::vector<Vec3>& exact) {
  ReconstructOptions o = tight();
  o.start = &exact;
  return reconstructor.reconstruct(rounded, o).positions;
}

double decoded_error(Reconstructor& reconstructor, const GridFields& rounded, const std::vector<Vec3>& exact, double exact_diagonal) {
  return rms_distance(decode_rounded(reconstructor, rounded, exact), exact) / exact_diagonal;
}

// A rounded keyframe's decoded error: the RMS displacement of its nodes and the 99th percentile of
// its rounding (fractions of the diagonal).
struct RoundedError {
  double rms = 0;
  double p99 = 0;
};

// The rounding's 99th percentile as the grid's decoded floor reads it (surface_distance: every
// vertex of both meshes to the other surface), measured where it could pass `budget`. A vertex's
// distance to the other surface is at most its node's displacement (the other node lies on that
// surface), so the displacements' p99 bounds it from above and is returned where it is within the
// budget: the point-to-surface measure is taken only where the bound may bind.
RoundedError rounded_error(Reconstructor& reconstructor, const GridFields& rounded, const std::vector<Vec3>& exact, double exact_diagonal,
                           double budget) {
  const std::vector<Vec3> positions = decode_rounded(reconstructor, rounded, exact);
  RoundedError e{.rms = rms_distance(positions, exact) / exact_diagonal};
  if (!std::isfinite(budget)) return e;
  std::vector<double> displacement(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) displacement[i] = (positions[i] - exact[i]).norm();
  e.p99 = nearest_rank_p99(displacement) / exact_diagonal;
  if (e.p99 > budget) {
    const DiskGrid& grid = reconstructor.geometry().grid();
    e.p99 = surface_distance(grid_mesh(grid, exact), grid_mesh(grid, positions)).p99 / exact_diagonal;
  }
  return e;
}

// Where one choose_field_coding keeps its keyframes' arrays (keyframe_store.hpp): the stores' mode,
// one count for all of them, and the bytes they wrote.
struct Spill {
  explicit Spill(bool spill) : mode(spill ? SurfaceStore::Mode::kSpill : SurfaceStore::Mode::kMemory) {}
  SurfaceStore::Mode mode;
  std::shared_ptr<ResidentCount> count = std::make_shared<ResidentCount>();
  uint64_t bytes = 0;
};

// A pointer-like view of what a getter returns: a plain pointer or shared_ptr as it is.
inline const GridFields* as_pointer(const GridFields* p) { return p; }
inline const std::shared_ptr<const GridFields>& as_pointer(const std::shared_ptr<const GridFields>& p) { return p; }

// Rounds arrays to multiples of their steps. Per-node arrays on G's interior are rounded with error
// diffusion (Floyd–Steinberg over the lattice, in node order): each node's rounding error is
// passed on to the neighbours not yet rounded, so the error left is high-pass. The reconstruction
// integrates the fields twice (Δ⁻¹ damps a wave of k cycles by 1/k²), so high-pass error barely
// moves the surface, and the same decoded error allows far larger steps than plain rounding.
// Only the encoder's choice of integers changes; the decoder reads integers as before.
//
// An inter keyframe (one the file codes as its change from the previous keyframe) rounds that
// change instead, with a dead zone: a value keeps the previous keyframe's code unless it moved by
// more than `dead_zone` steps (0.5: plain rounding, which gives the same codes as rounding the
// keyframe alone, since the previous codes are whole steps). A kept code is a zero in the file, its
// cheapest symbol; error diffusion carries what the dead zone leaves to the next nodes, so it stays
// high-pass.
class FieldRounder {
 public:
  FieldRounder(const DiskGrid& grid, bool shaped, double dead_zone) : grid_(grid), shaped_(shaped), dead_zone_(dead_zone) {}

  // Array `array`'s `values` (scalar_arrays' order) to multiples of `step`; with `previous` (the
  // previous keyframe's rounded values), their change from it, through the dead zone.
  void round(size_t array, std::vector<double>& values, double step, const std::vector<double>* previous = nullptr) const {
    const bool shaped = shaped_ && !is_position(array);
    if (previous) {
      for (size_t n = 0; n < values.size(); ++n) values[n] -= (*previous)[n];
    }
    const double zone = previous ? dead_zone_ * step : 0;
    const auto quantise = [&](double x) { return std::abs(x) < zone ? 0.0 : step * std::nearbyint(x / step); };
    if (!shaped || values.size() != static_cast<size_t>(grid_.interior_count)) {
      for (double& v : values) v = quantise(v);
    } else {
      diffuse(values, quantise);
    }
    if (previous) {
      // Back to values, snapped to exact multiples (a sum may miss one by an ulp).
      for (size_t n = 0; n < values.size(); ++n) values[n] = step * std::nearbyint((values[n] + (*previous)[n]) / step);
    }
  }

  GridFields rounded(const GridFields& fields, const std::vector<size_t>& which, const std::vector<double>& steps) const {
    std::vector<std::vector<double>> arrays = scalar_arrays(fields);
    for (size_t a : which) round(a, arrays[a], steps[a]);
    return fields_from_scalar_arrays(fields.representation, fields.grid_n, fields.fixed_nodes, arrays);
  }

  // Every keyframe's fields as the file will hold them, in order, handed to use(k, fields): those
  // the file may predict from the previous keyframe (not a multiple of the intra period) rounded as
  // their change from it. One keyframe's at a time (a long capture has hundreds): the rounding
  // carries only the previous keyframe's rounded arrays (Chain). `exact(k)` gives keyframe k's exact
  // fields (a GridFields, or a pointer to one).
  template <typename Exact, typename Use>
  void for_each_rounded(size_t count, const Exact& exact, const FieldCoding& coding, const Use& use) const {
    Chain chain(*this, coding);
    for (size_t k = 0; k < count; ++k) {
      GridFields rounded = chain.next(k, *as_pointer(exact(k)));  // the exact fields released before use
      use(k, std::move(rounded));
    }
  }

  // The rounding of keyframes one after another: keyframe k's rounded fields from its exact ones,
  // given after keyframe k − 1's unless k is intra (where the chain starts again).
  class Chain {
   public:
    Chain(const FieldRounder& rounder, const FieldCoding& coding) : rounder_(rounder), coding_(coding) {}
    GridFields next(size_t k, const GridFields& fields) {
      const bool intra = coding_.intra(k);
      if (!intra && (before_.empty() || k != last_ + 1))
        throw Error(ErrorCode::kInternal, "field rounding: keyframe " + std::to_string(k) + " out of order");
      std::vector<std::vector<double>> arrays = scalar_arrays(fields);
      for (size_t a = 0; a < arrays.size(); ++a) rounder_.round(a, arrays[a], coding_.steps[a], intra ? nullptr : &before_[a]);
      GridFields out = fields_from_scalar_arrays(fields.representation, fields.grid_n, fields.fixed_nodes, arrays);
      before_ = std::move(arrays);
      last_ = k;
      return out;
    }

   private:
    const FieldRounder& rounder_;
    const FieldCoding& coding_;
    std::vector<std::vector<double>> before_;  // the previous keyframe's rounded arrays
    size_t last_ = 0;
  };

  // The keyframes as the file will hold them: their fields as above, and the hole level. Keyframe
  // k's exact fields are not read again once k is rounded, so each is replaced in place.
  void round(std::vector<Keyframe>& keyframes, const FieldCoding& coding) const {
    for_each_rounded(
        keyframes.size(), [&](size_t k) { return &keyframes[k].fields; }, coding,
        [&](size_t k, GridFields&& fields) {
          keyframes[k].fields = std::move(fields);
          round_to_field_steps(keyframes[k], coding);
        });
  }

 private:
  // Positions (xyz) are decoded as stored, not integrated: no reconstruction smooths their
  // rounding away, and error diffusion leaves each node a larger error than plain rounding does
  // (its own rounding plus what its neighbours passed on) and the codes a high-pass texture the
  // spatial predictors cannot follow. Measured at the same target, diffusion cost ICT 9.4k 40% more
  // bytes for a held-out error no better (spec/method.md §7.20.2), so each position is rounded alone.
  static bool is_position(size_t array) { return array >= kFirstPosition && array < kFirstPosition + 3; }

  template <typename Quantise>
  void diffuse(std::vector<double>& values, const Quantise& quantise) const {
    std::vector<double> carried(values.size(), 0.0);
    constexpr std::array<std::array<int, 3>, 4> kSpread = {{{1, 0, 7}, {-1, 1, 3}, {0, 1, 5}, {1, 1, 1}}};  // (di, dj, sixteenths)
    for (size_t n = 0; n < values.size(); ++n) {
      const double wanted = values[n] + carried[n];
      const double rounded = quantise(wanted);
      const double error = wanted - rounded;
      values[n] = rounded;
      const auto [i, j] = grid_.cell[n];
      // Weights of the neighbours that exist renormalised, so the rim loses no error to outside G.
      double weight = 0;
      for (const auto& [di, dj, w] : kSpread) weight += grid_.node(i + di, j + dj) >= 0 ? w : 0;
      if (weight == 0) continue;
      for (const auto& [di, dj, w] : kSpread) {
        const int32_t m = grid_.node(i + di, j + dj);
        if (m >= 0) carried[static_cast<size_t>(m)] += error * w / weight;
      }
    }
  }

  const DiskGrid& grid_;  // the reconstructor's
  bool shaped_;
  double dead_zone_;
};

// Every keyframe's surface decoded from its exact fields, what every trial's rounded keyframes are
// compared with: decoded once per choose_field_coding (they do not depend on the steps or the dead
// zone), stored (1.25 MB a keyframe at N = 257) and read back one at a time.
struct ExactSurfaces {
  ExactSurfaces(const StoredSequence& keys, ReconstructorPool& pool, Spill& spill) : store(spill.mode, spill.count) {
    store.reset(keys.size());
    diagonals.assign(keys.size(), 0.0);
    failures.assign(keys.size(), nullptr);
    pool.run(keys.size(), [&](Reconstructor& reconstructor, size_t k) {
      Decoded d;
      try {
        d = decode_exact(reconstructor, *keys.fields(k));
      } catch (const Error& e) {
        // Named, so that the encoder can say which keyframe did not reconstruct (encode_sampled);
        // kept for rethrow_failures, which throws them in the order the encode meets them.
        failures[k] = std::make_exception_ptr(Error(e.code(), "keyframe " + std::to_string(k) + ": " + e.what()));
        return;
      }
      diagonals[k] = d.diagonal;
      store.put(k, std::move(d.exact));
    });
  }
  // Rethrows the failure of the lowest keyframe in [first, last) that did not decode, if any.
  void rethrow_failures(size_t first, size_t last) const {
    for (size_t k = first; k < last && k < failures.size(); ++k) {
      if (failures[k]) std::rethrow_exception(failures[k]);
    }
  }
  SurfaceStore store;
  std::vector<double> diagonals;
  std::vector<std::exception_ptr> failures;  // per keyframe: why its exact decode failed (null: it did not)
};

// The intra keyframes' decoded errors by the steps' scale, within one choose_field_coding: no dead
// zone applies to an intra keyframe (its rounding has no previous keyframe), so every dead zone's
// search measures the same errors at the scales they share (the first, 1, at least), decoded once.
struct IntraErrors {
  size_t intra_period = 1;
  std::map<std::pair<size_t, double>, RoundedError> by_keyframe_and_scale;
};

// Each keyframe's decoded error with `coding`: rounded in order on this thread (a keyframe's
// rounding carries the previous one's codes), then decoded a batch of the pool's size at a time, so
// that no more rounded fields than threads are held.
// With a finite `p99_budget`, each keyframe's rounding p99 too (rounded_error); else those are 0.
// `p99_budgets`: each keyframe's (empty: none bounded). `intra` (with the steps' `scale`): the
// intra keyframes' errors taken from it where measured at that scale, and kept in it.
std::vector<RoundedError> rounded_errors(const StoredSequence& keys, const FieldCoding& coding, const FieldRounder& rounder,
                                         const ExactSurfaces& exact, ReconstructorPool& pool, const std::vector<double>& p99_budgets = {},
                                         IntraErrors* intra = nullptr, double scale = 0) {
  std::vector<RoundedError> errors(keys.size());
  std::vector<std::pair<size_t, GridFields>> batch;
  const auto is_intra = [&](size_t k) { return intra && k % intra->intra_period == 0; };
  const auto decode_batch = [&] {
    pool.run(batch.size(), [&](Reconstructor& reconstructor, size_t i) {
      const auto& [k, rounded] = batch[i];
      const double budget = p99_budgets.empty() ? std::numeric_limits<double>::infinity() : p99_budgets[k];
      errors[k] = rounded_error(reconstructor, rounded, *exact.store.get(k), exact.diagonals[k], budget);
    });
    for (const auto& [k, rounded] : batch) {
      if (is_intra(k)) intra->by_keyframe_and_scale.emplace(std::pair(k, scale), errors[k]);
    }
    batch.clear();
  };
  rounder.for_each_rounded(
      keys.size(), [&](size_t k) { return keys.fields(k); }, coding,
      [&](size_t k, GridFields&& rounded) {
        if (is_intra(k)) {
          const auto measured = intra->by_keyframe_and_scale.find(std::pair(k, scale));
          if (measured != intra->by_keyframe_and_scale.end()) {
            errors[k] = measured->second;
            return;
          }
        }
        batch.emplace_back(k, std::move(rounded));
        if (batch.size() == pool.size()) decode_batch();
      });
  decode_batch();
  return errors;
}

}  // namespace

std::vector<Vec3> decode_keyframe_exactly(Reconstructor& reconstructor, const GridFields& fields) {
  reconstructor.forget_warm_start();
  return reconstructor.reconstruct(fields, tight()).positions;
}

void round_keyframes(Sequence& sequence, const FieldCoding& coding, const FieldPrecisionOptions& options) {
  check_dead_zone(options.inter_dead_zone);
  validate_sequence(sequence);
  const DiskGrid grid = make_disk_grid(sequence.grid_n);
  FieldRounder(grid, options.noise_shaping, options.inter_dead_zone).round(sequence.keyframes, coding);
}

int auto_intra_period(const Sequence& sequence) {
  const std::vector<Keyframe>& keys = sequence.keyframes;
  if (keys.size() < 2) return 1;
  const double interval = (keys.back().time - keys.front().time) / static_cast<double>(keys.size() - 1);
  return static_cast<int>(std::clamp(std::floor(kAutoIntraSeconds / interval), 1.0, static_cast<double>(keys.size())));
}

// The step at which rounding one group alone (the rest exact) displaces keyframe 0 by its share.
// The error is not proportional to the step (ICT's curvature: ∝ step^1.9 near its share), it is
// noisy (error diffusion reshuffles every code when the step moves: ±30% between steps 10% apart),
// and far under the share it is the reconstruction's own numerical noise (ICT: a first probe at a
// 4096th of the spread read 2.6e-6 or 1.2e-6 for inputs 1e-5 apart, so the one linear step taken
// from it gave steps 2x apart and files 15-25% apart at the same error). So the group is probed up
// to five times, each probe at the step where the power law fitted (least squares in log-log)
// through the readings above an eighth of the share meets the share, and the step is that fit's at
// the end; the verification in choose_steps sets the common scale.
// Where the last fit lands more than 4x under a probed step that met the share, that step is kept
// instead: the readings say the error rises with the step, so such a fit contradicts them. Two
// readings at nearly one step fit any exponent (ICT at T = 0.2%: log λ read 0.0112 at 0.671 and
// 0.0125 at 0.657; the exponent, clamped to 0.5, sent the fit to 0.0045, 100x under its share,
// though 0.0585 had read 0.09 of it): that step was 50x finer than at T = 0.16%, a 96 kB file
// against 55 kB (spec/method.md §7.21.1). Not every step under the met one: the fit's ordinary
// noise (±30% between steps 10% apart) lands a little under it, and keeping the met step there
// moved the defaults' files by that noise (the sample +3.6%, fast speech +5.7%).
double calibrated_step(const std::function<double(double)>& error_at, double share, double spread) {
  std::vector<std::pair<double, double>> readings;  // (log step, log error) above the floor
  auto fitted_step = [&](double step, double error) {
    if (readings.size() < 2) return error > 0 ? std::min(step * share / error, spread) : spread;
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const auto& [x, y] : readings) sx += x, sy += y, sxx += x * x, sxy += x * y;
    const double n = static_cast<double>(readings.size()), spread_x = sxx - sx * sx / n;
    const double exponent = spread_x > 1e-12 ? std::clamp((sxy - sx * sy / n) / spread_x, 0.5, 4.0) : 1.0;
    const double intercept = (sy - exponent * sx) / n;
    return std::min(std::exp((std::log(share) - intercept) / exponent), spread);
  };
  double met = 0;  // the coarsest step probed whose error met the share
  double step = spread / 4096;
  for (int probe = 0; probe < kCalibrationProbes; ++probe) {
    const double error = error_at(step);
    if (error <= share) met = std::max(met, step);
    if (error > share / 8) readings.emplace_back(std::log(step), std::log(error));
    const double next = fitted_step(step, error);
    if (next == step) break;  // at the spread: coarser steps are not tried
    step = next;
  }
  return step * kFitContradicted < met ? met : step;
}

namespace {

// Each group's step before the common scale: keyframe 0 rounded one group at a time. The same for
// every dead zone (keyframe 0 is intra: no dead zone applies to it), so choose_field_coding
// calibrates once for all its trials.
struct Calibration {
  std::vector<size_t> present;      // the groups the fields have
  std::vector<double> group_steps;  // per group (0: absent)
};

// The groups are calibrated each on a reconstructor of `pool` (their probes are independent: each
// rounds its own group and decodes from the exact surface, so any reconstructor gives the same
// readings), from the probe's exact surface as ExactSurfaces decoded it (with its diagonal).
Calibration calibrate(const GridFields& probe_fields, const std::vector<Vec3>& probe_exact, double probe_diagonal, double target_error,
                      bool noise_shaping, ReconstructorPool& pool) {
  const FieldRounder rounder(pool.grid(), noise_shaping, 0.5);
  const std::vector<std::vector<double>> arrays = scalar_arrays(probe_fields);
  Calibration calibration;
  std::vector<size_t>& present = calibration.present;
  for (size_t g = 0; g < kGroups.size(); ++g) {
    for (size_t a : kGroups[g]) {
      if (!arrays[a].empty()) {
        present.push_back(g);
        break;
      }
    }
  }
  // The budget's split: rounding a group of n values with step s costs about n (h - log2 s) bits
  // and displaces the surface by e = c s, so the fewest bits for a total error sqrt(Σ e²) = T come
  // with e_g² ∝ n_g (equal slopes): a group's share of the squared error is its share of the values.
  size_t values = 0;
  std::vector<size_t> group_values(kGroups.size(), 0);
  for (size_t g : present) {
    for (size_t a : kGroups[g]) group_values[g] += arrays[a].size();
    values += group_values[g];
  }
  std::vector<double>& group_steps = calibration.group_steps;
  group_steps.assign(kGroups.size(), 0.0);
  auto probe_error = [&](Reconstructor& reconstructor, size_t g, double step) {
    return decoded_error(reconstructor, rounder.rounded(probe_fields, kGroups[g], std::vector<double>(kKeyframeArrayCount, step)),
                         probe_exact, probe_diagonal);
  };
  pool.run(present.size(), [&](Reconstructor& reconstructor, size_t i) {
    const size_t g = present[i];
    const double share = target_error * std::sqrt(static_cast<double>(group_values[g]) / static_cast<double>(values));
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t a : kGroups[g]) {
      for (double v : arrays[a]) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
    const double spread = std::max(hi - lo, 1e-300);
    group_steps[g] = calibrated_step([&](double step) { return probe_error(reconstructor, g, step); }, share, spread);
  });
  return calibration;
}

// The steps choose_steps found, and what they measured.
struct StepChoice {
  FieldCoding coding;          // the steps at the coarsest scale that met the target
  double scale = 0;            // that scale of the calibration's steps
  std::vector<double> errors;  // each keyframe's decoded error at it
  std::vector<double> p99s;    // each keyframe's rounding p99 at it (empty: not bounded)
  int refinements = 0;
  int worst_region_refusals = 0;  // scales whose rounding p99 passed the budget
};

// The rounding's p99 budget (spec/method.md §5.3): what the worst-region target leaves the
// decoded floor, added linearly (spec/method.md §5.3: measured, quadrature let Medusa's frame 181
// through at 1.185%); infinite (not bounded) without a floor or with one at the target.
double rounding_p99_budget(const FieldPrecisionOptions& options) {
  if (!options.worst_floor || !(*options.worst_floor < options.worst_target)) return std::numeric_limits<double>::infinity();
  return options.worst_target - *options.worst_floor;
}

// Each of `count` keyframes' budget: the reference's (`budget`) where its own floor is no larger,
// what the target leaves its own floor where that is larger, infinite (not bounded) where its own
// floor is at or over the target. All `budget` without keyframe floors or without a bound.
std::vector<double> keyframe_p99_budgets(const FieldPrecisionOptions& options, double budget, size_t count) {
  std::vector<double> budgets(count, budget);
  if (!std::isfinite(budget) || options.keyframe_floors.empty()) return budgets;
  for (size_t k = 0; k < count; ++k) {
    const double floor = options.keyframe_floors[k];
    if (floor <= *options.worst_floor) continue;
    budgets[k] = floor < options.worst_target ? options.worst_target - floor : std::numeric_limits<double>::infinity();
  }
  return budgets;
}

// choose_field_coding's steps for one dead zone (the rounder's), from the calibration's steps, for
// the exact fields of `keys` (not changed: the caller rounds them), to meet `target_error` with
// keyframes intra every `intra_period` (resolved: not kAutoIntraPeriod), every keyframe's rounding
// p99 within its own of `budgets` (keyframe_p99_budgets: `p99_budget`, the reference's, or smaller;
// infinite: not bounded).
StepChoice choose_steps(const StoredSequence& keys, double target_error, double p99_budget, const std::vector<double>& budgets,
                        int intra_period, const FieldRounder& rounder, const Calibration& calibration, const ExactSurfaces& exact,
                        ReconstructorPool& pool, IntraErrors* intra = nullptr) {
  const Sequence& sequence = keys.shape();
  FieldCoding coding;
  coding.intra_period = intra_period;
  coding.steps.assign(kKeyframeArrayCount, 1.0);
  coding.steps[kScalarArrayCount] = kHoleStepPerCell * 2.0 / (sequence.grid_n - 1);  // of G's spacing
  set_default_pose_steps(coding, sequence.units);
  const std::vector<size_t>& present = calibration.present;
  const std::vector<double>& group_steps = calibration.group_steps;
  auto apply = [&](double scale) {
    for (size_t g : present) {
      for (size_t a : kGroups[g]) coding.steps[a] = group_steps[g] * scale;
    }
  };

  // Verify on every keyframe and rescale every step until the worst keyframe lies within
  // [0.8, 1.25] of the target (the calibration's linear model is only a model); keep the coarsest
  // scale that met the target. The error is not linear in the scale far from the probe (measured on a
  // noisy capture: 8x the scale, 50x the error, where error diffusion stops hiding the steps), so the
  // next scale follows the power law through the last two measurements, kept inside the bracket
  // of scales known to meet and to miss the target.
  // The worst region's budget is a bound, not a target (no tolerance over it): a scale whose worst
  // rounding p99 passes it misses, the next scale aims at 0.95 of it, and once it has refused a
  // scale, a scale that meets both within 0.8 of the budget is done (coarser ones would pass it).
  // Where it never refuses a scale, the search is the RMS target's alone, step for step.
  // A keyframe with a smaller budget of its own is read in the reference's budget's units (its p99
  // times p99_budget / its budget: exactly its p99 where the budgets are equal, so that the search is
  // the one every keyframe held to the reference's floor made), and one not bounded is measured as
  // the others, its p99 reported, but read as 0.
  const bool bounded = std::isfinite(p99_budget);
  const double aim = 0.95 * target_error, p99_aim = 0.95 * p99_budget;
  std::vector<double> measured_budgets(budgets.size()), weights(budgets.size());
  for (size_t k = 0; k < budgets.size(); ++k) {
    measured_budgets[k] = std::isfinite(budgets[k]) ? budgets[k] : p99_budget;
    weights[k] = !std::isfinite(budgets[k]) ? 0.0 : budgets[k] == p99_budget ? 1.0 : p99_budget / budgets[k];
  }
  double scale = 1, best_scale = 0, missed_scale = std::numeric_limits<double>::infinity();
  double last_scale = 0, last_worst = 0, last_p99 = 0;
  std::vector<double> best_errors, best_p99s;
  int refinements = 0, refusals = 0;
  for (;; ++refinements) {
    apply(scale);
    const std::vector<RoundedError> measured =
        rounded_errors(keys, coding, rounder, exact, pool, bounded ? measured_budgets : std::vector<double>{}, intra, scale);
    std::vector<double> errors, p99s;
    double worst_p99 = bounded ? 1e-300 : 0.0;
    for (size_t k = 0; k < measured.size(); ++k) {
      errors.push_back(measured[k].rms);
      if (bounded) {
        p99s.push_back(measured[k].p99);
        worst_p99 = std::max(worst_p99, weights[k] == 1.0 ? measured[k].p99 : measured[k].p99 * weights[k]);
      }
    }
    const double worst = std::max(*std::max_element(errors.begin(), errors.end()), 1e-300);
    const bool p99_met = !bounded || worst_p99 <= p99_budget;
    if (!p99_met) ++refusals;
    const bool met = worst <= kTolerance * target_error && p99_met;
    if (met && scale > best_scale) {
      best_scale = scale;
      best_errors = errors;
      best_p99s = p99s;
    }
    if (!met) missed_scale = std::min(missed_scale, scale);
    const bool near = worst >= 0.8 * target_error || (refusals > 0 && worst_p99 >= 0.8 * p99_budget);
    if ((met && near) || refinements == kMaxRefinements) break;
    // error ∝ scale^exponent, through the last two readings of the measure that decides
    const bool by_p99 = !p99_met;
    const double reading = by_p99 ? worst_p99 : worst, last_reading = by_p99 ? last_p99 : last_worst;
    double exponent = 1;
    if (last_scale > 0 && last_scale != scale && last_reading > 0 && last_reading != reading) {
      exponent = std::clamp(std::log(reading / last_reading) / std::log(scale / last_scale), 0.5, 4.0);
    }
    double next = scale * std::pow((by_p99 ? p99_aim : aim) / reading, 1 / exponent);
    if (best_scale > 0 && std::isfinite(missed_scale) && !(next > best_scale && next < missed_scale))
      next = std::sqrt(best_scale * missed_scale);
    last_scale = scale;
    last_worst = worst;
    last_p99 = worst_p99;
    scale = next;
  }
  if (best_scale == 0) {
    throw Error(ErrorCode::kNotConverged, "field precision: no steps met the target error " + std::to_string(target_error) +
                                              (bounded ? " and the worst region's rounding budget " + std::to_string(p99_budget) : "") +
                                              " in " + std::to_string(kMaxRefinements) + " refinements");
  }
  apply(best_scale);
  return {coding, best_scale, best_errors, best_p99s, refinements, refusals};
}

// A trial's keyframes as the file would hold them (fields, hole level and pose rounded; no texture),
// each made when the file writer asks for it from the exact fields. The writer reads a group's
// keyframes in order, so each is rounded once, after its predecessor (asked in another order, the
// chain starts again at the intra keyframe before it): the trial's file is measured holding one
// rounded keyframe, not a copy of every keyframe's fields.
class RoundedKeyframes final : public GeometryTrialSource {
 public:
  RoundedKeyframes(const StoredSequence& keys, const FieldRounder& rounder, const FieldCoding& coding)
      : GeometryTrialSource(keys.outline(), "field precision"), keys_(keys), rounder_(rounder), coding_(coding) {}
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override {
    std::lock_guard lock(mutex_);
    if (last_ && last_index_ == k) return last_;
    size_t from = k;
    if (!(last_ && last_index_ + 1 == k)) {
      from = k - k % static_cast<size_t>(coding_.intra_period);
      chain_.emplace(rounder_, coding_);
    }
    for (size_t j = from; j <= k; ++j) {
      auto key = std::make_shared<Keyframe>();
      key->time = keys_.shape().keyframes.at(j).time;
      key->pose = keys_.shape().keyframes[j].pose;
      key->hole_level = *keys_.hole_level(j);
      key->fields = chain_->next(j, *keys_.fields(j));
      round_to_field_steps(*key, coding_);
      last_ = std::move(key);
      last_index_ = j;
    }
    return last_;
  }

 private:
  const StoredSequence& keys_;
  const FieldRounder& rounder_;
  const FieldCoding& coding_;
  mutable std::mutex mutex_;
  mutable std::optional<FieldRounder::Chain> chain_;
  mutable std::shared_ptr<const Keyframe> last_;
  mutable size_t last_index_ = 0;
};

// The keyframes as the file will hold them, in order (each rounded after its predecessor), put
// back in place of their exact fields.
void put_rounded(StoredSequence& keys, const FieldRounder& rounder, const FieldCoding& coding) {
  FieldRounder::Chain chain(rounder, coding);
  for (size_t k = 0; k < keys.size(); ++k) {
    Keyframe key;
    key.pose = keys.shape().keyframes[k].pose;
    key.hole_level = *keys.hole_level(k);
    key.fields = chain.next(k, *keys.fields(k));
    round_to_field_steps(key, coding);
    keys.put_fields(k, std::move(key.fields));
    keys.put_hole_level(k, std::move(key.hole_level));
    keys.set_pose(k, key.pose);
  }
}

void check_options(const FieldPrecisionOptions& options) {
  if (!(options.target_error > 0) || !std::isfinite(options.target_error)) {
    throw Error(ErrorCode::kInvalidArgument, "field precision: the target error must be finite and positive");
  }
  if (options.inter_dead_zone != kAutoDeadZone) check_dead_zone(options.inter_dead_zone);
  if (options.intra_period < 0) throw Error(ErrorCode::kInvalidArgument, "field precision: a negative intra period");
  if (options.threads < 0) throw Error(ErrorCode::kInvalidArgument, "field precision: a negative thread count");
  if (!(options.worst_target > 0) || !std::isfinite(options.worst_target) ||
      (options.worst_floor && (!(*options.worst_floor >= 0) || !std::isfinite(*options.worst_floor)))) {
    throw Error(ErrorCode::kInvalidArgument,
                "field precision: the worst region's target must be finite and positive, its floor finite and not negative");
  }
  for (const double floor : options.keyframe_floors) {
    if (!(floor >= 0)) throw Error(ErrorCode::kInvalidArgument, "field precision: a keyframe's floor is negative or not a number");
  }
}

}  // namespace

FieldCoding choose_field_coding(StoredSequence& keys, const FieldPrecisionOptions& options, FieldPrecisionReport* report) {
  check_options(options);
  const Sequence& shape = keys.shape();
  if (shape.keyframes.empty()) throw Error(ErrorCode::kInvalidArgument, "sequence: no keyframes");
  Spill spill(options.spill);
  ReconstructorPool pool(shape.grid_n, options.threads);
  // What no trial changes, made once: every keyframe's exact surface (decoded side by side), and
  // from keyframe 0's the calibration's steps (keyframe 0 is intra: no dead zone applies to it).
  // Keyframe 0's exact surface was decoded twice before, for the calibration on one thread first.
  // The failures come in the order they always have: keyframe 0's decode, then the calibration's
  // probes, then the lowest other keyframe that does not decode (the error, and with it whether the
  // encode falls back to positions and what its file says, never depends on the threads).
  const ExactSurfaces exact(keys, pool, spill);
  exact.rethrow_failures(0, 1);
  Calibration calibration;
  try {
    calibration = calibrate(*keys.fields(0), *exact.store.get(0), exact.diagonals[0], options.target_error, options.noise_shaping, pool);
  } catch (const Error& e) {
    throw Error(e.code(), "keyframe 0: " + std::string(e.what()));  // the calibration's probes round keyframe 0
  }
  exact.rethrow_failures(1, keys.size());
  const int period = options.intra_period == kAutoIntraPeriod ? auto_intra_period(shape) : options.intra_period;
  const double p99_budget = rounding_p99_budget(options);
  if (!options.keyframe_floors.empty() && options.keyframe_floors.size() != keys.size())
    throw Error(ErrorCode::kInvalidArgument, "field precision: " + std::to_string(options.keyframe_floors.size()) +
                                                 " keyframe floors for " + std::to_string(keys.size()) + " keyframes");
  const std::vector<double> budgets = keyframe_p99_budgets(options, p99_budget, keys.size());
  double dead_zone = options.inter_dead_zone;
  std::optional<StepChoice> choice;
  uint64_t fewest = 0;  // the chosen zone's bytes (0: no zone compared)
  if (options.inter_dead_zone == kAutoDeadZone) {
    // Each candidate meets the same target; the one whose keyframes take the fewest bytes wins, and
    // its steps are the result (the search is deterministic: run again, it would find them again).
    dead_zone = kDeadZoneCandidates.front();
    const bool predicts = period > 1 && shape.keyframes.size() > 1;
    IntraErrors intra{static_cast<size_t>(period), {}};
    struct ZoneTrial {
      double zone = 0;
      StepChoice steps;
      uint64_t bytes = 0;
    };
    std::vector<ZoneTrial> trials;
    for (size_t c = 0; predicts && c < kDeadZoneCandidates.size(); ++c) {
      const FieldRounder rounder(pool.grid(), options.noise_shaping, kDeadZoneCandidates[c]);
      try {
        trials.push_back({kDeadZoneCandidates[c],
                          choose_steps(keys, options.target_error, p99_budget, budgets, period, rounder, calibration, exact, pool, &intra)});
      } catch (const Error& e) {
        if (e.code() != ErrorCode::kNotConverged) throw;
        continue;  // this zone met no steps; another may
      }
    }
    // The zones' files laid out side by side once every zone's steps are found: a layout reads the
    // exact fields and rounds them itself (RoundedKeyframes), so the layouts share nothing, and on
    // one thread each after the other they were ict24's longest stretch with the other thread idle
    // (1.4 s of 24). The same bytes, and the same zone kept (the first of the fewest).
    parallel_for(static_cast<int>(trials.size()), options.threads, [&](int t) {
      ZoneTrial& trial = trials[static_cast<size_t>(t)];
      const FieldRounder rounder(pool.grid(), options.noise_shaping, trial.zone);
      SequenceFileMetadata metadata;
      metadata.field_coding = trial.steps.coding;
      trial.bytes = sequence_file_size(RoundedKeyframes(keys, rounder, trial.steps.coding), metadata);
    });
    for (ZoneTrial& trial : trials) {
      if (!choice || trial.bytes < fewest) {
        fewest = trial.bytes;
        dead_zone = trial.zone;
        choice = std::move(trial.steps);
      }
    }
  }
  const FieldRounder rounder(pool.grid(), options.noise_shaping, dead_zone);
  if (!choice) choice = choose_steps(keys, options.target_error, p99_budget, budgets, period, rounder, calibration, exact, pool);
  put_rounded(keys, rounder, choice->coding);
  spill.bytes += exact.store.spilled_bytes();
  if (report) {
    report->target_error = options.target_error;
    report->group_steps = calibration.group_steps;
    for (double& s : report->group_steps) s *= choice->scale;
    report->keyframe_errors = choice->errors;
    report->refinements = choice->refinements;
    report->rounding_p99_budget = std::isfinite(p99_budget) ? p99_budget : 0.0;
    report->worst_target = options.worst_target;
    report->keyframe_p99s = choice->p99s;
    report->keyframe_budgets.clear();
    report->keyframe_floors.clear();
    if (std::any_of(budgets.begin(), budgets.end(), [&](double b) { return b != p99_budget; })) {
      for (const double b : budgets) report->keyframe_budgets.push_back(std::isfinite(b) ? b : 0.0);
      report->keyframe_floors = options.keyframe_floors;
    }
    report->worst_region_refusals = choice->worst_region_refusals;
    report->inter_dead_zone = dead_zone;
    report->geometry_bytes = fewest;
    report->peak_keyframes_in_memory = spill.count->peak.load();
    report->spilled_bytes = spill.bytes;
  }
  return choice->coding;
}

std::vector<double> apply_field_coding(StoredSequence& keys, const FieldCoding& coding, const FieldPrecisionOptions& options) {
  check_options(options);
  check_dead_zone(options.inter_dead_zone);
  if (keys.size() == 0) throw Error(ErrorCode::kInvalidArgument, "sequence: no keyframes");
  Spill spill(options.spill);
  ReconstructorPool pool(keys.shape().grid_n, options.threads);
  const ExactSurfaces exact(keys, pool, spill);
  const FieldRounder rounder(pool.grid(), options.noise_shaping, options.inter_dead_zone);
  std::vector<double> errors;
  for (const RoundedError& e : rounded_errors(keys, coding, rounder, exact, pool)) errors.push_back(e.rms);
  put_rounded(keys, rounder, coding);
  return errors;
}

FieldCoding choose_field_coding(Sequence& sequence, const FieldPrecisionOptions& options, FieldPrecisionReport* report) {
  check_options(options);
  validate_sequence(sequence);
  // The keyframes moved into a store for the search (in the temporary file with options.spill, as
  // the encoder keeps them) and back, rounded (back also when the search throws).
  return StoredSequence::around(sequence, options.spill ? SpillMode::kSpill : SpillMode::kMemory,
                                [&](StoredSequence& keys) { return choose_field_coding(keys, options, report); });
}

}  // namespace facemorph
