// Continuous collision kernels (kernels/ccd.h) against brute force and closed forms: the
// sign changes of the moving points' volume against dense sampling, the expanded cubic against
// the direct volume, vertex-face and edge-edge crossings at analytic times, and the penetration
// integral of eq 7.5 against its closed form and a fine quadrature.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <vector>

#include "kernels/ccd.h"

namespace gf {
namespace {

MovingQuad randomQuad(std::mt19937& rng, double spread) {
  std::uniform_real_distribution<double> u(-1, 1);
  const auto r = [&] { return Vec3{u(rng), u(rng), u(rng)}; };
  MovingQuad q;
  q.p0 = r(), q.a0 = r(), q.b0 = r(), q.c0 = r();
  q.p1 = q.p0 + spread * r(), q.a1 = q.a0 + spread * r(), q.b1 = q.b0 + spread * r();
  q.c1 = q.c0 + spread * r();
  return q;
}

TEST(Ccd, ExpandedCubicEqualsTheDirectVolume) {
  std::mt19937 rng(7);
  for (int i = 0; i < 200; ++i)
    for (bool ee : {false, true}) {
      const MovingQuad q = randomQuad(rng, 2.0);
      double k[4];
      quadVolumeCubic(q, ee, k);
      for (double t : {0.0, 0.3, 0.71, 1.0}) {
        const double direct = quadVolume(q, ee, t);
        const double poly = k[0] + t * (k[1] + t * (k[2] + t * k[3]));
        EXPECT_NEAR(
            poly, direct,
            1e-12 * (1 + std::abs(k[0]) + std::abs(k[1]) + std::abs(k[2]) + std::abs(k[3])));
      }
    }
}

// Every sign change a dense sampling of the direct volume sees is found, at the same place;
// none is invented.
TEST(Ccd, SignChangesMatchDenseSampling) {
  std::mt19937 rng(11);
  int total = 0, threeRoots = 0;
  for (int i = 0; i < 400; ++i)
    for (bool ee : {false, true}) {
      const MovingQuad q = randomQuad(rng, 3.0);
      std::vector<double> sampled;
      const int n = 20000;
      double prev = quadVolume(q, ee, 0);
      for (int s = 1; s <= n; ++s) {
        const double t = double(s) / n, f = quadVolume(q, ee, t);
        if ((prev > 0 && f < 0) || (prev < 0 && f > 0)) sampled.push_back(t - 0.5 / n);
        if (f != 0) prev = f;
      }
      double roots[3];
      const int found = quadVolumeSignChanges(q, ee, roots);
      ASSERT_EQ(found, int(sampled.size())) << "quad " << i << (ee ? " edge-edge" : " vertex-face");
      for (int r = 0; r < found; ++r) {
        EXPECT_NEAR(roots[r], sampled[size_t(r)], 0.6 / n);
        EXPECT_NEAR(quadVolume(q, ee, roots[r]), 0.0, 1e-9);
      }
      total += found;
      threeRoots += found == 3;
    }
  // The family must exercise the cubic, not only lines.
  EXPECT_GT(total, 200);
  EXPECT_GT(threeRoots, 0);
}

// A vertex falling through a static triangle at z = 0 from z0 to z1: one crossing at
// z0 / (z0 - z1), over the triangle only when its path is.
TEST(Ccd, VertexThroughTriangleAtTheAnalyticTime) {
  MovingQuad q;
  q.a0 = q.a1 = {0, 0, 0};
  q.b0 = q.b1 = {1, 0, 0};
  q.c0 = q.c1 = {0, 1, 0};
  for (double z0 : {0.3, 1e-6, 2.0})
    for (double z1 : {-0.1, -1e-7, -5.0}) {
      q.p0 = {0.2, 0.3, z0};
      q.p1 = {0.25, 0.2, z1};
      double roots[3];
      ASSERT_EQ(quadVolumeSignChanges(q, false, roots), 1);
      EXPECT_NEAR(roots[0], z0 / (z0 - z1), 1e-14);
      Vec3 w;
      EXPECT_TRUE(pointOverTriangle(q, roots[0], 1e-9, w));
      q.p0.x = q.p1.x = 0.9;  // passes beside the triangle (x + y > 1)
      EXPECT_EQ(quadVolumeSignChanges(q, false, roots), 1);
      EXPECT_FALSE(pointOverTriangle(q, roots[0], 1e-9, w));
    }
}

// Two edges, one along x dropping through one along y at z = 0 (cross at t = 0.4), and the
// same with the second edge moved past the end of the first (no contact).
TEST(Ccd, EdgeThroughEdgeAtTheAnalyticTime) {
  MovingQuad q;
  q.p0 = {-1, 0.2, 0.4}, q.a0 = {1, 0.2, 0.4};
  q.p1 = {-1, 0.2, -0.6}, q.a1 = {1, 0.2, -0.6};
  q.b0 = q.b1 = {0.3, -1, 0};
  q.c0 = q.c1 = {0.3, 1, 0};
  double roots[3], s = 0, u = 0;
  ASSERT_EQ(quadVolumeSignChanges(q, true, roots), 1);
  EXPECT_NEAR(roots[0], 0.4, 1e-14);
  ASSERT_TRUE(edgesMeet(q, roots[0], 1e-9, s, u));
  EXPECT_NEAR(s, 0.65, 1e-12);
  EXPECT_NEAR(u, 0.6, 1e-12);
  q.b0.x = q.b1.x = q.c0.x = q.c1.x = 1.5;
  ASSERT_EQ(quadVolumeSignChanges(q, true, roots), 1);
  EXPECT_FALSE(edgesMeet(q, roots[0], 1e-9, s, u));
}

// Eq 7.5 for a vertex falling through a static face: depth grows linearly from the crossing,
// so the integral is (1 - t0) * depth(1) / 2 along the face's normal; for a rising vertex it
// is the part before it comes out.
TEST(Ccd, PenetrationIntegralOfALinearDepthIsExact) {
  MovingQuad q;
  q.a0 = q.a1 = {0, 0, 0};
  q.b0 = q.b1 = {1, 0, 0};
  q.c0 = q.c1 = {0, 1, 0};
  q.p0 = {0.2, 0.2, 0.3};
  q.p1 = {0.2, 0.2, -0.5};
  const double t0 = 0.3 / 0.8;
  Vec3 I = penetrationIntegral(q, false, 1, 0, 1);
  EXPECT_NEAR(I.z, (1 - t0) * 0.5 / 2, 1e-15);
  EXPECT_NEAR(I.x, 0, 1e-15);
  EXPECT_NEAR(I.y, 0, 1e-15);
  // From a later start only the part after it counts.
  I = penetrationIntegral(q, false, 1, 0.8, 1);
  const double d08 = 0.8 * 0.8 - 0.3, d1 = 0.5;
  EXPECT_NEAR(I.z, 0.2 * (d08 + d1) / 2, 1e-15);
  // Rising: inside from 0 until it crosses at 0.625.
  std::swap(q.p0, q.p1);
  I = penetrationIntegral(q, false, 1, 0, 1);
  EXPECT_NEAR(I.z, 0.625 * 0.5 / 2, 1e-15);
}

// With a turning face the integrand is not a polynomial: compare with a fine midpoint rule.
TEST(Ccd, PenetrationIntegralOfATurningFaceMatchesFineQuadrature) {
  std::mt19937 rng(5);
  int compared = 0;
  double worst = 0;
  for (int i = 0; i < 100; ++i) {
    for (bool ee : {false, true}) {
      const MovingQuad q = randomQuad(rng, 0.3);
      const double sign = ee ? -1 : 1;
      const Vec3 I = penetrationIntegral(q, ee, sign, 0, 1);
      Vec3 ref;
      const int n = 200000;
      for (int s = 0; s < n; ++s) {
        const double t = (s + 0.5) / n;
        const double f = quadVolume(q, ee, t);
        if (sign * f >= 0) continue;
        const Vec3 N = quadNormal(q, ee, t);
        ref += (-f / dot(N, N) / n) * N;
      }
      const double scale = norm(ref) + 1e-3;
      // The midpoint rule of 2e5 cells is good to ~1e-6 here (it has a kink at each root).
      EXPECT_NEAR(I.x, ref.x, 1e-5 * scale);
      EXPECT_NEAR(I.y, ref.y, 1e-5 * scale);
      EXPECT_NEAR(I.z, ref.z, 1e-5 * scale);
      worst = std::max(worst, norm(I - ref) / scale);
      compared += norm(ref) > 1e-3;
    }
  }
  EXPECT_GT(compared, 50);
  std::printf("worst relative error against the fine rule: %.2e\n", worst);
}

}  // namespace
}  // namespace gf
