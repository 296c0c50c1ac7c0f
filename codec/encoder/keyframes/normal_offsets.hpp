// The selection's inner loop (Predictor, keyframe_selection.cpp): how far a frame predicted from
// its keyframes lies from the frame, along the frame's normals, at every node of the selection grid.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/sequence/pose.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <span>

namespace facemorph {

// offsets[v] = (pose.apply(Σ_i weights[i] · keys[i][v]) − world[v]) · normals[v] for v < count, with
// each sum, product and the pose's arithmetic in the order of the Eigen expression
//   (pose.apply(local) - world[v]).dot(normal)   (normal: normals[v] as a Vec3, SelectionFrame::normal_at)
// with local accumulated key by key from zero (the same bits as that expression; a test checks it),
// in blocks of nodes whose arithmetic the compiler vectorises.
void predicted_normal_offsets(std::span<const Eigen::Vector3f* const> keys, std::span<const double> weights, const RigidPose& pose,
                              const Vec3* world, const Eigen::Vector3f* normals, size_t count, double* offsets);

}  // namespace facemorph
