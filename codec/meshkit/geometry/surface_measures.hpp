// Measures of a triangle mesh the encoder and the tools use and a player does not: corner angles,
// intrinsic cotangents, face and vertex areas, normals, volume, mean curvature. The sign conventions
// (K, Δ, H) are those of codec/core/geometry/differential.hpp, whose operators the decoder keeps.
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/mesh.hpp"

#include <Eigen/Core>

#include <span>
#include <vector>

namespace facemorph {

// Interior angle (radians) at each corner of each face.
std::vector<CornerValues> corner_angles(std::span<const Vec3> positions, std::span<const Face> faces);

// Cotangent of the angle at each corner from intrinsic edge lengths (lengths[f][k] is the length of
// the edge opposite corner k).
std::vector<CornerValues> corner_cotangents_from_lengths(std::span<const CornerValues> lengths);

std::vector<double> face_areas(std::span<const Vec3> positions, std::span<const Face> faces);
double total_area(std::span<const Vec3> positions, std::span<const Face> faces);
// Signed enclosed volume (divergence theorem); meaningful for closed, consistently oriented meshes.
double signed_volume(std::span<const Vec3> positions, std::span<const Face> faces);

// One third of the area of each incident face.
Eigen::VectorXd barycentric_areas(std::span<const Vec3> positions, std::span<const Face> faces);

// Unit face normals ((b-a) x (c-a), normalised; zero for degenerate faces).
std::vector<Vec3> face_normals(std::span<const Vec3> positions, std::span<const Face> faces);
// Angle-weighted unit vertex normals; zero for vertices with no non-degenerate face.
std::vector<Vec3> vertex_normals(std::span<const Vec3> positions, std::span<const Face> faces);

// Signed mean curvature per vertex, H_i = <(Δx)_i, n_i> / 2 with angle-weighted normals and mixed
// areas. At boundary vertices the one-ring is incomplete, so H there is the mean over interior
// neighbours (0 when a boundary vertex has none). `is_boundary` has one flag per vertex.
Eigen::VectorXd mean_curvature(std::span<const Vec3> positions, std::span<const Face> faces, const std::vector<bool>& is_boundary);

// The per-vertex mean-curvature vector Δx (length 2|H|), before projection on the normal.
std::vector<Vec3> laplace_beltrami_of_positions(std::span<const Vec3> positions, std::span<const Face> faces);

}  // namespace facemorph
