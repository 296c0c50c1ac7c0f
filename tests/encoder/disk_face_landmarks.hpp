// What the registration tests share: a face's landmarks laid out on the reference disk, and the checks
// every registration of the disk must pass.
#pragma once

#include "codec/encoder/registration/registration.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace facemorph::testing {

// A face's landmarks on the reference disk (nose tip at 0, forehead up), about as the conformal map
// places them: midline, lips, mouth corners, eyes and lids, brows, cheeks, jaw, temples. The inner
// lips are 0.07 apart, the eyelids 0.09.
inline std::vector<Vec2> face_points() {
  return {{0, 0},          {0, 0.217},     {0, 0.35},        {0, 0.783},      {0, -0.583},     {0, -0.183},     {0, -0.23},
          {0, -0.30},      {0, -0.367},    {-0.192, -0.267}, {0.192, -0.267}, {-0.367, 0.325}, {-0.167, 0.325}, {-0.267, 0.371},
          {-0.267, 0.279}, {0.167, 0.325}, {0.367, 0.325},   {0.267, 0.371},  {0.267, 0.279},  {-0.133, 0.5},   {-0.417, 0.5},
          {0.133, 0.5},    {0.417, 0.5},   {-0.583, 0.117},  {0.583, 0.117},  {-0.35, -0.1},   {0.35, -0.1},    {-0.4, -0.45},
          {0.4, -0.45},    {-0.6, 0.45},   {0.6, 0.45}};
}

inline Vec2 on_circle(double angle) { return {std::cos(angle), std::sin(angle)}; }

// The face's points and, with `rim`, eight boundary markers rim_0..rim_7 from the top; frame = reference.
inline DiskLandmarks face(bool rim) {
  DiskLandmarks l;
  l.reference = face_points();
  l.on_rim.assign(l.reference.size(), 0);
  if (rim) {
    for (int k = 0; k < 8; ++k) {
      l.reference.push_back(on_circle(kPi / 2 + k * kPi / 4));
      l.on_rim.push_back(1);
    }
  }
  l.frame = l.reference;
  return l;
}

inline double max_landmark_error(const DiskRegistration& f, const DiskLandmarks& l) {
  double error = 0;
  for (size_t j = 0; j < l.reference.size(); ++j) error = std::max(error, (f(l.reference[j]) - l.frame[j]).norm());
  return error;
}

// The circle's images under the map: on the circle (within `radius_tolerance`) and strictly
// counter-clockwise, once round.
inline void expect_circle_onto_circle(const DiskRegistration& f, int samples, double radius_tolerance) {
  double turn = 0;
  Vec2 previous = f(on_circle(0));
  for (int k = 1; k <= samples; ++k) {
    const Vec2 y = f(on_circle(2 * kPi * k / samples));
    EXPECT_NEAR(y.norm(), 1.0, radius_tolerance);
    const double step = std::atan2(previous.x() * y.y() - previous.y() * y.x(), previous.dot(y));
    EXPECT_GT(step, 0) << "at sample " << k;
    turn += step;
    previous = y;
  }
  EXPECT_NEAR(turn, 2 * kPi, 1e-9);
}

}  // namespace facemorph::testing
