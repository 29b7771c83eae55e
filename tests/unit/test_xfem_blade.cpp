// A blade's path through the tets of an Is-XFEM body (thesis sec 3.1): Moeller's
// triangle-triangle test against an independent criterion (two triangles in general position meet
// exactly when an edge of one crosses the other) and hand-made touching and coplanar cases; the
// segment-tet test against sampling; a planar blade, however finely triangulated, gives every tet
// the blade's own plane and crosses every tet fully; a blade ending inside the body crosses the
// tets at its front only partially; a blade folded inside a tet reports how far it strays.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/xfem_blades.h"
#include "kernels/tri_tri.h"
#include "xfem/blade_path.h"

namespace gf::detail {
namespace {

TEST(XfemBlade, MoellerAgreesWithEdgeCrossingsOnRandomTriangles) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int meets = 0, apart = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Vec3 v[3], w[3];
    for (int k = 0; k < 3; ++k) {
      v[k] = {u(rng), u(rng), u(rng)};
      w[k] = {u(rng) + 0.5, u(rng), u(rng)};
    }
    // Independent: in general position, triangles meet iff an edge of one crosses the other.
    bool crossing = false;
    double s;
    for (int k = 0; k < 3 && !crossing; ++k)
      crossing = segmentCrossesTriangle(v[k], v[(k + 1) % 3], w[0], w[1], w[2], s, 0) ||
                 segmentCrossesTriangle(w[k], w[(k + 1) % 3], v[0], v[1], v[2], s, 0);
    ASSERT_EQ(trianglesIntersect(v, w, 0), crossing) << "trial " << trial;
    ASSERT_EQ(trianglesIntersect(w, v, 0), crossing) << "trial " << trial;
    (crossing ? meets : apart)++;
  }
  std::printf("Moeller vs edge crossings: %d meeting, %d apart pairs, all agree\n", meets, apart);
  EXPECT_GT(meets, 2000);
  EXPECT_GT(apart, 2000);
}

TEST(XfemBlade, MoellerTouchingAndCoplanarCases) {
  const Vec3 t[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  // A vertex on the other triangle's interior, and one a hair above it.
  const Vec3 touch[3] = {{0.2, 0.2, 0}, {0.5, 0.5, 1}, {0, 0.6, 1}};
  const Vec3 above[3] = {{0.2, 0.2, 1e-9}, {0.5, 0.5, 1}, {0, 0.6, 1}};
  EXPECT_TRUE(trianglesIntersect(t, touch));
  EXPECT_FALSE(trianglesIntersect(t, above));
  // Coplanar: overlapping, one inside the other, disjoint.
  const Vec3 overlap[3] = {{0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.2, 0}};
  const Vec3 inside[3] = {{0.1, 0.1, 0}, {0.3, 0.1, 0}, {0.1, 0.3, 0}};
  const Vec3 apart[3] = {{1, 1, 0}, {2, 1, 0}, {1, 2, 0}};
  EXPECT_TRUE(trianglesIntersect(t, overlap));
  EXPECT_TRUE(trianglesIntersect(t, inside));
  EXPECT_TRUE(trianglesIntersect(inside, t));
  EXPECT_FALSE(trianglesIntersect(t, apart));
  // Crossing through each other's interiors, and sharing only the line of their planes.
  const Vec3 pierce[3] = {{0.2, 0.2, -1}, {0.2, 0.2, 1}, {0.8, 0.9, 0.5}};
  const Vec3 beside[3] = {{1.2, 0.2, -1}, {1.2, 0.2, 1}, {1.8, 0.9, 0.5}};
  EXPECT_TRUE(trianglesIntersect(t, pierce));
  EXPECT_FALSE(trianglesIntersect(t, beside));
}

TEST(XfemBlade, SegmentMeetsTetAgreesWithSampling) {
  const Vec3 X[4] = {{0, 0, 0}, {1, 0.1, 0}, {0.2, 1, 0.1}, {0.1, 0.2, 1}};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-0.5, 1.5);
  int hits = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Vec3 a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)};
    bool sampled = false;
    for (int i = 0; i <= 2000 && !sampled; ++i)
      sampled = pointInTet(X, a + (i / 2000.0) * (b - a), 0);
    const bool meets = segmentMeetsTet(X, a, b, 0);
    // Sampling can miss a grazing crossing, never invent one.
    if (sampled) {
      ASSERT_TRUE(meets) << trial;
    }
    hits += meets;
    if (meets && !sampled) {
      // Then the segment passes within a sample spacing of the tet.
      double best = 1e9;
      for (int i = 0; i <= 2000; ++i) {
        double l[4];
        tetBarycentric(X, a + (i / 2000.0) * (b - a), l);
        best = std::min(best, -std::min(std::min(l[0], l[1]), std::min(l[2], l[3])));
      }
      EXPECT_LT(best, 2e-3 * norm(b - a)) << trial;
    }
  }
  EXPECT_GT(hits, 300);
}

// A node on the blade's plane to rounding (a few ulps either side): the snapped test gives the
// same answer whichever side rounding puts it, and the edges of a tet around it that lead to the
// negative side are crossed exactly at the node (s = 0), those to the positive side not at all;
// the strict test instead flips with the sign of the noise. Independent truth: the node's side is
// decided by construction (on the plane = positive), the other endpoints are 0.3 off it.
TEST(XfemBlade, SnappedCrossingsAreTheSameWhicheverSideRoundingFalls) {
  const Vec3 p0{-2, -2, 0.7}, p1{3, -2, 0.7}, p2{0, 3, 0.7};  // z = 0.7, normal +z
  const Vec3 below{0.1, 0.2, 0.4}, above{-0.2, 0.1, 1.0};
  int strictFlips = 0;
  for (double noise : {-4e-16, -1e-16, 0.0, 1e-16, 4e-16}) {
    const Vec3 node{0.3, 0.4, 0.7 + noise};
    double s = -1;
    EXPECT_TRUE(segmentCrossesTriangleSnapped(node, below, 1e-13, 0, p0, p1, p2, s)) << noise;
    EXPECT_EQ(s, 0.0) << noise;
    EXPECT_TRUE(segmentCrossesTriangleSnapped(below, node, 0, 1e-13, p0, p1, p2, s)) << noise;
    EXPECT_EQ(s, 1.0) << noise;
    EXPECT_FALSE(segmentCrossesTriangleSnapped(node, above, 1e-13, 0, p0, p1, p2, s)) << noise;
    // Off the snap distance, the crossing is the ordinary one.
    EXPECT_TRUE(segmentCrossesTriangleSnapped(below, above, 1e-13, 1e-13, p0, p1, p2, s));
    EXPECT_NEAR(s, 0.3 / 0.6, 1e-15);
    strictFlips += segmentCrossesTriangle(node, below, p0, p1, p2, s) !=
                   segmentCrossesTriangle(node, above, p0, p1, p2, s);
  }
  EXPECT_GT(strictFlips, 0);  // unsnapped, the answer follows the sign of the noise
}

// A tet with its apex 2e-16 on the positive side of a plane z = const: exact clipping leaves a
// positive corner cell of rounding noise (volume ~1e-48); with the apex counted as on the plane
// (onPlane 1e-12) the positive side is empty and the negative cell is the whole tet (1/6).
TEST(XfemBlade, OnPlaneToleranceLeavesNoSliverCell) {
  const Vec3 X[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.3, 1}};
  const CutPlane plane{{0, 0, 1}, 1 - 2e-16};  // positive side z >= 1 - 2e-16
  const double sliver = polytopeVolume(clipTet(X, &plane, 1, 1u));
  EXPECT_GT(sliver, 0);
  EXPECT_LT(sliver, 1e-40);
  EXPECT_EQ(clipTet(X, &plane, 1, 1u, 1e-12).faceCount, 0);
  EXPECT_NEAR(polytopeVolume(clipTet(X, &plane, 1, 0u, 1e-12)), 1.0 / 6, 1e-15);
}

using test::planarBlade;

TEST(XfemBlade, PlanarBladeGivesItsPlaneInEveryTet) {
  const TetMesh mesh = gen::box(2, 1, 1, 6, 3, 3);
  const double a = 0.93, b = 0.2, c = 0.1, len = std::sqrt(1 + b * b + c * c);
  const CutPlane plane{{1 / len, -b / len, -c / len}, a / len};
  for (int n : {1, 7}) {
    XfemBlade blade{planarBlade(a, b, c, -0.5, 1.5, n, 3), {}};
    auto made = traceBlade(mesh, blade);
    ASSERT_TRUE(made.ok()) << made.error().message;
    const BladePath& path = made.value();
    // Independent: the tets whose nodes lie strictly on both sides of the plane.
    int expected = 0;
    for (size_t t = 0; t < mesh.tetCount(); ++t) {
      bool pos = false, neg = false;
      for (int k = 0; k < 4; ++k) {
        const double* p = &mesh.positions[3 * size_t(mesh.tets[4 * t + k])];
        const double d = planeDistance(plane, {p[0], p[1], p[2]});
        pos = pos || d > 0;
        neg = neg || d < 0;
      }
      expected += pos && neg;
    }
    double normalErr = 0, offsetErr = 0;
    for (const BladeTetCrossing& x : path.crossings) {
      normalErr = std::max(normalErr, norm(x.plane.normal - plane.normal));
      offsetErr = std::max(offsetErr, std::abs(x.plane.offset - plane.offset));
    }
    std::printf(
        "%d x %d cells blade: %d tets fully crossed (expected %d), %d partially, %d touched; "
        "local plane vs blade plane: normal %.1e, offset %.1e; deviation %.1e; %lld tests\n",
        n, n, path.fullCount, expected, path.partialCount, path.touched, normalErr, offsetErr,
        path.maxDeviation, static_cast<long long>(path.triangleTests));
    EXPECT_EQ(path.fullCount, expected);
    EXPECT_EQ(path.partialCount, 0);
    // The plane comes from edge crossing points a cell apart: rounding over the cell size.
    EXPECT_LE(normalErr, 1e-13);
    EXPECT_LE(offsetErr, 1e-13);
    EXPECT_LE(path.maxDeviation, 1e-14);
  }
}

TEST(XfemBlade, BladeEndingInsideCrossesItsFrontTetsPartially) {
  const TetMesh mesh = gen::box(2, 1, 1, 6, 3, 3);
  // The plane x = 0.93 + 0.2 y + 0.1 z, only for y below 0.55: it ends inside the box.
  XfemBlade blade{planarBlade(0.93, 0.2, 0.1, -0.5, 0.55, 1, 3), {}};
  // Only the part z in [-0.5, 0.55] too: both y and z ends are inside.
  auto made = traceBlade(mesh, blade);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const BladePath& path = made.value();
  std::printf("blade ending inside: %d full, %d partial crossings\n", path.fullCount,
              path.partialCount);
  EXPECT_GT(path.fullCount, 0);
  EXPECT_GT(path.partialCount, 0);
  for (const BladeTetCrossing& x : path.crossings) {
    // A partial tet contains a point of the blade's front (y or z = 0.55 on the plane).
    double ymax = -1e9, zmax = -1e9, ymin = 1e9, zmin = 1e9;
    for (int k = 0; k < 4; ++k) {
      const double* p = &mesh.positions[3 * size_t(mesh.tets[4 * size_t(x.tet) + k])];
      ymax = std::max(ymax, p[1]), ymin = std::min(ymin, p[1]);
      zmax = std::max(zmax, p[2]), zmin = std::min(zmin, p[2]);
    }
    const bool straddlesFront = (ymin < 0.55 && ymax > 0.55) || (zmin < 0.55 && zmax > 0.55);
    if (!x.full) {
      EXPECT_TRUE(straddlesFront) << x.tet;
    }
    if (ymax < 0.55 && zmax < 0.55) {
      EXPECT_TRUE(x.full) << x.tet;
    }
  }
}

TEST(XfemBlade, FoldedBladeReportsItsDeviation) {
  const TetMesh mesh = gen::box(1, 1, 1, 1, 1, 1);
  // Two half-planes meeting at y = 0.5: x = 0.45 + 0.2 |y - 0.5|, across the whole cube (the
  // kink off the Kuhn split's planes x = y, so inside tets).
  Blade blade;
  blade.vertices = {0.65, -0.5, -1, 0.45, 0.5, -1, 0.65, 1.5, -1,
                    0.65, -0.5, 2,  0.45, 0.5, 2,  0.65, 1.5, 2};
  blade.triangles = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4};
  auto made = traceBlade(mesh, {blade, {}});
  ASSERT_TRUE(made.ok()) << made.error().message;
  double worst = 0;
  for (const BladeTetCrossing& x : made.value().crossings)
    if (x.triangles > 2) worst = std::max(worst, x.deviation);
  std::printf("folded blade: %d full crossings, largest distance from a local plane %.3e\n",
              made.value().fullCount, worst);
  EXPECT_GT(worst, 1e-3);
  EXPECT_LT(worst, 0.1);
}

}  // namespace
}  // namespace gf::detail
