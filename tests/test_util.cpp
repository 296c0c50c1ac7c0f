#include "tests/test_util.hpp"

#include <map>

namespace facemorph::testing {

SparseMatrix shifted_grid_laplacian(int n, double shift) {
  std::vector<Eigen::Triplet<double>> entries;
  const auto at = [n](int i, int j) { return i * n + j; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      double degree = 0;
      for (const auto& [di, dj] : {std::pair{1, 0}, {-1, 0}, {0, 1}, {0, -1}}) {
        const int k = i + di, l = j + dj;
        if (k < 0 || k >= n || l < 0 || l >= n) continue;
        entries.emplace_back(at(i, j), at(k, l), -1.0);
        degree += 1;
      }
      entries.emplace_back(at(i, j), at(i, j), degree + shift);
    }
  SparseMatrix A(n * n, n * n);
  A.setFromTriplets(entries.begin(), entries.end());
  return A;
}

TriangleMesh icosphere(double radius, int subdivisions) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleMesh m;
  m.positions = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                 {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
             {3, 9, 4},  {3, 4, 2}, {3, 2, 6}, {3, 6, 8},  {3, 8, 9},   {4, 9, 5}, {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (Vec3& p : m.positions) p.normalize();
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int32_t> midpoint;
    auto mid = [&](int32_t a, int32_t b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      m.positions.push_back((m.positions[static_cast<size_t>(a)] + m.positions[static_cast<size_t>(b)]).normalized());
      const auto index = static_cast<int32_t>(m.positions.size() - 1);
      midpoint.emplace(key, index);
      return index;
    };
    std::vector<Face> next;
    for (const Face& f : m.faces) {
      const int32_t a = mid(f[0], f[1]), b = mid(f[1], f[2]), c = mid(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    m.faces = std::move(next);
  }
  for (Vec3& p : m.positions) p *= radius;
  return m;
}

}  // namespace facemorph::testing
