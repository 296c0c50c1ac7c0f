// Untangling a disk map: the vertices around flipped faces re-solved with mean-value weights.
#include "codec/encoder/conformal/untangle.hpp"

#include "codec/core/geometry/differential.hpp"
#include "format/error.hpp"

#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace facemorph {
namespace {

// Mean-value weights (Floater 2003) of the edges at vertex i, from the surface's angles: always
// positive, so with a fixed convex border the solution is an embedding (Tutte-Floater).
void add_mean_value_row(const TriangleMesh& surface, const std::vector<std::vector<int>>& faces_of, int i,
                        std::vector<std::pair<int, double>>& row) {
  row.clear();
  for (int f : faces_of[static_cast<size_t>(i)]) {
    const Face& t = surface.faces[static_cast<size_t>(f)];
    int k = 0;
    while (t[k] != i) ++k;
    const int j = t[(k + 1) % 3], l = t[(k + 2) % 3];
    const Vec3& p = surface.positions[static_cast<size_t>(i)];
    const Vec3 a = surface.positions[static_cast<size_t>(j)] - p, b = surface.positions[static_cast<size_t>(l)] - p;
    const double half_tan = std::tan(0.5 * angle_between(a, b));
    row.push_back({j, half_tan / std::max(a.norm(), 1e-300)});
    row.push_back({l, half_tan / std::max(b.norm(), 1e-300)});
  }
}

}  // namespace

int count_flipped(const std::vector<Vec2>& w, const std::vector<Face>& faces) {
  int flipped = 0;
  for (const Face& f : faces) {
    flipped += signed_area(w[static_cast<size_t>(f[0])], w[static_cast<size_t>(f[1])], w[static_cast<size_t>(f[2])]) <= 0;
  }
  return flipped;
}

int untangle(DiskMap& map) {
  const auto& faces = map.surface.faces;
  const int n = map.surface.vertex_count();
  std::vector<std::vector<int>> faces_of(static_cast<size_t>(n));
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int32_t v : faces[f]) faces_of[static_cast<size_t>(v)].push_back(static_cast<int>(f));
  }
  std::vector<uint8_t> on_rim(static_cast<size_t>(n), 0);
  for (int v : map.rim) on_rim[static_cast<size_t>(v)] = 1;
  auto flipped_faces = [&] {
    std::vector<int> out;
    for (size_t f = 0; f < faces.size(); ++f) {
      if (signed_area(map.disk[static_cast<size_t>(faces[f][0])], map.disk[static_cast<size_t>(faces[f][1])],
                      map.disk[static_cast<size_t>(faces[f][2])]) <= 0)
        out.push_back(static_cast<int>(f));
    }
    return out;
  };
  std::vector<int> flipped = flipped_faces();
  int moved = 0;
  std::vector<std::pair<int, double>> row;
  for (int rings = 1; !flipped.empty(); rings *= 2) {
    // Grow the patch ring by ring from the flipped faces' vertices.
    std::vector<int> in_patch(static_cast<size_t>(n), -1);
    std::vector<int> patch;
    for (int f : flipped) {
      for (int32_t v : faces[static_cast<size_t>(f)]) {
        if (in_patch[static_cast<size_t>(v)] < 0 && !on_rim[static_cast<size_t>(v)]) {
          in_patch[static_cast<size_t>(v)] = static_cast<int>(patch.size());
          patch.push_back(v);
        }
      }
    }
    const bool whole = rings >= n;
    for (size_t begin = 0, ring = 0; (whole || ring < static_cast<size_t>(rings)) && begin < patch.size(); ++ring) {
      const size_t end = patch.size();
      for (size_t k = begin; k < end; ++k) {
        for (int f : faces_of[static_cast<size_t>(patch[k])]) {
          for (int32_t v : faces[static_cast<size_t>(f)]) {
            if (in_patch[static_cast<size_t>(v)] < 0 && !on_rim[static_cast<size_t>(v)]) {
              in_patch[static_cast<size_t>(v)] = static_cast<int>(patch.size());
              patch.push_back(v);
            }
          }
        }
      }
      begin = end;
    }
    const auto m = static_cast<Eigen::Index>(patch.size());
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(m, 2);
    for (Eigen::Index r = 0; r < m; ++r) {
      add_mean_value_row(map.surface, faces_of, patch[static_cast<size_t>(r)], row);
      double diagonal = 0;
      for (const auto& [j, w] : row) {
        diagonal += w;
        const int c = in_patch[static_cast<size_t>(j)];
        if (c >= 0)
          triplets.emplace_back(r, c, -w);
        else
          rhs.row(r) += w * map.disk[static_cast<size_t>(j)].transpose();
      }
      triplets.emplace_back(r, r, diagonal);
    }
    SparseMatrix A(m, m);
    A.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SparseLU<SparseMatrix> solver(A);  // mean-value weights are not symmetric
    if (solver.info() != Eigen::Success) throw Error(ErrorCode::kNumerical, "untangling the disk map: singular patch system");
    const Eigen::MatrixXd x = solver.solve(rhs);
    for (Eigen::Index r = 0; r < m; ++r) map.disk[static_cast<size_t>(patch[static_cast<size_t>(r)])] = x.row(r).transpose();
    moved = std::max(moved, static_cast<int>(m));
    flipped = flipped_faces();
    if (whole && !flipped.empty()) throw Error(ErrorCode::kNumerical, "untangling the disk map failed even on the whole disk");
  }
  return moved;
}

void finish_disk_map(DiskMap& map, std::vector<Vec2> fallback_disk) {
  const std::vector<int> rim = map.rim;
  auto finish = [&] {
    map.rim = rim;
    double total = 0;
    for (const Face& f : map.surface.faces) {
      total += signed_area(map.disk[static_cast<size_t>(f[0])], map.disk[static_cast<size_t>(f[1])], map.disk[static_cast<size_t>(f[2])]);
    }
    if (total < 0) {
      for (Vec2& p : map.disk) p.y() = -p.y();  // w -> conj(w): orientation-preserving
      std::reverse(map.rim.begin(), map.rim.end());
    }
    map.report.flipped_triangles = count_flipped(map.disk, map.surface.faces);
    map.report.untangled_vertices = untangle(map);
  };
  try {
    finish();
  } catch (const Error& e) {
    if (fallback_disk.empty()) throw;
    map.disk = std::move(fallback_disk);
    map.report.method = ConformalMethod::kLinear;
    map.report.fallback_reason = std::string("the disk could not be untangled (") + e.what() + ")";
    finish();
  }
}

}  // namespace facemorph
