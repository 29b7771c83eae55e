// Is-XFEM bodies cut by blades (triangle meshes, thesis sec 3.1) instead of planes: a planar
// blade, however it is triangulated, gives the body the plane's exact pieces and step matrix; two
// crossing blades give four pieces of exactly the split volumes; a blade that ends inside the body
// enriches no node of the tets at its front, so the body stays one piece and the part beyond the
// cut hangs on instead of falling; a blade with a kink inside tets separates the body, with piece
// volumes off the exact split by no more than the blade's distance from its local planes allows,
// while a kink sharper than the tets (crossing an edge twice) leaves them uncut.
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "common/xfem_blades.h"
#include "xfem/cut_body.h"

namespace gf::detail {
namespace {

using test::planarBlade;

XfemBodyDef boxDef() { return test::xfemBox(1e7); }

TEST(XfemBlades, PlanarBladeMatchesThePlane) {
  const double a = 0.93, b = 0.2, c = 0.1;
  XfemBodyDef byPlane = boxDef();
  byPlane.planes = {test::slantedPlane(a, b, c)};
  auto plane = XfemBody::create(byPlane);
  ASSERT_TRUE(plane.ok()) << plane.error().message;
  const double exactLeft = a + b / 2 + c / 2;
  for (int n : {1, 5}) {
    XfemBodyDef byBlade = boxDef();
    byBlade.blades = {{planarBlade(a, b, c, -0.5, 1.5, n), {}}};
    auto blade = XfemBody::create(byBlade);
    ASSERT_TRUE(blade.ok()) << blade.error().message;
    const XfemBody &p = *plane.value(), &q = *blade.value();
    ASSERT_EQ(q.pieces().size(), 2u);
    EXPECT_EQ(q.cutTetCount(), p.cutTetCount());
    EXPECT_EQ(q.enrichedCount(), p.enrichedCount());
    const double left = q.pieces()[size_t(q.pieceWithMask(0u))].volume;
    const double right = q.pieces()[size_t(q.pieceWithMask(1u))].volume;
    double offPlane = 0;
    for (const XfemCutFace& f : q.cutFaces())
      for (int i = 0; i < f.polygon.count; ++i)
        offPlane = std::max(offPlane, std::abs(planeDistance(byPlane.planes[0], f.polygon.v[i])));
    const double matrixDiff =
        (Eigen::MatrixXd(q.stepMatrix()) - Eigen::MatrixXd(p.stepMatrix())).norm() /
        Eigen::MatrixXd(p.stepMatrix()).norm();
    std::printf(
        "blade of %d x %d cells: %d cut tets, volumes rel. error %.1e / %.1e, cut faces off "
        "the plane <= %.1e, step matrix vs the plane's %.1e\n",
        n, n, q.cutTetCount(), std::abs(left - exactLeft) / exactLeft,
        std::abs(right - (2 - exactLeft)) / (2 - exactLeft), offPlane, matrixDiff);
    EXPECT_NEAR(left, exactLeft, 1e-10 * exactLeft);
    EXPECT_NEAR(right, 2 - exactLeft, 1e-10 * (2 - exactLeft));
    EXPECT_LE(offPlane, 1e-12);
    EXPECT_LE(matrixDiff, 1e-12);
    EXPECT_EQ(q.cutReports()[0].partialTets, 0);
    EXPECT_EQ(q.cutReports()[0].openTets, q.cutTetCount());
  }
}

TEST(XfemBlades, TwoCrossingBladesGiveFourExactPieces) {
  XfemBodyDef def = boxDef();
  // x = 0.93 + 0.2 y + 0.1 z, and z = 0.45 + 0.1 x (as a blade over x, y).
  def.blades.push_back({planarBlade(0.93, 0.2, 0.1, -0.5, 1.5, 3), {}});
  Blade second;
  second.vertices = {-1, -1, 0.45 - 0.1, 3, -1, 0.45 + 0.3, 3, 2, 0.45 + 0.3, -1, 2, 0.45 - 0.1};
  second.triangles = {0, 1, 2, 0, 2, 3};  // normal +z - 0.1 x
  def.blades.push_back({second, {}});
  auto made = XfemBody::create(def);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const XfemBody& body = *made.value();
  ASSERT_EQ(body.pieces().size(), 4u);
  // Independent truth: per column (x, y), the z-lengths of the four pieces are exact (left of
  // the first cut is z > zf, below the second z < g); summed by the midpoint rule in x and y.
  double exact[4] = {0, 0, 0, 0};
  const int n = 2000;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) {
      const double y = (i + 0.5) / n, x = 2 * (k + 0.5) / n;
      const double g = 0.45 + 0.1 * x, zf = (x - 0.93 - 0.2 * y) / 0.1;
      const double lo = std::clamp(zf, 0.0, 1.0);
      const double below = std::clamp(g, 0.0, 1.0);
      const double leftBelow = std::max(0.0, below - lo),
                   leftAbove = std::max(0.0, 1 - std::max(lo, below));
      const double cell = (1.0 / n) * (2.0 / n);
      exact[0] += cell * leftBelow;                  // x < f, z < g
      exact[1] += cell * (below - leftBelow);        // x > f, z < g
      exact[2] += cell * leftAbove;                  // x < f, z > g
      exact[3] += cell * ((1 - below) - leftAbove);  // x > f, z > g
    }
  double worst = 0;
  for (unsigned mask = 0; mask < 4; ++mask) {
    const int p = body.pieceWithMask(mask);
    ASSERT_GE(p, 0) << mask;
    worst = std::max(worst, std::abs(body.pieces()[size_t(p)].volume - exact[mask]) / exact[mask]);
  }
  std::printf("two crossing blades: 4 pieces, volumes vs a 2000^2 column sum: worst %.1e\n", worst);
  // The column sum is exact in z and a midpoint rule of a piecewise-linear function in x, y.
  EXPECT_LE(worst, 1e-5);
}

TEST(XfemBlades, BladeEndingInsideLeavesOnePieceThatHangsOn) {
  const double a = 0.93, b = 0.2, c = 0.1;
  double fall[2];
  for (int ends = 0; ends < 2; ++ends) {
    XfemBodyDef def = boxDef();
    def.material.youngs = 1e10;
    // Through the whole section, or only y and z below 0.8 (a ligament stays uncut). Stiff,
    // so that the held body's sag stays far below the free fall.
    def.blades = {{planarBlade(a, b, c, -0.5, ends ? 0.8 : 1.5, 1), {}}};
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
      if (def.mesh.positions[3 * size_t(n)] == 0) def.fixedNodes.push_back(n);
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    XfemBody& body = *made.value();
    const XfemCutReport& r = body.cutReports()[0];
    std::printf("blade %s: %d full, %d partial tets, %d enriched, %d open; %zu pieces\n",
                ends ? "ending inside" : "through", r.fullTets, r.partialTets, r.enrichedTets,
                r.openTets, body.pieces().size());
    if (ends) {
      EXPECT_GT(r.partialTets, 0);
      EXPECT_GT(r.openTets, 0);
      EXPECT_LT(r.openTets, r.enrichedTets);  // blended tets next to the front
      EXPECT_EQ(body.pieces().size(), 1u);
    } else {
      EXPECT_EQ(r.partialTets, 0);
      EXPECT_EQ(body.pieces().size(), 2u);
    }
    for (int s = 0; s < 100; ++s) body.step();
    // The far end's mean displacement: the nodes at x = 2 (standard DOFs).
    double y = 0;
    int count = 0;
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
      if (def.mesh.positions[3 * size_t(n)] == 2) y += body.displacement()[3 * n + 1], ++count;
    fall[ends] = -y / count;
  }
  const double t = 100 * 1e-3, free = 9.81 * t * t / 2;
  std::printf("far end fell %.4f m (cut through), %.2e m (cut ending inside); g t^2/2 = %.4f\n",
              fall[0], fall[1], free);
  EXPECT_GT(fall[0], 0.9 * free);
  EXPECT_LT(fall[1], 0.05 * free);
}

// x = ridge + 0.3 |y - 0.5| over the whole section, as two half-planes.
Blade kinkedBlade(double ridge) {
  const double out = ridge + 0.3 * 1.5;
  Blade blade;
  blade.vertices = {out, -1, -1, ridge, 0.5, -1, out, 2, -1, out, -1, 2, ridge, 0.5, 2, out, 2, 2};
  blade.triangles = {0, 1, 4, 0, 4, 3, 1, 2, 5, 1, 5, 4};
  return blade;
}

TEST(XfemBlades, KinkedBladeSeparatesWithBoundedVolumeError) {
  // Ridge at x = 0.9: the kink at y = 0.5 runs through the middle layer of tets, the blade
  // crosses every tet edge at most once and passes through no node.
  XfemBodyDef def = boxDef();
  def.blades = {{kinkedBlade(0.9), {}}};
  auto made = XfemBody::create(def);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const XfemBody& body = *made.value();
  const XfemCutReport& r = body.cutReports()[0];
  std::printf("kinked blade: %d full, %d partial, %d enriched, %d open tets, %zu pieces\n",
              r.fullTets, r.partialTets, r.enrichedTets, r.openTets, body.pieces().size());
  ASSERT_EQ(body.pieces().size(), 2u);
  EXPECT_EQ(r.partialTets, 0);
  const double exactLeft = 0.9 + 0.3 * 0.25;  // integral of 0.9 + 0.3 |y - 0.5| over y, z
  const double left = body.pieces()[size_t(body.pieceWithMask(0u))].volume;
  const double total = body.pieces()[0].volume + body.pieces()[1].volume;
  // The cut follows local planes within `deviation` of the blade over the section.
  const double bound = r.maxDeviation * std::sqrt(1 + 0.3 * 0.3);
  std::printf(
      "kinked blade: largest distance from a local plane %.3e m; left piece %.6f vs exact %.6f "
      "(error %.2e m^3, bound %.2e); total error %.1e\n",
      r.maxDeviation, left, exactLeft, std::abs(left - exactLeft), bound, std::abs(total - 2) / 2);
  EXPECT_GT(r.maxDeviation, 1e-3);
  EXPECT_LE(std::abs(left - exactLeft), bound);
  EXPECT_LE(std::abs(total - 2), 1e-12);

  // Ridge at x = 0.97: the ridge pokes through tet edges at x = 1 (crossed twice), which one
  // plane per tet cannot represent; those tets stay uncut and the crack does not open.
  def.blades = {{kinkedBlade(0.97), {}}};
  auto sharp = XfemBody::create(def);
  ASSERT_TRUE(sharp.ok()) << sharp.error().message;
  const XfemCutReport& rs = sharp.value()->cutReports()[0];
  std::printf("unresolved kink: %d full, %d partial, %d open tets, %zu pieces\n", rs.fullTets,
              rs.partialTets, rs.openTets, sharp.value()->pieces().size());
  EXPECT_GT(rs.partialTets, 0);
  EXPECT_EQ(sharp.value()->pieces().size(), 1u);
}

}  // namespace
}  // namespace gf::detail
