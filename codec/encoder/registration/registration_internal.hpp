// The registration room's internals: checked landmarks, the boundary correspondence they carry,
// and the fits and checks register_disks builds on.
#pragma once

#include "codec/encoder/registration/registration.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace facemorph {

// What the registration (landmarks.cpp) and the geodesic frame (geodesic_path.cpp) refuse of the
// input they are handed: kInvalidArgument, the message prefixed with which of the two refuses it.
[[noreturn]] void refuse_registration_input(const std::string& what);
[[noreturn]] void refuse_geodesic_frame_input(const std::string& what);

inline constexpr double kTwoPi = 2 * std::numbers::pi;

// Angle from a to b going counter-clockwise, in [0, 2π) (radians).
inline double ccw_gap(double a, double b) {
  const double g = std::fmod(b - a, kTwoPi);
  return g < 0 ? g + kTwoPi : g;
}

// Landmarks as the fits use them: complex points, rim markers exactly on the circle, one weight each.
struct CheckedLandmarks {
  std::vector<Complex> p, q;    // reference disk, frame disk
  std::vector<double> w;        // ω >= 0
  std::vector<uint8_t> on_rim;  // one per landmark
  std::vector<int> rim;         // indices of the rim markers, by increasing reference angle
};

// Validates (kInvalidArgument naming the landmark and the reason) and normalises `landmarks`.
CheckedLandmarks check_landmarks(const DiskLandmarks& landmarks);

// The OMT on checked landmarks (fit_moebius without the check).
MoebiusFit fit_moebius_checked(const CheckedLandmarks& landmarks, const MoebiusFitOptions& options);

// check_bijection that stops at the first point failing register_disks' test, det Df <= 0 or an
// area ratio <= stop_ratio (then `stopped` is set and worst_point is that point): all a rejected
// GMF try needs, often at a small fraction of the cost.
BijectionCheck check_bijection_until(const DiskRegistration& f, int grid_size, double stop_ratio);

// Samples of the circle for the GMF, in the disk after the Möbius map m: centres every `spacing`
// radians of angle (skipping those within a quarter spacing of a landmark's image m(p), which is a
// centre itself), and their targets on the frame's circle. The target angle follows the rim
// markers angle-linearly: between consecutive markers the offset (frame angle - angle after m)
// is interpolated linearly in the angle after m; one marker gives a constant offset, none the
// Möbius map alone (zero displacement).
struct BoundarySamples {
  std::vector<Vec2> centres, targets;
};
BoundarySamples boundary_samples(const CheckedLandmarks& landmarks, const DiskMoebius& m, double spacing);

}  // namespace facemorph
