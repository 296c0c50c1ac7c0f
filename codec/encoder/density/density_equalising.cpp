// The density-equalising reparametrisation of the reference disk (Choi & Rycroft 2018, adapted to a
// disk whose rim must stay on the circle): spec/method.md §7.11.
//
// Each vertex carries a share of the surface ("population": the surface's area to the power s
// times the disk's to the power 1 - s, so s = 1 aims at an equal-area map and s = 0 changes
// nothing). The density ρ = population / disk area is recomputed from the current disk every step,
// smoothed by one implicit diffusion step on the current mesh, (M + δt K) ρ' = M ρ, and the vertices
// move with the flow v = -∇ρ'/ρ' that carries population from dense to sparse regions until ρ is
// uniform. Recomputing ρ from the areas (rather than only diffusing it) keeps the final disk
// consistent with the population exactly, whatever the step.
#include "codec/encoder/density/density_equalising.hpp"

#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/elementary.hpp"
#include "codec/core/grid/disk_grid.hpp"
#include "codec/encoder/conformal/lagged_cholesky.hpp"
#include "codec/meshkit/geometry/surface_measures.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <string>

namespace facemorph {

namespace {

std::vector<double> disk_areas(const std::vector<Vec2>& points, const std::vector<Face>& faces) {
  std::vector<double> areas(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    areas[f] = signed_area(points[static_cast<size_t>(faces[f][0])], points[static_cast<size_t>(faces[f][1])],
                           points[static_cast<size_t>(faces[f][2])]);
  }
  return areas;
}

// ρ per vertex: the population of its faces over their disk area.
Eigen::VectorXd vertex_density(const std::vector<double>& population, const std::vector<double>& areas, const std::vector<Face>& faces,
                               size_t vertices) {
  Eigen::VectorXd people = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(vertices));
  Eigen::VectorXd room = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(vertices));
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      people[faces[f][k]] += population[f];
      room[faces[f][k]] += std::max(areas[f], 1e-300);
    }
  }
  return people.cwiseQuotient(room);
}

// Coefficient of variation of the face density population / area, weighted by area.
double variation(const std::vector<double>& population, const std::vector<double>& areas) {
  double total = 0, people = 0;
  for (size_t f = 0; f < areas.size(); ++f) total += areas[f], people += population[f];
  const double mean = people / total;
  double spread = 0;
  for (size_t f = 0; f < areas.size(); ++f) {
    const double rho = population[f] / std::max(areas[f], 1e-300);
    spread += areas[f] * (rho - mean) * (rho - mean);
  }
  return std::sqrt(spread / total) / mean;
}

// The gradient of a piecewise-linear function on each face, averaged to the vertices by face area.
std::vector<Vec2> vertex_gradients(const std::vector<Vec2>& points, const std::vector<Face>& faces, const std::vector<double>& areas,
                                   const Eigen::VectorXd& f) {
  std::vector<Vec2> sum(points.size(), Vec2::Zero());
  std::vector<double> weight(points.size(), 0.0);
  for (size_t t = 0; t < faces.size(); ++t) {
    const auto i = static_cast<size_t>(faces[t][0]), j = static_cast<size_t>(faces[t][1]), k = static_cast<size_t>(faces[t][2]);
    Eigen::Matrix2d edges;
    edges.row(0) = (points[j] - points[i]).transpose();
    edges.row(1) = (points[k] - points[i]).transpose();
    const Vec2 rise(f[static_cast<Eigen::Index>(j)] - f[static_cast<Eigen::Index>(i)],
                    f[static_cast<Eigen::Index>(k)] - f[static_cast<Eigen::Index>(i)]);
    const Vec2 g = edges.partialPivLu().solve(rise);
    for (size_t v : {i, j, k}) {
      sum[v] += areas[t] * g;
      weight[v] += areas[t];
    }
  }
  for (size_t v = 0; v < points.size(); ++v) sum[v] /= std::max(weight[v], 1e-300);
  return sum;
}

// The flow's grid: 129² (13k nodes) resolves the density finely enough for any G (the map is
// smooth at that scale) and flows in a second or two.
constexpr int kFlowGrid = 129;

// The density to equalise on each of the reference's faces: (surface area share / disk area share)
// to the power `strength`, the ratio capped at 10⁶ against degenerate disk triangles.
std::vector<double> reference_density(const DiskMap& reference, double strength) {
  const std::vector<Face>& faces = reference.surface.faces;
  const std::vector<double> disk = disk_areas(reference.disk, faces);
  const std::vector<double> surface = face_areas(reference.surface.positions, faces);
  const double disk_total = std::accumulate(disk.begin(), disk.end(), 0.0);
  const double surface_total = std::accumulate(surface.begin(), surface.end(), 0.0);
  if (!(disk_total > 0) || !(surface_total > 0)) throw Error(ErrorCode::kNumerical, "density-equalising: the reference has no area");
  std::vector<double> density(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    const double share = surface[f] / surface_total, room = std::max(disk[f], 0.0) / disk_total;
    const double ratio = room > 0 ? std::clamp(share / room, 1e-6, 1e6) : 1e6;
    density[f] = std::pow(ratio, strength);
  }
  return density;
}

// 4√3 A / Σ edge²: 1 for an equilateral triangle, 0.87 for the grid's right isosceles ones, 0 for
// a degenerate one, negative for one turned over. The flow stops before any triangle of its grid
// falls below kMinShapeQuality: an extreme density (ICT's nostril pockets at strength 1) otherwise
// squeezes triangles into slivers, and G sampled through a sliver gets triangles on the surface too
// thin for the Laplace–Beltrami reconstruction (measured: keyframes at 8.4% RMS instead of 0.25%).
constexpr double kMinShapeQuality = 0.25;

double shape_quality(const std::vector<Vec2>& points, const Face& f, double area) {
  const Vec2 &a = points[static_cast<size_t>(f[0])], &b = points[static_cast<size_t>(f[1])], &c = points[static_cast<size_t>(f[2])];
  return 4 * std::sqrt(3.0) * area / ((b - a).squaredNorm() + (c - b).squaredNorm() + (a - c).squaredNorm());
}

double angle_of(const Vec2& p) {
  const double a = std::atan2(p.y(), p.x());
  return a < 0 ? a + 2 * std::numbers::pi : a;
}

}  // namespace

DiskReparametrisation::DiskReparametrisation(const DiskMap& reference, const DensityEqualisingOptions& options) {
  if (!(options.strength >= 0 && options.strength <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "density-equalising strength must be in [0, 1], not " + std::to_string(options.strength));
  }
  if (!(options.step > 0) || options.max_steps < 0) throw Error(ErrorCode::kInvalidArgument, "density-equalising: step must be positive");
  if (options.strength == 0 || options.max_steps == 0) return;
  // The flow runs on a disk grid, not on the reference's own triangles: a captured mesh's disk
  // has slivers and crowded pockets (ICT's nostrils: disk triangles 10⁴ times smaller than their
  // neighbours) that any motion turns over, while the grid's triangles are well shaped. The
  // reference only supplies the density, sampled at four points of every grid triangle.
  const DiskGrid grid = make_disk_grid(kFlowGrid);
  const std::vector<Face>& faces = grid.faces;
  const size_t n = grid.nodes.size();
  std::vector<Vec2> points = grid.nodes;
  std::vector<double> areas = disk_areas(points, faces);
  const std::vector<double> density = reference_density(reference, options.strength);
  const InverseDiskMap inverse(reference);
  std::vector<double> population(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    const Vec2 &a = points[static_cast<size_t>(faces[f][0])], &b = points[static_cast<size_t>(faces[f][1])],
               &c = points[static_cast<size_t>(faces[f][2])];
    double sum = 0;
    const Vec2 samples[] = {(4 * a + b + c) / 6, (a + 4 * b + c) / 6, (a + b + 4 * c) / 6, (a + b + c) / 3};
    for (const Vec2& sample : samples) {
      const auto hit = inverse.locate(sample.norm() > 1 ? Vec2(sample.normalized()) : sample);
      sum += hit ? density[static_cast<size_t>(hit->face)] : 1.0;
    }
    population[f] = areas[f] * sum / 4;
  }
  const double disk_total = std::accumulate(areas.begin(), areas.end(), 0.0);
  const double people = std::accumulate(population.begin(), population.end(), 0.0);
  for (double& p : population) p *= disk_total / people;

  std::vector<char> on_rim(n, 0);
  for (size_t v = static_cast<size_t>(grid.interior_count); v < n; ++v) on_rim[v] = 1;
  report_.variation_before = variation(population, areas);
  report_.variation_after = report_.variation_before;

  // The vertices move a little each step, so an earlier step's factor preconditions this one's
  // system well (LaggedCholesky).
  LaggedCholesky solver;
  std::vector<Vec3> lifted(n);
  double step = options.step;
  for (int iteration = 0; iteration < options.max_steps; ++iteration) {
    for (size_t v = 0; v < n; ++v) lifted[v] = Vec3(points[v].x(), points[v].y(), 0);
    const SparseMatrix K = cotangent_laplacian(lifted, faces);
    const Eigen::VectorXd M = barycentric_areas(lifted, faces);
    const Eigen::VectorXd rho = vertex_density(population, areas, faces, n);
    // Converged when the density seen at the vertices is uniform; what remains in the faces is
    // triangle-scale (the sampling of the reference's own triangles), which no smooth map removes.
    // Tested before the step's factorisation, which a converged flow does not use.
    const double mean = M.dot(rho) / M.sum();
    if (std::sqrt(M.dot((rho.array() - mean).square().matrix()) / M.sum()) / mean < options.tolerance) break;
    const SparseMatrix A = SparseMatrix(M.asDiagonal()) + step * K;
    if (iteration == 0) solver.analyze(A);
    Eigen::MatrixXd solved;
    if (!solver.solve(A, M.cwiseProduct(rho), solved))
      throw Error(ErrorCode::kNumerical, "density-equalising: the diffusion system is not positive definite");
    const Eigen::VectorXd smooth = solved.col(0);
    const std::vector<Vec2> gradient = vertex_gradients(points, faces, areas, smooth);
    std::vector<Vec2> velocity(n);
    for (size_t v = 0; v < n; ++v) {
      velocity[v] = -gradient[v] / std::max(smooth[static_cast<Eigen::Index>(v)], 1e-300);
      if (on_rim[v]) {
        const Vec2 normal = points[v].normalized();
        velocity[v] -= velocity[v].dot(normal) * normal;  // slide along the circle
      }
    }
    // The step, halved until every triangle stays positive.
    std::vector<Vec2> moved(n);
    std::vector<double> moved_areas;
    bool valid = false;
    for (int halving = 0; halving < 8 && !valid; ++halving) {
      const double h = step / std::pow(2.0, halving);
      for (size_t v = 0; v < n; ++v) {
        moved[v] = points[v] + h * velocity[v];
        if (on_rim[v]) moved[v].normalize();
      }
      moved_areas = disk_areas(moved, faces);
      valid = true;
      for (size_t f = 0; f < faces.size() && valid; ++f) valid = shape_quality(moved, faces[f], moved_areas[f]) >= kMinShapeQuality;
    }
    if (!valid) {
      report_.stopped_early = true;
      break;
    }
    points = std::move(moved);
    areas = std::move(moved_areas);
    report_.variation_after = variation(population, areas);
    report_.steps = iteration + 1;
  }

  auto mesh = std::make_shared<Mesh>();
  mesh->conformal = grid.nodes;
  mesh->equalised = std::move(points);
  mesh->faces = faces;
  // The rim in the order of its equalised angles (sliding keeps the cyclic order: no triangle turned).
  std::vector<std::pair<double, size_t>> rim;
  for (size_t v = static_cast<size_t>(grid.interior_count); v < n; ++v) rim.emplace_back(angle_of(mesh->equalised[v]), v);
  std::sort(rim.begin(), rim.end());
  double previous = -1e300;
  for (const auto& [angle, v] : rim) {
    mesh->rim_angle.push_back(angle);
    double conformal = angle_of(mesh->conformal[v]);
    while (conformal < previous) conformal += 2 * std::numbers::pi;
    mesh->rim_conformal_angle.push_back(conformal);
    previous = conformal;
  }
  mesh->locator = std::make_unique<TriangleLocator>(mesh->equalised, mesh->faces);
  mesh_ = std::move(mesh);
}

namespace {

constexpr int kRadialBins = 1024;

// The surface's area in kRadialBins rings of equal width in disk radius: each face's area spread
// evenly over the span of its vertices' radii (a face's centroid alone leaves rings empty where the
// faces are wider than a ring, near a whole head's rim).
std::vector<double> radial_area(const DiskMap& map) {
  std::vector<double> bins(kRadialBins, 0.0);
  const std::vector<double> surface = face_areas(map.surface.positions, map.surface.faces);
  for (size_t f = 0; f < surface.size(); ++f) {
    double lo = 1, hi = 0;
    for (int32_t v : map.surface.faces[f]) {
      const double r = std::min(map.disk[static_cast<size_t>(v)].norm(), 1.0);
      lo = std::min(lo, r), hi = std::max(hi, r);
    }
    const double a = lo * kRadialBins, b = hi * kRadialBins;
    const int first = std::min(static_cast<int>(a), kRadialBins - 1), last = std::min(static_cast<int>(b), kRadialBins - 1);
    if (first == last || b - a < 1e-12) {
      bins[static_cast<size_t>(first)] += surface[f];
      continue;
    }
    for (int k = first; k <= last; ++k) {
      const double overlap = std::min<double>(k + 1, b) - std::max<double>(k, a);
      bins[static_cast<size_t>(k)] += surface[f] * std::max(overlap, 0.0) / (b - a);
    }
  }
  return bins;
}

}  // namespace

double half_area_radius(const DiskMap& map) {
  const std::vector<double> bins = radial_area(map);
  const double total = std::accumulate(bins.begin(), bins.end(), 0.0);
  if (!(total > 0)) throw Error(ErrorCode::kNumerical, "half_area_radius: the surface has no area");
  double sum = 0;
  for (int k = 0; k < kRadialBins; ++k) {
    const double next = sum + bins[static_cast<size_t>(k)];
    if (next >= 0.5 * total) return (k + (0.5 * total - sum) / std::max(bins[static_cast<size_t>(k)], 1e-300)) / kRadialBins;
    sum = next;
  }
  return 1;
}

DiskReparametrisation DiskReparametrisation::radial(const DiskMap& reference, double strength) {
  if (!(strength > 0 && strength <= 1)) throw Error(ErrorCode::kInvalidArgument, "radial reparametrisation: strength must be in (0, 1]");
  const std::vector<double> bins = radial_area(reference);
  const double total = std::accumulate(bins.begin(), bins.end(), 0.0);
  if (!(total > 0)) throw Error(ErrorCode::kNumerical, "radial reparametrisation: the reference has no area");
  // Each ring's population: its disk area times (surface share / disk share)^strength, plus a
  // trace of its disk area so the cumulative share rises strictly; P at the ring edges.
  std::vector<double> P(kRadialBins + 1, 0.0);
  for (int k = 0; k < kRadialBins; ++k) {
    const double room = (std::pow(k + 1.0, 2) - std::pow(k, 2.0)) / (static_cast<double>(kRadialBins) * kRadialBins);
    const double ratio = std::clamp(bins[static_cast<size_t>(k)] / total / room, 0.0, 1e6);
    P[static_cast<size_t>(k) + 1] = P[static_cast<size_t>(k)] + room * (std::pow(ratio, strength) + 1e-9);
  }
  for (double& p : P) p /= P.back();
  // Equal population, equal area of the new disk: R² = P(r). Tabulated as r at R = k / (size - 1).
  constexpr int kTable = 4096;
  auto table = std::make_shared<std::vector<double>>(kTable + 1);
  size_t ring = 0;
  for (int k = 0; k <= kTable; ++k) {
    const double R = static_cast<double>(k) / kTable, target = R * R;
    while (ring + 1 < P.size() - 1 && P[ring + 1] < target) ++ring;
    const double span = P[ring + 1] - P[ring];
    const double f = span > 0 ? std::clamp((target - P[ring]) / span, 0.0, 1.0) : 0.0;
    (*table)[static_cast<size_t>(k)] = (static_cast<double>(ring) + f) / kRadialBins;
  }
  (*table)[0] = 0;
  (*table)[kTable] = 1;
  DiskReparametrisation out;
  out.radial_ = std::move(table);
  // What it does to the half-area radius: R holding P = 1/2 of the population... of the surface.
  out.report_.half_area_radius_before = half_area_radius(reference);
  double sum = 0;
  for (int k = 0; k < kRadialBins; ++k) {
    sum += bins[static_cast<size_t>(k)];
    if (sum >= 0.5 * total) {
      out.report_.half_area_radius_after = std::sqrt(P[static_cast<size_t>(k) + 1]);
      break;
    }
  }
  return out;
}

Vec2 DiskReparametrisation::operator()(const Vec2& g) const {
  if (radial_) {
    const double R = std::min(g.norm(), 1.0);
    if (R == 0) return g;
    const std::vector<double>& table = *radial_;
    const double x = R * static_cast<double>(table.size() - 1);
    const auto k = std::min(static_cast<size_t>(x), table.size() - 2);
    const double f = x - static_cast<double>(k);
    const double r = (1 - f) * table[k] + f * table[k + 1];
    return g * (r / g.norm());
  }
  if (!mesh_) return g;
  const Mesh& m = *mesh_;
  // Within 10⁻⁶ of the circle (inside the rim chords' slivers) by angle, so the circle maps onto itself.
  const auto hit = g.norm() < 1 - 1e-6 ? m.locator->locate(g, 1e-9) : std::nullopt;
  if (hit) {
    const Face& f = m.faces[static_cast<size_t>(hit->face)];
    return hit->bary[0] * m.conformal[static_cast<size_t>(f[0])] + hit->bary[1] * m.conformal[static_cast<size_t>(f[1])] +
           hit->bary[2] * m.conformal[static_cast<size_t>(f[2])];
  }
  // On the circle or between a rim chord and it: the same radius at the angle interpolated between the rim
  // vertices either side.
  const double theta = angle_of(g);
  const size_t count = m.rim_angle.size();
  size_t i = static_cast<size_t>(std::upper_bound(m.rim_angle.begin(), m.rim_angle.end(), theta) - m.rim_angle.begin());
  i = (i + count - 1) % count;
  const size_t j = (i + 1) % count;
  double span = m.rim_angle[j] - m.rim_angle[i], offset = theta - m.rim_angle[i];
  if (span <= 0) span += 2 * std::numbers::pi;
  if (offset < 0) offset += 2 * std::numbers::pi;
  const double t = std::clamp(offset / span, 0.0, 1.0);
  double to = m.rim_conformal_angle[j];
  while (to < m.rim_conformal_angle[i]) to += 2 * std::numbers::pi;
  const double angle = (1 - t) * m.rim_conformal_angle[i] + t * to;
  return std::min(g.norm(), 1.0) * Vec2(std::cos(angle), std::sin(angle));
}

std::vector<Vec2> DiskReparametrisation::operator()(std::span<const Vec2> points) const {
  std::vector<Vec2> out(points.size());
  for (size_t i = 0; i < points.size(); ++i) out[i] = (*this)(points[i]);
  return out;
}

}  // namespace facemorph
