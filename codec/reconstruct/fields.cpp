// What a keyframe stores on G, computed with the decoder's own operators.
#include "facemorph/error.hpp"
#include "facemorph/reconstruct.hpp"

#include "format/quantize.hpp"

#include <cmath>

namespace facemorph {

GridFields compute_fields(const GridGeometry& geometry, const std::vector<Vec3>& positions, Representation representation) {
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
  const std::vector<std::array<Vec3, 3>> band_frame = tangential ? geometry.band_frames(fields.rim) : std::vector<std::array<Vec3, 3>>{};
  fields.mean_curvature.resize(interior);
  fields.log_conformal_factor.resize(interior);
  if (tangential) {
    fields.tangential_u.assign(interior, 0.0);
    fields.tangential_v.assign(interior, 0.0);
    fields.band_laplacian.resize(static_cast<size_t>(geometry.band_count()));
  }
  for (size_t v = 0; v < interior; ++v) {
    // Δ_h S = 2 H λ² n + a t_u + b t_v: H from the normal part (sign: spec/method.md §1).
    fields.log_conformal_factor[v] = 0.5 * std::log(lambda2[v]);
    const bool band = tangential && geometry.in_band(static_cast<int>(v));
    fields.mean_curvature[v] = band ? 0.0 : laplacian[v].dot(n[v]) / (2 * lambda2[v]);
    if (!tangential) continue;
    if (band) {
      const auto b = static_cast<size_t>(geometry.band_index(static_cast<int>(v)));
      fields.band_laplacian[b] = Vec3(laplacian[v].dot(band_frame[b][0]), laplacian[v].dot(band_frame[b][1]), laplacian[v].dot(band_frame[b][2]));
    } else {
      fields.tangential_u[v] = laplacian[v].dot(tu[v]);
      fields.tangential_v[v] = laplacian[v].dot(tv[v]);
    }
  }
  return fields;
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
  scale(out.band_laplacian, weights[0]);
  scale(out.positions, weights[0]);
  scale(out.rim, weights[0]);
  for (size_t k = 1; k < keys.size(); ++k) {
    const GridFields& key = *keys[k];
    if (key.representation != first.representation || key.grid_n != first.grid_n || key.rim.size() != first.rim.size() ||
        key.mean_curvature.size() != first.mean_curvature.size() || key.positions.size() != first.positions.size() ||
        key.band_laplacian.size() != first.band_laplacian.size() || key.tangential_u.size() != first.tangential_u.size()) {
      throw Error(ErrorCode::kInvalidArgument, "combine_fields: keyframes of different representations or grids");
    }
    add(out.mean_curvature, key.mean_curvature, weights[k]);
    add(out.log_conformal_factor, key.log_conformal_factor, weights[k]);
    add(out.tangential_u, key.tangential_u, weights[k]);
    add(out.tangential_v, key.tangential_v, weights[k]);
    add(out.band_laplacian, key.band_laplacian, weights[k]);
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
  q.band_laplacian = round_trip(fields.band_laplacian);  // its own range: rim values are huge
  q.positions = round_trip(fields.positions);
  q.rim = round_trip(fields.rim);
  return q;
}

}  // namespace facemorph
