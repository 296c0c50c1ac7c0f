// Discrete differential geometry on triangle meshes (method-notes §1, spec/method.md §1): the
// operators the reconstruction needs, and the vertex normals every side shows. Measures only the encoder and the tools use (angles,
// normals, mean curvature, ...) are meshkit's, in codec/meshkit/geometry/surface_measures.hpp.
//
// Sign conventions, used everywhere in facemorph:
//  * K is the positive semidefinite cotangent Laplacian: K_ij = -w_ij, K_ii = sum_j w_ij,
//    w_ij = (cot a_ij + cot b_ij) / 2. Dirichlet energy E(f) = f^T K f / 2.
//  * The Laplace-Beltrami operator is (Δx)_i = -(K x)_i / A_i with A_i the mixed Voronoi area.
//  * Δx = 2 H n: H is positive where the surface bends towards its normal; a sphere with outward
//    normals has H = -1/R.
#pragma once

#include "codec/core/geometry/mesh.hpp"

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

// Cotangent of the angle at each corner of each face.
std::vector<CornerValues> corner_cotangents(std::span<const Vec3> positions, std::span<const Face> faces);

// K from per-corner cotangents: corner k of face f weights the edge opposite it by cot/2.
SparseMatrix laplacian_from_cotangents(std::span<const Face> faces, std::span<const CornerValues> cotangents, int vertex_count);
SparseMatrix cotangent_laplacian(std::span<const Vec3> positions, std::span<const Face> faces);

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c);
// Mixed Voronoi vertex areas (Meyer et al. 2003); sums to the total area.
Eigen::VectorXd mixed_voronoi_areas(std::span<const Vec3> positions, std::span<const Face> faces);

// Area-weighted unit vertex normals (Σ over the vertex's triangles of (b − a) × (c − a), then
// normalised) as 3 floats per vertex into `out` (3 × positions.size()); zero for a vertex that
// touches no triangle of non-zero area. Throws kInvalidArgument for a face index out of range or
// a wrong output size.
void area_weighted_normals(std::span<const Vec3> positions, std::span<const Face> faces, std::span<float> out);

}  // namespace facemorph
