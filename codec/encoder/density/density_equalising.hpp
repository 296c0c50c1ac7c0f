// A reparametrisation of the reference frame's disk that spreads its surface area more evenly over
// the disk (issue 8, item 10; spec/method.md §7.11).
//
// The conformal map crowds: a nose, a nostril pocket or a neck rim takes a tiny patch of the disk,
// so a uniform grid G samples it coarsely and the resampling floor there dominates. `hl+t` fields
// decode any parametrisation of the disk, so the encoder may sample the registered surfaces on G
// through a map D⁻¹ of the disk onto itself chosen to balance area: the density-equalising map of
// Choi & Rycroft (2018), a diffusion of the area density ρ = A_surface / A_disk on the disk mesh
// whose flow v = -∇ρ/ρ carries the vertices until ρ is uniform. Partially: ρ is taken to the power
// `strength` (0 keeps the conformal map, 1 aims at an equal-area map), since full equalisation
// trades crowding for shear.
//
// The rim stays on the circle (its vertices slide along it), the map stays a bijection with no
// sliver (a step that would squeeze a triangle of the flow's grid too thin is halved, and the flow
// stops if it cannot go on), and the decoder needs nothing: it never sees D.
#pragma once

#include "codec/encoder/conformal/conformal.hpp"
#include "codec/meshkit/geometry/locator.hpp"

#include <memory>
#include <span>
#include <vector>

namespace facemorph {

// Radial strength "auto": 1 where the reference's conformal disk holds half the surface within
// kCrowdedHalfAreaRadius of its centre (a whole head whose rim is the neck), else 0.
constexpr double kAutoRadial = -1;
constexpr double kCrowdedHalfAreaRadius = 0.25;

struct DensityEqualisingOptions {
  double strength = 0.5;  // exponent of the density equalised, in [0, 1]; 0: the identity
  double step = 0.05;     // diffusion time step (disk of area π)
  int max_steps = 100;
  double tolerance = 1e-2;  // stop when the vertex density's coefficient of variation is below this
  // The radial reparametrisation's strength (DiskReparametrisation::radial) where `strength` is 0:
  // in [0, 1] (0: none), or kAutoRadial (fmenc --radial-equalising).
  double radial = kAutoRadial;
};

struct DensityEqualisingReport {
  int steps = 0;
  // Coefficient of variation of the area density (to the power strength) over the flow grid's triangles.
  double variation_before = 0, variation_after = 0;
  bool stopped_early = false;  // a step could not keep every triangle well shaped
  // The radial reparametrisation (DiskReparametrisation::radial): the conformal disk's radius that
  // holds half the surface's area, and after it (sqrt(1/2) for an equal-area one). 0: not radial.
  double half_area_radius_before = 0, half_area_radius_after = 0;
};

// The radius of the disk about its centre that holds half the surface's area in `map` (each face's
// area spread evenly over the span of its vertices' radii). About 0.5-0.7 for a face with its nose at
// the centre; a whole head, whose rim is the neck, holds half its area within a few hundredths.
double half_area_radius(const DiskMap& map);

// D⁻¹: points of the equalised disk (where G's nodes are) to points of the reference's conformal
// disk. The identity when default-constructed or built with strength 0.
class DiskReparametrisation {
 public:
  DiskReparametrisation() = default;
  // Throws kInvalidArgument for a strength outside [0, 1].
  DiskReparametrisation(const DiskMap& reference, const DensityEqualisingOptions& options);

  bool identity() const { return !mesh_ && !radial_; }
  const DensityEqualisingReport& report() const { return report_; }

  // A radial map g -> g r(|g|)/|g| that equalises the surface's area by radius, to the power
  // `strength` in (0, 1] (as the flow's density): the crowding of a whole head is radial (the face
  // at the centre, the neck a tube that the conformal map shrinks towards the rim by about e per
  // radius of its length), and a radial map removes it without the flow's shear or slivers.
  // spec/method.md §7.11.
  static DiskReparametrisation radial(const DiskMap& reference, double strength);

  // Any |g| <= 1 (+1e-9); the circle onto the circle.
  Vec2 operator()(const Vec2& g) const;
  std::vector<Vec2> operator()(std::span<const Vec2> points) const;

 private:
  struct Mesh {
    std::vector<Vec2> conformal, equalised;  // per vertex
    std::vector<Face> faces;
    std::vector<double> rim_angle;            // equalised rim vertices' angles, sorted, in [0, 2π)
    std::vector<double> rim_conformal_angle;  // the same vertices' conformal angles, unwrapped to increase
    std::unique_ptr<TriangleLocator> locator;
  };
  std::shared_ptr<const Mesh> mesh_;
  std::shared_ptr<const std::vector<double>> radial_;  // conformal radius at equalised radius k/(size-1)
  DensityEqualisingReport report_;
};

}  // namespace facemorph
