// Registration of a frame's disk to the reference disk (method-notes §4-6): the OMT, then the GMF
// composed after it, and the fallbacks that keep the result a bijection of the disk; Φ on a geodesic
// frame's partition built on that GMF.
#include "codec/encoder/registration/registration_internal.hpp"

#include "codec/core/util/enum_names.hpp"
#include "codec/encoder/registration/partition_map.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>

namespace facemorph {

namespace {

constexpr EnumName<RegistrationMethod> kRegistrationMethodNames[] = {
    {RegistrationMethod::kMoebius, "moebius"}, {RegistrationMethod::kGmf, "gmf"}, {RegistrationMethod::kFrame, "frame"}};
constexpr EnumName<GmfForm> kGmfFormNames[] = {{GmfForm::kThinPlate, "thin-plate"}, {GmfForm::kPaperGrid, "paper-grid"}};
constexpr EnumName<RegistrationFallback> kRegistrationFallbackNames[] = {
    {RegistrationFallback::kNone, "none"},
    {RegistrationFallback::kMoreSmoothing, "more-smoothing"},
    {RegistrationFallback::kSubsteps, "substeps"},
    {RegistrationFallback::kMoebiusOnly, "moebius-only"},
    {RegistrationFallback::kGmfInsteadOfFrame, "gmf-instead-of-frame"}};

}  // namespace

const char* registration_method_name(RegistrationMethod method) { return name_of(kRegistrationMethodNames, method); }

RegistrationMethod parse_registration_method(const std::string& name) {
  return parse_name(kRegistrationMethodNames, name, "registration method");
}

const char* gmf_form_name(GmfForm form) { return name_of(kGmfFormNames, form); }

GmfForm parse_gmf_form(const std::string& name) { return parse_name(kGmfFormNames, name, "GMF form"); }

const char* registration_fallback_name(RegistrationFallback fallback) { return name_of(kRegistrationFallbackNames, fallback); }

namespace {

double energy_of(const DiskRegistration& f, const CheckedLandmarks& l) {
  double e = 0;
  for (size_t i = 0; i < l.p.size(); ++i) e += l.w[i] * (f(to_vec2(l.p[i])) - to_vec2(l.q[i])).squaredNorm();
  return e;
}

void check_registration_options(const RegistrationOptions& o) {
  if (!std::isfinite(o.smoothing) || o.smoothing < 0) refuse_registration_input("smoothing must be finite and >= 0");
  if (o.paper_grid_n < 2 || o.paper_grid_n > 256) refuse_registration_input("paper grid n must be in [2, 256]");
  if (!std::isfinite(o.boundary_spacing_degrees) || o.boundary_spacing_degrees < 0 || o.boundary_spacing_degrees > 120) {
    refuse_registration_input("boundary sample spacing must be 0 (none) or in (0, 120] degrees");
  }
  if (o.fold_grid < 3 || o.fold_grid > 4097) refuse_registration_input("fold grid size must be in [3, 4097]");
  if (o.smoothing_tries < 0 || o.smoothing_tries > 12) refuse_registration_input("smoothing tries must be in [0, 12]");
  if (o.max_substeps < 1 || o.max_substeps > 64) refuse_registration_input("max substeps must be in [1, 64]");
  if (!(o.min_area_ratio >= 0 && o.min_area_ratio < 1)) refuse_registration_input("min area ratio must be in [0, 1)");
}

bool accepted(const BijectionCheck& c, const RegistrationOptions& o) { return c.ok() && c.min_area_ratio > o.min_area_ratio; }

std::string describe(const BijectionCheck& c, const RegistrationOptions& o) {
  std::ostringstream out;
  if (c.folded_points > 0 || !(c.min_area_ratio > o.min_area_ratio)) {
    out << (c.folded_points > 0 ? "folds" : "nearly folds") << " near w = (" << c.worst_point.x() << ", " << c.worst_point.y()
        << ") (area ratio " << c.min_area_ratio << ")";
  }
  if (c.boundary_order_breaks > 0) {
    out << (out.tellp() > 0 ? "; " : "") << "circle images out of order at " << c.boundary_order_breaks << " of " << c.boundary_samples
        << " samples";
  }
  return out.str();
}

// The GMF's data: the landmarks after m (ω > 0 only: a landmark with no weight has no say) and the
// boundary samples, with their targets on the frame disk.
struct GmfData {
  std::vector<Vec2> points, targets;
  std::vector<double> weights;
  double spacing2 = 0;  // mean squared nearest-neighbour spacing of the landmarks after m
  int boundary = 0;
};

GmfData gmf_data(const CheckedLandmarks& l, const DiskMoebius& m, double spacing_degrees) {
  GmfData data;
  for (size_t i = 0; i < l.p.size(); ++i) {
    if (l.w[i] == 0) continue;
    data.points.push_back(to_vec2(m(l.p[i])));
    data.targets.push_back(to_vec2(l.q[i]));
    data.weights.push_back(l.w[i]);
  }
  const size_t landmarks = data.points.size();
  for (size_t i = 0; i < landmarks; ++i) {
    double nearest = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < landmarks; ++j) {
      if (j != i) nearest = std::min(nearest, (data.points[i] - data.points[j]).squaredNorm());
    }
    if (std::isfinite(nearest)) data.spacing2 += nearest / static_cast<double>(landmarks);
  }
  const BoundarySamples samples = boundary_samples(l, m, spacing_degrees * std::numbers::pi / 180);
  data.points.insert(data.points.end(), samples.centres.begin(), samples.centres.end());
  data.targets.insert(data.targets.end(), samples.targets.begin(), samples.targets.end());
  data.weights.insert(data.weights.end(), samples.centres.size(), 1.0);
  data.boundary = static_cast<int>(samples.centres.size());
  return data;
}

// One GMF try: `substeps` fields, each fitted at the points' current images to 1/(steps left) of
// what remains, composed after m; then the bijection check. Empty, with `why`, when a fit is
// singular (sub-steps can bring two images together).
std::optional<DiskRegistration> try_gmf(const DiskRegistration& base, const GmfData& data, const RegistrationOptions& o, double smoothing,
                                        int substeps, std::string& why) {
  DiskRegistration f = base;
  f.smoothing = smoothing;
  std::vector<Vec2> at = data.points, step_targets(at.size());
  std::vector<double> lambda(at.size());
  // Weighted smoothing λ/ω: a landmark trusted less may be missed more (Wahba's weighted spline).
  for (size_t i = 0; i < at.size(); ++i) lambda[i] = smoothing * data.spacing2 / data.weights[i];
  try {
    for (int s = 0; s < substeps; ++s) {
      for (size_t i = 0; i < at.size(); ++i) step_targets[i] = (data.targets[i] - at[i]) / (substeps - s);
      f.steps.push_back(o.form == GmfForm::kThinPlate ? fit_thin_plate(at, step_targets, smoothing > 0 ? lambda : std::vector<double>{})
                                                      : fit_paper_grid(at, step_targets, data.weights, o.paper_grid_n, smoothing));
      for (Vec2& x : at) x += f.steps.back()(x);
    }
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kNumerical) throw;
    why = e.what();
    return std::nullopt;
  }
  f.check = check_bijection_until(f, o.fold_grid, o.min_area_ratio);
  why = describe(f.check, o);
  return f;
}

}  // namespace

double matching_energy(const DiskRegistration& f, const DiskLandmarks& landmarks) { return energy_of(f, check_landmarks(landmarks)); }

DiskRegistration register_disks(const DiskLandmarks& landmarks, const RegistrationOptions& options, const GeodesicFrame* frame) {
  check_registration_options(options);
  if (options.method == RegistrationMethod::kFrame) {
    if (!frame || !frame->partition) {
      throw Error(ErrorCode::kInvalidArgument,
                  "registration: method 'frame' needs the reference's geodesic frame (make_geodesic_frame), and none was given");
    }
    // Φ depends on f̄ only at the partition's vertices (notes §6): f̄ is the GMF, fallbacks and all.
    RegistrationOptions gmf = options;
    gmf.method = RegistrationMethod::kGmf;
    const DiskRegistration fbar = register_disks(landmarks, gmf);
    const std::vector<Vec2>& vertices = frame->partition->vertices();
    std::vector<Vec2> images(vertices.size());
    for (size_t i = 0; i < vertices.size(); ++i) images[i] = fbar(vertices[i]);
    DiskRegistration f = partition_registration(*frame, fbar, std::move(images), options.allow_fallback);
    f.energy = energy_of(f, check_landmarks(landmarks));
    return f;
  }
  const CheckedLandmarks l = check_landmarks(landmarks);
  const MoebiusFit omt = fit_moebius_checked(l, options.moebius);

  DiskRegistration base;
  base.method = options.method;
  base.form = options.form;
  base.moebius = omt.map;
  base.moebius_iterations = omt.iterations;
  base.moebius_start = omt.start;
  base.energy_moebius = energy_of(base, l);
  base.energy = base.energy_moebius;
  if (options.method == RegistrationMethod::kMoebius) return base;

  const GmfData data = gmf_data(l, omt.map, options.boundary_spacing_degrees);
  base.boundary_samples = data.boundary;
  auto finish = [&](DiskRegistration f, RegistrationFallback fallback, std::string reason) {
    f.fallback = fallback;
    f.fallback_reason = std::move(reason);
    f.energy = energy_of(f, l);
    return f;
  };

  std::string why;
  std::optional<DiskRegistration> f = try_gmf(base, data, options, options.smoothing, 1, why);
  if (f && accepted(f->check, options)) return finish(*f, RegistrationFallback::kNone, "");
  const std::string first = "the GMF " + why;
  if (!options.allow_fallback) {
    if (f) {
      f->check = check_bijection(*f, options.fold_grid);  // the whole story, not just the first fold
      return finish(*f, RegistrationFallback::kNone, first + " (fallback disabled)");
    }
    throw Error(ErrorCode::kNumerical, "registration: " + why);
  }

  // 1. Smoother: a stiffer spline bends less, and in the limit is the affine least-squares fit.
  // Starting from 1e-4 (thin plate, in spacing² units) or the paper's 1e-6 (ε) when none was asked.
  double smoothing = options.smoothing > 0 ? options.smoothing : (options.form == GmfForm::kThinPlate ? 1e-4 : 1e-6);
  std::ostringstream tried;
  tried << first;
  for (int k = 1; k <= options.smoothing_tries; ++k) {
    smoothing *= 10;
    f = try_gmf(base, data, options, smoothing, 1, why);
    if (f && accepted(f->check, options)) {
      tried << "; used smoothing " << smoothing;
      return finish(*f, RegistrationFallback::kMoreSmoothing, tried.str());
    }
  }
  if (options.smoothing_tries > 0) tried << "; smoothing up to " << smoothing << " does not help";
  // 2. Sub-steps at the smoothing asked for: each small move keeps I + ∇d near I.
  for (int k = 2; k <= options.max_substeps; k *= 2) {
    f = try_gmf(base, data, options, options.smoothing, k, why);
    if (f && accepted(f->check, options)) {
      tried << "; used " << k << " sub-steps";
      return finish(*f, RegistrationFallback::kSubsteps, tried.str());
    }
  }
  if (options.max_substeps >= 2) tried << "; nor do up to " << options.max_substeps << " sub-steps";
  // 3. The OMT alone: a Möbius map is always a bijection of the disk.
  DiskRegistration m = base;
  m.check = check_bijection(m, options.fold_grid);
  tried << ": the OMT alone";
  return finish(m, RegistrationFallback::kMoebiusOnly, tried.str());
}

}  // namespace facemorph
