#include "facemorph/disk_grid.hpp"

#include "facemorph/error.hpp"

#include "codec/geometry/delaunay.hpp"

#include <cmath>
#include <numbers>

namespace facemorph {

double DiskGrid::rim_angle(int k) const { return 2 * std::numbers::pi * k / rim_count; }

DiskGrid make_disk_grid(int n, int rim_samples) {
  if (n < 5 || n > 8193) throw Error(ErrorCode::kInvalidArgument, "grid size N must be in [5, 8193], got " + std::to_string(n));
  if (rim_samples != 0 && rim_samples < 8) throw Error(ErrorCode::kInvalidArgument, "at least 8 rim samples are needed");
  DiskGrid grid;
  grid.n = n;
  grid.h = 2.0 / (n - 1);
  grid.node_at.assign(static_cast<size_t>(n) * n, -1);
  const double limit = 1.0 - 0.5 * grid.h;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Vec2 w(-1 + i * grid.h, -1 + j * grid.h);
      if (w.norm() > limit) continue;
      grid.node_at[static_cast<size_t>(j) * n + i] = static_cast<int32_t>(grid.nodes.size());
      grid.nodes.push_back(w);
      grid.cell.push_back({i, j});
    }
  }
  grid.interior_count = static_cast<int>(grid.nodes.size());
  grid.rim_count = rim_samples > 0 ? rim_samples : std::max(8, static_cast<int>(std::lround(2 * std::numbers::pi / grid.h)));
  for (int k = 0; k < grid.rim_count; ++k) {
    const double a = grid.rim_angle(k);
    grid.nodes.emplace_back(std::cos(a), std::sin(a));
  }
  // The grid's squares are cocircular; a deterministic perturbation far below the node spacing
  // breaks the ties for the triangulation only (the nodes keep their exact positions).
  std::vector<Vec2> perturbed = grid.nodes;
  uint64_t state = 0x9E3779B97F4A7C15ull;
  for (Vec2& p : perturbed) {
    auto next = [&state] {
      state ^= state << 13;
      state ^= state >> 7;
      state ^= state << 17;
      return static_cast<double>(state >> 11) / 9007199254740992.0 - 0.5;
    };
    p += 1e-7 * grid.h * Vec2(next(), next());
  }
  grid.faces = delaunay_triangulation(perturbed);
  return grid;
}

}  // namespace facemorph
