// What a keyframe stores on G, computed with the decoder's own operators.
#include "facemorph/error.hpp"
#include "facemorph/reconstruct.hpp"

#include "format/quantize.hpp"

#include <algorithm>
#include <cmath>

namespace facemorph {

GridFields compute_fields(const GridGeometry& geometry, const std::vector<Vec3>& positions, Representation representation,
                          const std::vector<int32_t>& extra_fixed_nodes) {
  const DiskGrid& grid = geometry.grid();
  if (positions.size() != grid.nodes.size()) {
    throw Error(ErrorCode::kInvalidArgument, "compute_fields: " + std::to_string(positions.size()) + " positions for a grid of " +
                                                 std::to_string(grid.nodes.size()) + " nodes");
  }
  GridFields fields;
  fields.representation = representation;
  fields.grid_n = grid.n;
  const auto interior = static_cast<size_t>(grid.interior_count);
  fields.rim.assign(positions.begin() + static_cast<long>(interior), positions.end());
  if (representation == Representation::kXYZ) {
    fields.positions.assign(positions.begin(), positions.begin() + static_cast<long>(interior));
    return fields;
  }
  const std::vector<Vec3> laplacian = geometry.laplacian(positions);
  const std::vector<double> lambda2 = geometry.conformal_factor_squared(positions);
  std::vector<Vec3> tu, tv, n;
  geometry.frames(positions, tu, tv, n);
  const bool tangential = representation == Representation::kHLT;
  std::vector<uint8_t> fixed(interior, 0);
  if (tangential) {
    for (int32_t v : geometry.band_nodes()) fixed[static_cast<size_t>(v)] = 1;
    for (int32_t v : extra_fixed_nodes) {
      if (v < 0 || static_cast<size_t>(v) >= interior) throw Error(ErrorCode::kInvalidArgument, "compute_fields: fixed node out of range");
      fixed[static_cast<size_t>(v)] = 1;
    }
    for (size_t v = 0; v < interior; ++v) {
      if (fixed[v]) fields.fixed_nodes.push_back(static_cast<int32_t>(v));
    }
    fields.tangential_u.assign(interior, 0.0);
    fields.tangential_v.assign(interior, 0.0);
    const auto frames = geometry.boundary_frames(fields.rim, fields.fixed_nodes);
    for (size_t i = 0; i < frames.size(); ++i) {
      const Vec3& d = laplacian[static_cast<size_t>(fields.fixed_nodes[i])];
      fields.fixed_laplacian.emplace_back(d.dot(frames[i][0]), d.dot(frames[i][1]), d.dot(frames[i][2]));
    }
  }
  fields.mean_curvature.resize(interior);
  fields.log_conformal_factor.resize(interior);
  for (size_t v = 0; v < interior; ++v) {
    // Δ_h S = 2 H λ² n + a t_u + b t_v: H from the normal part (sign: spec/method.md §1).
    fields.log_conformal_factor[v] = 0.5 * std::log(lambda2[v]);
    fields.mean_curvature[v] = fixed[v] ? 0.0 : laplacian[v].dot(n[v]) / (2 * lambda2[v]);
    if (tangential && !fixed[v]) {
      fields.tangential_u[v] = laplacian[v].dot(tu[v]);
      fields.tangential_v[v] = laplacian[v].dot(tv[v]);
    }
  }
  return fields;
}

std::vector<int32_t> folded_nodes(const GridGeometry& geometry, const std::vector<Vec3>& positions) {
  const DiskGrid& grid = geometry.grid();
  const auto interior = static_cast<size_t>(grid.interior_count);
  std::vector<Vec3> tu, tv, n;
  geometry.frames(positions, tu, tv, n);
  std::vector<uint8_t> mark(interior, 0);
  for (size_t v = 0; v < interior; ++v) {
    const auto [i, j] = grid.cell[v];
    for (const auto& [di, dj] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
      const int32_t u = grid.node(i + di, j + dj);
      if (u >= 0 && n[v].dot(n[static_cast<size_t>(u)]) < 0.5) mark[v] = 1;  // more than 60° apart
    }
  }
  // Two rings around them (measured on ICT: one ring left 1.3% RMS, two reached the floor).
  for (int ring = 0; ring < 2; ++ring) {
    std::vector<uint8_t> grown = mark;
    for (size_t v = 0; v < interior; ++v) {
      if (!mark[v]) continue;
      const auto [i, j] = grid.cell[v];
      for (int dj = -1; dj <= 1; ++dj) {
        for (int di = -1; di <= 1; ++di) {
          const int32_t u = grid.node(i + di, j + dj);
          if (u >= 0) grown[static_cast<size_t>(u)] = 1;
        }
      }
    }
    mark = std::move(grown);
  }
  std::vector<int32_t> out;
  for (size_t v = 0; v < interior; ++v) {
    if (mark[v]) out.push_back(static_cast<int32_t>(v));
  }
  return out;
}

GridFields combine_fields(const std::vector<const GridFields*>& keys, const std::vector<double>& weights) {
  if (keys.empty() || keys.size() != weights.size()) throw Error(ErrorCode::kInvalidArgument, "combine_fields: one weight per key needed");
  const GridFields& first = *keys[0];
  GridFields out = first;
  auto scale = [](auto& values, double w) {
    for (auto& v : values) v *= w;
  };
  auto add = [](auto& into, const auto& from, double w) {
    for (size_t i = 0; i < into.size(); ++i) into[i] += w * from[i];
  };
  scale(out.mean_curvature, weights[0]);
  scale(out.log_conformal_factor, weights[0]);
  scale(out.tangential_u, weights[0]);
  scale(out.tangential_v, weights[0]);
  scale(out.fixed_laplacian, weights[0]);
  scale(out.positions, weights[0]);
  scale(out.rim, weights[0]);
  for (size_t k = 1; k < keys.size(); ++k) {
    const GridFields& key = *keys[k];
    if (key.representation != first.representation || key.grid_n != first.grid_n || key.rim.size() != first.rim.size() ||
        key.mean_curvature.size() != first.mean_curvature.size() || key.positions.size() != first.positions.size() ||
        key.fixed_nodes != first.fixed_nodes || key.tangential_u.size() != first.tangential_u.size()) {
      throw Error(ErrorCode::kInvalidArgument, "combine_fields: keyframes of different representations or grids");
    }
    add(out.mean_curvature, key.mean_curvature, weights[k]);
    add(out.log_conformal_factor, key.log_conformal_factor, weights[k]);
    add(out.tangential_u, key.tangential_u, weights[k]);
    add(out.tangential_v, key.tangential_v, weights[k]);
    add(out.fixed_laplacian, key.fixed_laplacian, weights[k]);
    add(out.positions, key.positions, weights[k]);
    add(out.rim, key.rim, weights[k]);
  }
  return out;
}

namespace {

std::vector<double> round_trip(const std::vector<double>& values) { return format::dequantize16(format::quantize16(values)); }

std::vector<Vec3> round_trip(const std::vector<Vec3>& values) {
  std::vector<Vec3> out(values.size());
  for (int k = 0; k < 3; ++k) {
    std::vector<double> component(values.size());
    for (size_t i = 0; i < values.size(); ++i) component[i] = values[i][k];
    const std::vector<double> back = round_trip(component);
    for (size_t i = 0; i < values.size(); ++i) out[i][k] = back[i];
  }
  return out;
}

}  // namespace

GridFields quantize_fields(const GridFields& fields) {
  GridFields q = fields;
  q.mean_curvature = round_trip(fields.mean_curvature);
  q.log_conformal_factor = round_trip(fields.log_conformal_factor);
  q.tangential_u = round_trip(fields.tangential_u);
  q.tangential_v = round_trip(fields.tangential_v);
  q.fixed_laplacian = round_trip(fields.fixed_laplacian);  // its own range: rim values are huge
  q.positions = round_trip(fields.positions);
  q.rim = round_trip(fields.rim);
  return q;
}

}  // namespace facemorph
