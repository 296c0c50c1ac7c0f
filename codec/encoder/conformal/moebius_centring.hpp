// Centring a symmetric spherical map by a disk Möbius map: the gauge QIEM fixes after every step.
#pragma once

#include "codec/encoder/conformal/double_cover.hpp"

#include <Eigen/Core>

namespace facemorph {

// Centres a symmetric spherical map: finds the disk automorphism w -> (w - a)/(1 - ā w) (applied to
// copy 1 in stereographic coordinates, mirrored to copy 2) after which the area-weighted centroid
// of the image is the origin, and applies it. The map is only defined up to such automorphisms, so
// this fixes the gauge without changing the (continuum) energy. The radial projection
// (φ - c)/|φ - c| some codes use is not a Möbius map: it perturbed the energy by ~1e-7 per step
// and stalled the flow on real faces (spec/method.md §3.2). `p`: one unit vector per double-cover
// vertex; `areas`: one area per vertex.
void centre_by_moebius(Eigen::MatrixXd& p, const Eigen::VectorXd& areas, const DoubleCover& cover);

}  // namespace facemorph
