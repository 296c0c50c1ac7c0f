// G's lattice as the keyframe coding predicts along it (file_layout.hpp).
#include "codec/core/container/file_layout.hpp"

#include "codec/core/grid/disk_grid.hpp"

#include <mutex>

namespace facemorph::file_layout {

std::shared_ptr<const GridFacts> grid_facts(int n) {
  static std::mutex mutex;
  static std::shared_ptr<const GridFacts> cached;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (cached && cached->n == n) return cached;
  }
  const DiskGrid grid = make_disk_grid(n);
  auto facts = std::make_shared<GridFacts>();
  facts->n = n;
  facts->hash = grid.hash;
  format::LatticeNeighbours& l = facts->all_nodes;
  for (int node = 0; node < grid.node_count(); ++node) {
    if (grid.is_rim(node)) {
      l.left.push_back(node - 1);
      l.up.push_back(-1);
      l.up_left.push_back(-1);
      continue;
    }
    const auto [i, j] = grid.cell[static_cast<size_t>(node)];
    l.left.push_back(grid.node(i - 1, j));
    l.up.push_back(grid.node(i, j - 1));
    l.up_left.push_back(grid.node(i - 1, j - 1));
  }
  const auto interior = static_cast<ptrdiff_t>(grid.interior_count);
  facts->interior.left.assign(l.left.begin(), l.left.begin() + interior);
  facts->interior.up.assign(l.up.begin(), l.up.begin() + interior);
  facts->interior.up_left.assign(l.up_left.begin(), l.up_left.begin() + interior);
  facts->interior_levels = format::level_order(grid.cell, grid.node_at, grid.n);
  std::lock_guard<std::mutex> lock(mutex);
  cached = std::move(facts);
  return cached;
}

}  // namespace facemorph::file_layout
