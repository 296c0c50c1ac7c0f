// Landmark validation: the one place the registration checks what the encoder hands it.
#include "codec/encoder/registration/registration_internal.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace facemorph {

void refuse_registration_input(const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "registration: " + what); }

CheckedLandmarks check_landmarks(const DiskLandmarks& landmarks) {
  const size_t n = landmarks.reference.size();
  if (landmarks.frame.size() != n) {
    refuse_registration_input(std::to_string(n) + " reference landmarks but " + std::to_string(landmarks.frame.size()) +
                              " frame landmarks");
  }
  if (!landmarks.weights.empty() && landmarks.weights.size() != n) {
    refuse_registration_input(std::to_string(landmarks.weights.size()) + " weights for " + std::to_string(n) + " landmarks");
  }
  if (!landmarks.on_rim.empty() && landmarks.on_rim.size() != n) {
    refuse_registration_input(std::to_string(landmarks.on_rim.size()) + " rim flags for " + std::to_string(n) + " landmarks");
  }
  // Three points fix a Möbius map up to the one real parameter the disk leaves free; fewer leave
  // the fit undetermined.
  if (n < 3) refuse_registration_input("needs at least 3 landmarks, got " + std::to_string(n));

  CheckedLandmarks out;
  out.p.resize(n);
  out.q.resize(n);
  out.w.assign(n, 1.0);
  out.on_rim.assign(n, 0);
  double total_weight = 0;
  for (size_t j = 0; j < n; ++j) {
    const std::string name = "landmark " + std::to_string(j);
    const bool rim = !landmarks.on_rim.empty() && landmarks.on_rim[j] != 0;
    Complex p = to_complex(landmarks.reference[j]), q = to_complex(landmarks.frame[j]);
    if (!std::isfinite(p.real()) || !std::isfinite(p.imag()) || !std::isfinite(q.real()) || !std::isfinite(q.imag())) {
      refuse_registration_input(name + " is not finite");
    }
    if (std::abs(p) > 1 + 1e-9)
      refuse_registration_input(name + " lies outside the unit disk on the reference disk (|p| = " + std::to_string(std::abs(p)) + ")");
    if (std::abs(q) > 1 + 1e-9)
      refuse_registration_input(name + " lies outside the unit disk on the frame disk (|q| = " + std::to_string(std::abs(q)) + ")");
    if (rim) {
      // A rim point interpolated on a boundary edge sits on its chord, ~1e-5 inside for rims of a
      // few hundred edges; farther in it is not a boundary point.
      if (std::abs(std::abs(p) - 1) > 1e-3 || std::abs(std::abs(q) - 1) > 1e-3)
        refuse_registration_input(name + " is a rim marker but does not lie on the circle");
      p /= std::abs(p);
      q /= std::abs(q);
    } else {
      if (std::abs(p) > 1) p /= std::abs(p);  // the 1e-9 of slack, back onto the closed disk
      if (std::abs(q) > 1) q /= std::abs(q);
    }
    if (!landmarks.weights.empty()) {
      const double w = landmarks.weights[j];
      if (!std::isfinite(w) || w < 0) refuse_registration_input(name + " has weight " + std::to_string(w) + " (needs a finite value >= 0)");
      out.w[j] = w;
    }
    total_weight += out.w[j];
    out.p[j] = p;
    out.q[j] = q;
    out.on_rim[j] = rim;
    if (rim) out.rim.push_back(static_cast<int>(j));
  }
  if (!(total_weight > 0)) refuse_registration_input("all landmark weights are zero");
  // Coincident centres make the interpolating spline singular, and one point cannot go two ways.
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      if (std::abs(out.p[i] - out.p[j]) <= 1e-12) {
        refuse_registration_input("landmarks " + std::to_string(i) + " and " + std::to_string(j) + " coincide on the reference disk");
      }
    }
  }

  std::sort(out.rim.begin(), out.rim.end(),
            [&](int a, int b) { return std::arg(out.p[static_cast<size_t>(a)]) < std::arg(out.p[static_cast<size_t>(b)]); });
  // A homeomorphism of the circle keeps the cyclic order: walking the markers in reference order,
  // the frame angles must go round exactly once.
  const size_t r = out.rim.size();
  if (r >= 2) {
    double turn = 0;
    for (size_t k = 0; k < r; ++k) {
      const double gap =
          ccw_gap(std::arg(out.q[static_cast<size_t>(out.rim[k])]), std::arg(out.q[static_cast<size_t>(out.rim[(k + 1) % r])]));
      if (gap == 0)
        refuse_registration_input("rim markers " + std::to_string(out.rim[k]) + " and " + std::to_string(out.rim[(k + 1) % r]) +
                                  " coincide on the frame disk");
      turn += gap;
    }
    if (std::abs(turn - kTwoPi) > std::numbers::pi)
      refuse_registration_input("rim markers are in a different cyclic order on the two disks");
  }
  return out;
}

}  // namespace facemorph
