// Is-XFEM enrichment (thesis eqs 3.1-3.7): the signed distance to a blade triangle; psi of
// eq 3.2 vanishes on a node's own side for k = 0 and everywhere in an uncut tet; the enriched
// element's standard block equals the plain linear tet (consistent mass rho V (1 + delta) / 20,
// stiffness = the corotated kernel's rest Hessian, which is linear elasticity); the stiffness
// annihilates a rigid translation of either piece alone; the shape-function gradients match
// finite differences.
#include <gtest/gtest.h>

#include <cmath>

#include "kernels/element.h"
#include "kernels/materials.h"
#include "xfem/cut_element.h"

namespace gf::detail {
namespace {

const Vec3 kTet[4] = {{0.1, 0.0, 0.05}, {1.2, 0.1, 0.0}, {0.2, 0.9, 0.1}, {0.15, 0.2, 1.1}};
const CutPlane kCut{{0.6, 0.64, 0.48}, 0.45};  // unit normal; splits the tet 2-2 or 1-3

TEST(XfemEnrichment, SignedDistanceToTriangle) {
  const Vec3 a{0, 0, 0}, b{1, 0, 0}, c{0, 1, 0};
  EXPECT_DOUBLE_EQ(signedDistanceToTriangle({0.2, 0.2, 0.5}, a, b, c), 0.5);
  EXPECT_DOUBLE_EQ(signedDistanceToTriangle({0.2, 0.2, -0.3}, a, b, c), -0.3);
  // Beyond the edge b-c: the distance to the edge, signed by the plane side.
  EXPECT_NEAR(signedDistanceToTriangle({1, 1, 1}, a, b, c), std::sqrt(0.5 + 1.0), 1e-15);
  EXPECT_NEAR(signedDistanceToTriangle({-1, -1, -1}, a, b, c), -std::sqrt(3.0), 1e-15);
}

TEST(XfemEnrichment, ClassicEnrichmentVanishesOnTheNodesSide) {
  for (double hNode : {0.0, 1.0})
    for (double gamma : {0.0, 0.3, 1.0}) {
      EXPECT_EQ(stableEnrichment(0.0, hNode, gamma, hNode), 0.0);
      EXPECT_EQ(std::abs(stableEnrichment(0.0, 1 - hNode, gamma, hNode)), 1.0);
    }
  // Uncut: every node on the cell's side, gamma = H, psi = 0 for any k.
  for (double k : {0.0, 0.1, 0.5}) EXPECT_EQ(stableEnrichment(k, 1.0, 1.0, 1.0), 0.0);
}

TEST(XfemEnrichment, StandardBlockIsThePlainTet) {
  const LinearElastic mat{2e6, 0.3, 900};
  const CutElement e = buildCutElement(kTet, &kCut, 1, 0.1, mat);
  ASSERT_EQ(e.cells.size(), 2u);
  double volume = 0;
  const Mat3 dmInv = restShapeInverse(kTet, volume);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      EXPECT_NEAR(e.mass(a, b), mat.density * volume * (a == b ? 2.0 : 1.0) / 20.0,
                  1e-13 * mat.density * volume);
  const MaterialCoeffs c = makeMaterialCoeffs(kCorotated, mat.youngs, mat.poisson, 0, Vec3{});
  double grad[12];
  Mat12 h;
  elementForces(c, kTet, dmInv, volume, grad, &h, false);
  double scale = 0;
  for (int i = 0; i < 144; ++i) scale = std::max(scale, std::abs(h.m[i]));
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) EXPECT_NEAR(e.stiffness(i, j), h(i, j), 1e-10 * scale);
}

// An uncut tet takes the standard (Grundmann-Moeller) rule, not a fitted one: its element is
// still the plain linear tet, in closed form, and its one cell is the whole tet.
TEST(XfemEnrichment, UncutTetIsThePlainTetWithTheStandardRule) {
  const LinearElastic mat{2e6, 0.3, 900};
  const CutElement e = buildCutElement(kTet, nullptr, 0, 0.1, mat);
  ASSERT_EQ(e.cells.size(), 1u);
  EXPECT_EQ(e.cells[0].rule.count, 15);  // not the 35 points of a fitted rule
  double volume = 0;
  const Mat3 dmInv = restShapeInverse(kTet, volume);
  EXPECT_NEAR(e.cells[0].volume, volume, 1e-15 * volume);
  ASSERT_EQ(e.mass.rows(), 4);
  for (int a = 0; a < 4; ++a) {
    EXPECT_NEAR(e.load[a], mat.density * volume / 4, 1e-14 * mat.density * volume);
    for (int b = 0; b < 4; ++b)
      EXPECT_NEAR(e.mass(a, b), mat.density * volume * (a == b ? 2.0 : 1.0) / 20.0,
                  1e-14 * mat.density * volume);
  }
  const MaterialCoeffs c = makeMaterialCoeffs(kCorotated, mat.youngs, mat.poisson, 0, Vec3{});
  double grad[12];
  Mat12 h;
  elementForces(c, kTet, dmInv, volume, grad, &h, false);
  double scale = 0;
  for (int i = 0; i < 144; ++i) scale = std::max(scale, std::abs(h.m[i]));
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) EXPECT_NEAR(e.stiffness(i, j), h(i, j), 1e-10 * scale);
}

TEST(XfemEnrichment, PieceTranslationIsStressFree) {
  for (double k : {0.0, 0.1}) {
    const CutElement e = buildCutElement(kTet, &kCut, 1, k, {1e6, 0.3, 1000});
    // Translating only the positive piece by t: u_a = H_a t, enriched a_a = t (see cut_body).
    Eigen::VectorXd u = Eigen::VectorXd::Zero(24);
    const Vec3 t{0.3, -0.2, 0.7};
    for (int a = 0; a < 4; ++a)
      for (int i = 0; i < 3; ++i) {
        u[3 * a + i] = e.sides.side[0][a] * t[i];
        u[12 + 3 * a + i] = t[i];
      }
    EXPECT_LE((e.stiffness * u).norm(), 1e-9 * e.stiffness.norm() * u.norm()) << k;
    EXPECT_GT(e.stiffness.norm(), 0);
  }
}

TEST(XfemEnrichment, GradientsMatchFiniteDifferences) {
  double volume = 0;
  const Mat<4, 3> B = shapeGradients(restShapeInverse(kTet, volume));
  CutElementSides sides;
  sides.cutCount = 1;
  for (int a = 0; a < 4; ++a) sides.side[0][a] = xfemHeaviside(planeDistance(kCut, kTet[a]));
  const Vec3 x{0.35, 0.3, 0.3};
  double v[8], vp[8], vm[8];
  Vec3 g[8], scratch[8];
  enrichedShapeFunctions(kTet[0], B, sides, 1u, 0.1, x, v, g);
  const double h = 1e-6;
  for (int axis = 0; axis < 3; ++axis) {
    Vec3 xp = x, xm = x;
    xp[axis] += h;
    xm[axis] -= h;
    enrichedShapeFunctions(kTet[0], B, sides, 1u, 0.1, xp, vp, scratch);
    enrichedShapeFunctions(kTet[0], B, sides, 1u, 0.1, xm, vm, scratch);
    for (int A = 0; A < 8; ++A) EXPECT_NEAR(g[A][axis], (vp[A] - vm[A]) / (2 * h), 1e-8) << A;
  }
}

}  // namespace
}  // namespace gf::detail
