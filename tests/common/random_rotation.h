// Frobenius norms and uniformly random rotations for the kernel tests' invariance checks.
#pragma once

#include <cmath>
#include <random>

#include "kernels/math.h"

namespace gf::test {

inline double frob(const Mat3& a) { return std::sqrt(frobeniusDot(a, a)); }
inline double frob9(const Mat9& a) { return std::sqrt(frobeniusDot(a, a)); }

/// Uniformly random rotation: a normalised Gaussian quaternion is uniform on the unit sphere
/// of S^3, hence its rotation is uniform (Haar) on SO(3).
inline Mat3 randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0, 1);
  double w = n(rng), x = n(rng), y = n(rng), z = n(rng);
  const double l = std::sqrt(w * w + x * x + y * y + z * z);
  w /= l;
  x /= l;
  y /= l;
  z /= l;
  Mat3 r;
  r(0, 0) = 1 - 2 * (y * y + z * z);
  r(0, 1) = 2 * (x * y - z * w);
  r(0, 2) = 2 * (x * z + y * w);
  r(1, 0) = 2 * (x * y + z * w);
  r(1, 1) = 1 - 2 * (x * x + z * z);
  r(1, 2) = 2 * (y * z - x * w);
  r(2, 0) = 2 * (x * z - y * w);
  r(2, 1) = 2 * (y * z + x * w);
  r(2, 2) = 1 - 2 * (x * x + y * y);
  return r;
}

}  // namespace gf::test
