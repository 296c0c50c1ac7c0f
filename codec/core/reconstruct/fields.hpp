// What a keyframe stores on the shared disk grid G (spec/method.md §5.2-5.3): the fields of one
// surface, how they are computed (with the decoder's own operators, so a keyframe decodes to its
// resampled surface), validated, blended between keyframes and quantised.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/util/enum_names.hpp"

#include <cstdint>

#include <string>
#include <vector>

namespace facemorph {

enum class Representation {
  kHL,   // the paper's: mean curvature H and log λ
  kHLT,  // H, log λ and the tangential part (a, b) of Δ_h S; Cartesian Δ_h S in the rim band
  kXYZ,  // positions
};
// Each representation's name (settings, command lines) and the number the header stores (spec/container.md §5).
inline constexpr CodedEnumName<Representation, uint8_t> kRepresentations[] = {
    {Representation::kHL, "hl", 0}, {Representation::kHLT, "hl+t", 1}, {Representation::kXYZ, "xyz", 2}};
static_assert(is_one_to_one(kRepresentations));
const char* representation_name(Representation representation);  // "hl", "hl+t", "xyz"
Representation parse_representation(const std::string& name);    // throws kInvalidArgument

// What one surface stores on G, dequantised (spec/method.md §5.2).
struct GridFields {
  Representation representation = Representation::kHLT;
  int grid_n = 0;
  std::vector<double> mean_curvature;        // H per interior node (hl, hl+t; 0 at fixed-frame nodes for hl+t)
  std::vector<double> log_conformal_factor;  // log λ per interior node (hl, hl+t)
  std::vector<double> tangential_u;          // a = <Δ_h S, t_u> per interior node (hl+t; 0 at fixed-frame nodes)
  std::vector<double> tangential_v;          // b = <Δ_h S, t_v>
  // hl+t: the nodes whose Δ_h S is stored in a boundary frame instead (sorted): the rim band, plus
  // any crowded nodes the encoder adds; and those vectors' components in their boundary frames.
  std::vector<int32_t> fixed_nodes;
  std::vector<Vec3> fixed_laplacian;
  std::vector<Vec3> positions;  // per interior node (xyz)
  std::vector<Vec3> rim;        // the boundary curve: positions at the rim nodes
};

// Checks that `fields` is what its representation promises for its grid (spec/method.md §5.2):
// N in range; the rim's length; the arrays of the representation sized to G's interior and the
// others empty; fixed nodes strictly increasing, inside the interior, one vector each; every value
// finite. Throws kInvalidArgument naming the array and the defect. Every consumer calls it: the
// reconstruction, blending, quantisation and the container reader (which reports kCorrupt).
void validate_fields(const GridFields& fields);

// Every scalar array of `fields` in the order a keyframe stores them, vectors split into their
// x, y, z components: H, log λ, a, b, the fixed-frame vectors, positions, the rim. Empty arrays
// (not used by the representation) are included, so the list has the same length for every
// representation.
std::vector<std::vector<double>> scalar_arrays(const GridFields& fields);
inline constexpr size_t kScalarArrayCount = 13;

// The inverse of scalar_arrays: fields of `representation` on grid N from kScalarArrayCount arrays in
// that order, with the fixed nodes they were stored with. Checks nothing beyond the array count
// (kInvalidArgument): validate_fields says whether the result is what the representation promises.
GridFields fields_from_scalar_arrays(Representation representation, int grid_n, std::vector<int32_t> fixed_nodes,
                                     const std::vector<std::vector<double>>& arrays);

// The fields of a surface sampled at every node of G (interior nodes, then rim nodes). For hl+t,
// `extra_fixed_nodes` are stored in boundary frames like the band (see folded_nodes); keyframes to
// be blended must share them, so a sequence passes the union over its keyframes.
GridFields compute_fields(const GridGeometry& geometry, const std::vector<Vec3>& positions, Representation representation,
                          const std::vector<int32_t>& extra_fixed_nodes = {});

// Interior nodes where the sampled surface folds at the grid's resolution — a grid neighbour's normal
// more than 60° away (90° misses a fold along a grid line, whose own normal lies sideways) — and
// the two rings around them. There (ICT's closed-lip grooves, thinner than
// a grid cell) the frame-dependent equations have a second solution the decoder converges to
// (measured: 2.4% RMS instead of 0.17%); stored in boundary frames, their equations are linear.
std::vector<int32_t> folded_nodes(const GridGeometry& geometry, const std::vector<Vec3>& positions);

// Σ weights[k] · fields of keys[k], field by field (log λ in log space, band vectors in their band
// frames, the boundary curve point by point): how keyframes are interpolated. The keys must be
// valid and share the representation, grid and fixed nodes (kInvalidArgument otherwise); weights
// need not sum to 1 (spline extrapolation).
GridFields combine_fields(const std::vector<const GridFields*>& keys, const std::vector<double>& weights);

// Rounds every field to 16 bits (fixed point over its own [min, max]; the band separately from
// the interior) and back: what a container keyframe holds (spec/method.md §5.3). Validates first.
GridFields quantize_fields(const GridFields& fields);

}  // namespace facemorph
