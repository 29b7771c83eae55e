// Generated meshes: every one must validate with no repairs, and its volume must be exact
// (box, notched box, slab, the cylinder's and tube's inscribed polygons) or converge to the
// analytic value at the expected second-order rate (cylinder, sphere).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "common/mesh_checks.h"
#include "graphfrac/mesh.h"

namespace {

using gf::test::enclosedVolume;

constexpr double kPi = std::numbers::pi;

// Validates without repairs and checks the boundary encloses the tet volume.
void expectValid(gf::TetMesh m, const std::string& what) {
  int flipped = -1;
  gf::Result<void> r = gf::validate(m, what, &flipped);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(flipped, 0) << what;
  EXPECT_NEAR(enclosedVolume(m), m.volume(), 1e-12 * std::max(1.0, m.volume())) << what;
}

TEST(MeshGen, BoxIsExact) {
  for (int n : {1, 2, 3, 7}) {
    const gf::TetMesh m = gf::gen::box(3.0, 0.5, 0.25, 4 * n, n, n);
    expectValid(m, "box");
    EXPECT_EQ(m.nodeCount(), static_cast<size_t>((4 * n + 1) * (n + 1) * (n + 1)));
    EXPECT_EQ(m.tetCount(), static_cast<size_t>(6 * 4 * n * n * n));
    EXPECT_NEAR(m.volume(), 3.0 * 0.5 * 0.25, 1e-13);  // exact up to summation rounding
  }
}

TEST(MeshGen, NotchedBoxCarvesAnExactV) {
  const double sx = 4, sy = 1, sz = 0.5, depth = 0.3, angle = 60;
  const double halfWidth = depth * std::tan(angle / 2 * kPi / 180);
  for (int n : {40, 80, 160}) {
    gf::gen::BoxOptions o;
    o.notchDepth = depth;
    o.notchAngleDeg = angle;
    const gf::TetMesh m = gf::gen::box(sx, sy, sz, n, n / 8, 2, o);
    expectValid(m, "notched box n=" + std::to_string(n));
    // V cross-section area: half-width * depth.
    EXPECT_NEAR(m.volume(), sx * sy * sz - halfWidth * depth * sz, 1e-12) << n;
    // The tip is a node at (sx/2, sy - depth).
    bool tip = false;
    for (size_t i = 0; i < m.nodeCount(); ++i) {
      tip |= std::abs(m.positions[3 * i] - 2.0) < 1e-15 &&
             std::abs(m.positions[3 * i + 1] - 0.7) < 1e-15;
    }
    EXPECT_TRUE(tip) << n;
  }
  // Off-centre, wide and narrow notches on coarse grids still validate (the V is then only
  // approximated where cells are coarser than it).
  for (double a : {10.0, 90.0, 150.0}) {
    for (int n : {3, 8, 21}) {
      gf::gen::BoxOptions o;
      o.notchDepth = 0.6;
      o.notchAngleDeg = a;
      o.notchX = 1.1;
      expectValid(gf::gen::box(sx, sy, sz, n, 3, 2, o), "notch a=" + std::to_string(a));
    }
  }
}

TEST(MeshGen, SlabThicknessFromCellSize) {
  const gf::TetMesh m = gf::gen::slab(2.0, 1.0, 0.3, 20, 10);  // cell 0.1 -> 3 layers
  expectValid(m, "slab");
  EXPECT_EQ(m.nodeCount(), static_cast<size_t>(21 * 4 * 11));
  EXPECT_NEAR(m.volume(), 2.0 * 1.0 * 0.3, 1e-13);
  const gf::TetMesh thin = gf::gen::slab(2.0, 1.0, 0.001, 4, 4);  // at least one layer
  expectValid(thin, "thin slab");
  EXPECT_EQ(thin.tetCount(), static_cast<size_t>(6 * 16));
}

TEST(MeshGen, CylinderConvergesToPiR2H) {
  const double r = 0.4, h = 1.5;
  double previous = 1;
  for (int seg : {8, 16, 32, 64}) {
    const gf::TetMesh m = gf::gen::cylinder(r, h, seg, seg / 4, seg / 8);
    expectValid(m, "cylinder " + std::to_string(seg));
    // The cross-section is exactly the inscribed polygon of the outer ring.
    const double polygon = 0.5 * seg * r * r * std::sin(2 * kPi / seg);
    EXPECT_NEAR(m.volume(), polygon * h, 1e-12);
    // Polygon error (2pi/n)^2 / 6 relative: second order.
    const double err = std::abs(m.volume() - kPi * r * r * h) / (kPi * r * r * h);
    EXPECT_LT(err, 1.01 * std::pow(2 * kPi / seg, 2) / 6) << seg;
    EXPECT_LT(err, 0.3 * previous) << seg;
    previous = err;
  }
  expectValid(gf::gen::cylinder(1.0, 0.05, 24, 1, 4), "disc");
  expectValid(gf::gen::cylinder(1.0, 2.0, 3, 1, 1), "triangular prism");
}

TEST(MeshGen, TubeIsTheAnnulusOfItsPolygons) {
  const double r = 0.05, ri = 0.035, h = 0.6;
  for (int seg : {3, 12, 40}) {
    for (int rings : {1, 3}) {
      const gf::TetMesh m = gf::gen::tube(r, ri, h, seg, 20, rings);
      const std::string what = "tube " + std::to_string(seg) + "/" + std::to_string(rings);
      expectValid(m, what);
      // The cross-section is the outer polygon less the inner one, both inscribed.
      const double annulus = 0.5 * seg * (r * r - ri * ri) * std::sin(2 * kPi / seg);
      EXPECT_NEAR(m.volume(), annulus * h, 1e-14) << what;
      // The hole is empty: no node inside the inner circle, every tet's centroid in the wall.
      for (size_t i = 0; i < m.nodeCount(); ++i) {
        const double* p = &m.positions[3 * i];
        EXPECT_GE(std::hypot(p[0], p[2]), ri * (1 - 1e-14)) << what;
      }
      for (size_t t = 0; t < m.tetCount(); ++t) {
        double c[3] = {0, 0, 0};
        for (int k = 0; k < 4; ++k) {
          for (int d = 0; d < 3; ++d) c[d] += 0.25 * m.positions[3 * m.tets[4 * t + k] + d];
        }
        EXPECT_GT(std::hypot(c[0], c[2]), ri * std::cos(kPi / seg)) << what;
      }
    }
  }
  // No hole is the solid cylinder.
  EXPECT_EQ(gf::gen::tube(0.4, 0, 1.0, 8, 2, 1).tets, gf::gen::cylinder(0.4, 1.0, 8, 2, 1).tets);
}

TEST(MeshGen, SphereConvergesToFourThirdsPiR3) {
  const double r = 0.8, exact = 4.0 / 3.0 * kPi * r * r * r;
  double previous = 1;
  for (int n : {2, 4, 8, 16, 32}) {
    const gf::TetMesh m = gf::gen::sphere(r, n);
    expectValid(m, "sphere " + std::to_string(n));
    const double err = std::abs(m.volume() - exact) / exact;
    // Inscribed polyhedron with edge ~ pi r / n: error ~ C / n^2, halving h quarters it.
    EXPECT_LT(err, 6.0 / (n * n)) << n;
    if (n > 2) {
      EXPECT_LT(err, 0.35 * previous) << n;
    }
    previous = err;
    // All nodes inside the ball, and the surface nodes on the sphere.
    for (size_t i = 0; i < m.nodeCount(); ++i) {
      const double* p = &m.positions[3 * i];
      EXPECT_LE(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]), r * (1 + 1e-14));
    }
  }
}

}  // namespace
