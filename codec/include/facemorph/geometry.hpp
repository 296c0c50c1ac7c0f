// Discrete differential geometry on triangle meshes (method-notes §1, spec/method.md §1).
//
// Sign conventions, used everywhere in facemorph:
//  * K is the positive semidefinite cotangent Laplacian: K_ij = -w_ij, K_ii = sum_j w_ij,
//    w_ij = (cot a_ij + cot b_ij) / 2. Dirichlet energy E(f) = f^T K f / 2.
//  * The Laplace-Beltrami operator is (Δx)_i = -(K x)_i / A_i with A_i the mixed Voronoi area.
//  * Δx = 2 H n: H is positive where the surface bends towards its normal; a sphere with outward
//    normals has H = -1/R.
#pragma once

#include "facemorph/mesh.hpp"

#include <Eigen/Sparse>

#include <array>
#include <span>
#include <vector>

namespace facemorph {

using SparseMatrix = Eigen::SparseMatrix<double>;
using CornerValues = std::array<double, 3>;  // one value per corner of a face

// Cotangent of the angle between edge vectors a and b, with |a x b| clamped below at
// 1e-12 |a||b| so that degenerate triangles give large finite weights, never Inf/NaN.
double cotangent(const Vec3& a, const Vec3& b);

// Interior angle (radians) at each corner of each face.
std::vector<CornerValues> corner_angles(std::span<const Vec3> positions, std::span<const Face> faces);

// Cotangent of the angle at each corner, from positions or from intrinsic edge lengths
// (lengths[f][k] is the length of the edge opposite corner k).
std::vector<CornerValues> corner_cotangents(std::span<const Vec3> positions, std::span<const Face> faces);
std::vector<CornerValues> corner_cotangents_from_lengths(std::span<const CornerValues> lengths);

// K from per-corner cotangents: corner k of face f weights the edge opposite it by cot/2.
SparseMatrix laplacian_from_cotangents(std::span<const Face> faces, std::span<const CornerValues> cotangents,
                                       int vertex_count);
SparseMatrix cotangent_laplacian(std::span<const Vec3> positions, std::span<const Face> faces);

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);
std::vector<double> face_areas(std::span<const Vec3> positions, std::span<const Face> faces);
double total_area(std::span<const Vec3> positions, std::span<const Face> faces);
// Signed enclosed volume (divergence theorem); meaningful for closed, consistently oriented meshes.
double signed_volume(std::span<const Vec3> positions, std::span<const Face> faces);

// Mixed Voronoi vertex areas (Meyer et al. 2003); sums to the total area.
Eigen::VectorXd mixed_voronoi_areas(std::span<const Vec3> positions, std::span<const Face> faces);
// One third of the area of each incident face.
Eigen::VectorXd barycentric_areas(std::span<const Vec3> positions, std::span<const Face> faces);

// Unit face normals ((b-a) x (c-a), normalised; zero for degenerate faces).
std::vector<Vec3> face_normals(std::span<const Vec3> positions, std::span<const Face> faces);
// Angle-weighted unit vertex normals; zero for vertices with no non-degenerate face.
std::vector<Vec3> vertex_normals(std::span<const Vec3> positions, std::span<const Face> faces);

// Signed mean curvature per vertex, H_i = <(Δx)_i, n_i> / 2 with angle-weighted normals and mixed
// areas. At boundary vertices the one-ring is incomplete, so H there is the mean over interior
// neighbours (0 when a boundary vertex has none). `is_boundary` has one flag per vertex.
Eigen::VectorXd mean_curvature(std::span<const Vec3> positions, std::span<const Face> faces,
                               const std::vector<bool>& is_boundary);

// The per-vertex mean-curvature vector Δx (length 2|H|), before projection on the normal.
std::vector<Vec3> laplace_beltrami_of_positions(std::span<const Vec3> positions, std::span<const Face> faces);

}  // namespace facemorph
