// Boundary samples for the GMF: the circle's correspondence, known only at the rim markers,
// filled in angle-linearly between them.
#include "codec/encoder/registration/registration_internal.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace facemorph {

BoundarySamples boundary_samples(const CheckedLandmarks& landmarks, const DiskMoebius& m, double spacing) {
  BoundarySamples out;
  if (!(spacing > 0)) return out;
  const size_t r = landmarks.rim.size();
  // Marker angles after m (alpha) and on the frame (beta), in the reference's cyclic order, which
  // m keeps. The offset beta - alpha of marker k+1 follows from marker k's by the two gaps, so the
  // offsets stay on one branch all the way round (check_landmarks made the frame gaps sum to 2π).
  std::vector<double> alpha(r), gap(r), offset(r);
  for (size_t k = 0; k < r; ++k) {
    const size_t j = static_cast<size_t>(landmarks.rim[k]);
    alpha[k] = std::arg(m(landmarks.p[j]));
  }
  for (size_t k = 0; k < r; ++k) {
    const size_t j = static_cast<size_t>(landmarks.rim[k]), next = static_cast<size_t>(landmarks.rim[(k + 1) % r]);
    gap[k] = r == 1 ? kTwoPi : ccw_gap(alpha[k], alpha[(k + 1) % r]);
    const double frame_gap = r == 1 ? kTwoPi : ccw_gap(std::arg(landmarks.q[j]), std::arg(landmarks.q[next]));
    if (k == 0) offset[0] = std::remainder(std::arg(landmarks.q[j]) - alpha[0], kTwoPi);
    if (k + 1 < r) offset[k + 1] = offset[k] + frame_gap - gap[k];
  }

  const int count = std::max(3, static_cast<int>(std::lround(kTwoPi / spacing)));
  const double step = kTwoPi / count;
  for (int s = 0; s < count; ++s) {
    const double psi = s * step;
    const Complex centre = std::polar(1.0, psi);
    // A sample next to a landmark's centre nearly duplicates it: the interpolation system would be
    // ill-conditioned for no gain.
    bool near = false;
    for (size_t j = 0; j < landmarks.p.size() && !near; ++j) near = std::abs(centre - m(landmarks.p[j])) < 0.25 * step;
    if (near) continue;
    // The segment starts at the last marker at or before psi counter-clockwise.
    double delta = 0;
    if (r > 0) {
      size_t k = 0;
      for (size_t i = 1; i < r; ++i) {
        if (ccw_gap(alpha[i], psi) < ccw_gap(alpha[k], psi)) k = i;
      }
      const double t = std::min(1.0, ccw_gap(alpha[k], psi) / gap[k]);
      delta = (1 - t) * offset[k] + t * offset[(k + 1) % r];
    }
    out.centres.push_back(to_vec2(centre));
    out.targets.push_back(to_vec2(delta == 0 ? centre : std::polar(1.0, psi + delta)));
  }
  return out;
}

}  // namespace facemorph
