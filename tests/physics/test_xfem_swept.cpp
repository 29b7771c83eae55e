// Swept blades in an Is-XFEM body (issue 21 item 1: "the existing Blade, static or swept"): a
// blade moved rigidly from its pose to `to` cuts along the surface it sweeps. Checked against
// independent truths: a planar blade swept within its own plane through the box gives the static
// plane's pieces and volumes; a blade swept across its plane cuts where it passes first (the
// start face) when it leaves the body through the far side, both ways round; and swept across
// with its edge inside the body, its cut faces lie on the swept surface (the start face and the
// quad its leading edge sweeps).
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/xfem_blades.h"
#include "xfem/cut_body.h"

namespace gf::detail {
namespace {

using test::planarBlade;

XfemBodyDef boxDef() { return test::xfemBox(1e7); }

BladePose shifted(Vec3 d) {
  BladePose p;
  p.translation = d;
  return p;
}

TEST(XfemSwept, InPlaneSweepGivesTheStaticPlanesPieces) {
  const double a = 0.93, b = 0.2, c = 0.1;
  XfemBodyDef byPlane = boxDef();
  byPlane.planes = {test::slantedPlane(a, b, c)};
  auto plane = XfemBody::create(byPlane);
  ASSERT_TRUE(plane.ok()) << plane.error().message;
  const double exactLeft = a + b / 2 + c / 2;
  for (int n : {1, 3}) {
    // The blade covers y, z in [-0.5, 1.5]; it starts 2 m lower along its plane (wholly below
    // the box) and ends 2 m higher (wholly above): only the sweep crosses the body.
    const Vec3 along{b, 1, 0};  // in the plane x = a + b y + c z
    XfemBodyDef bySweep = boxDef();
    bySweep.blades = {
        {planarBlade(a, b, c, -0.5, 1.5, n), shifted(-2.0 * along), shifted(2.0 * along)}};
    auto sweep = XfemBody::create(bySweep);
    ASSERT_TRUE(sweep.ok()) << sweep.error().message;
    // Static at its start or end pose, the blade misses the body.
    XfemBodyDef atStart = bySweep;
    atStart.blades[0].to.reset();
    auto start = XfemBody::create(atStart);
    ASSERT_TRUE(start.ok()) << start.error().message;
    EXPECT_EQ(start.value()->pieces().size(), 1u);
    EXPECT_EQ(start.value()->cutTetCount(), 0);

    const XfemBody &p = *plane.value(), &q = *sweep.value();
    ASSERT_EQ(q.pieces().size(), 2u);
    double worst = 0;
    for (unsigned mask : {0u, 1u}) {
      const double vp = p.pieces()[size_t(p.pieceWithMask(mask))].volume;
      const double vq = q.pieces()[size_t(q.pieceWithMask(mask))].volume;
      const double exact = mask ? 2 - exactLeft : exactLeft;
      worst = std::max({worst, std::abs(vq - vp) / vp, std::abs(vq - exact) / exact});
    }
    double off = 0;
    for (const XfemCutFace& f : q.cutFaces())
      for (int i = 0; i < f.polygon.count; ++i)
        off = std::max(off, std::abs(planeDistance(byPlane.planes[0], f.polygon.v[i])));
    std::printf(
        "in-plane sweep, %dx%d blade: %zu pieces, volumes vs plane and exact <= %.1e rel.; cut "
        "faces %.1e off the plane; %d cut tets (plane %d)\n",
        n, n, q.pieces().size(), worst, off, q.cutTetCount(), p.cutTetCount());
    EXPECT_LE(worst, 1e-10);
    EXPECT_LE(off, 1e-12);
    EXPECT_EQ(q.cutTetCount(), p.cutTetCount());
  }
}

// A horizontal blade (y = 0.4, normal +y) over x in [-1, xEdge], z in [-1, 2], swept by dy.
XfemBlade horizontalBlade(double xEdge, double dy) {
  XfemBlade blade;
  blade.blade.vertices = {-1, 0.4, -1, -1, 0.4, 2, xEdge, 0.4, 2, xEdge, 0.4, -1};
  blade.blade.triangles = {0, 1, 2, 0, 2, 3};  // (0,0,3) x (xEdge+1,0,3): normal +y
  blade.to = shifted({0, dy, 0});
  return blade;
}

TEST(XfemSwept, SweepAcrossThroughTheBodyCutsWhereItEnters) {
  for (double dy : {2.0, -2.0}) {
    XfemBodyDef def = boxDef();
    def.blades = {horizontalBlade(3, dy)};
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    const XfemBody& body = *made.value();
    ASSERT_EQ(body.pieces().size(), 2u) << dy;
    // Leaving through the top (bottom), the swept volume's only face in the body is the start
    // blade at y = 0.4: below it 0.8 m^3, above 1.2 m^3.
    const double lower = std::min(body.pieces()[0].volume, body.pieces()[1].volume);
    double off = 0;
    for (const XfemCutFace& f : body.cutFaces())
      for (int i = 0; i < f.polygon.count; ++i)
        off = std::max(off, std::abs(f.polygon.v[i].y - 0.4));
    std::printf(
        "swept across by dy = %+.0f: pieces %.15f and %.15f m^3, cut faces %.1e off y = 0.4\n", dy,
        body.pieces()[0].volume, body.pieces()[1].volume, off);
    EXPECT_NEAR(lower, 0.8, 1e-10 * 0.8) << dy;
    EXPECT_NEAR(body.pieces()[0].volume + body.pieces()[1].volume, 2.0, 1e-12) << dy;
    EXPECT_LE(off, 1e-12) << dy;
  }
}

TEST(XfemSwept, SweepAcrossWithItsEdgeInsideCutsTheSweptSurface) {
  // The blade's edge x = 0.9 is inside the body: swept up, it cuts y = 0.4 for x < 0.9 and the
  // quad x = 0.9 for y > 0.4, cutting the block x < 0.9, y > 0.4 (0.54 m^3) out of the box. The
  // surface folds along x = 0.9, y = 0.4 inside a column of tets (x in [2/3, 1], y in [1/3,
  // 2/3]): each is crossed once per edge, so it is cut along its crossing points' plane, which
  // strays from the fold by up to the reported deviation (blade_path.h), and the block's volume
  // is exact up to that column's share.
  XfemBodyDef def = boxDef();
  def.blades = {horizontalBlade(0.9, 2.0)};
  auto made = XfemBody::create(def);
  ASSERT_TRUE(made.ok()) << made.error().message;
  const XfemBody& body = *made.value();
  const XfemCutReport& r = body.cutReports()[0];
  double offExact = 0, offFold = 0, exactArea = 0, foldArea = 0;
  for (const XfemCutFace& f : body.cutFaces()) {
    double off = 0;
    for (int i = 0; i < f.polygon.count; ++i) {
      const Vec3 x = f.polygon.v[i];
      // Distance to the swept surface: the start face (x <= 0.9) or the edge's quad (y >= 0.4).
      const double toStart = std::hypot(x.y - 0.4, std::max(0.0, x.x - 0.9));
      const double toQuad = std::hypot(x.x - 0.9, std::max(0.0, 0.4 - x.y));
      off = std::max(off, std::min(toStart, toQuad));
    }
    // The fold's column of tets: x in [2/3, 1], y in [1/3, 2/3].
    Vec3 c;
    for (int i = 0; i < f.polygon.count; ++i) c += f.polygon.v[i];
    c = (1.0 / f.polygon.count) * c;
    const bool fold = c.x > 2.0 / 3 && c.x < 1 && c.y > 1.0 / 3 && c.y < 2.0 / 3;
    (fold ? offFold : offExact) = std::max(fold ? offFold : offExact, off);
    (fold ? foldArea : exactArea) += polygonArea(f.polygon);
  }
  ASSERT_EQ(body.pieces().size(), 2u);
  const int block = body.pieces()[0].volume < body.pieces()[1].volume ? 0 : 1;
  const double blockVolume = body.pieces()[size_t(block)].volume;
  std::printf(
      "swept across, edge inside: %d full / %d partial tets, %zu pieces; cut faces off the swept "
      "surface %.1e outside the fold's column (area %.4f), %.3f inside it (area %.4f; reported "
      "deviation %.3f); the cut-out block %.4f m^3 (swept 0.54, the column holds 0.111)\n",
      r.fullTets, r.partialTets, body.pieces().size(), offExact, exactArea, offFold, foldArea,
      r.maxDeviation, blockVolume);
  EXPECT_LE(offExact, 1e-12);
  EXPECT_GT(exactArea, 0.9);  // of 0.9 + 0.6 m^2 of swept surface in the body
  EXPECT_LE(offFold, r.maxDeviation + 1e-12);
  EXPECT_LT(std::abs(blockVolume - 0.54), 0.111 / 2);
}

TEST(XfemSwept, BadSweptPoseIsRefusedNamingTheBlade) {
  XfemBodyDef def = boxDef();
  def.blades = {horizontalBlade(3, 2.0)};
  def.blades[0].to->translation.x = std::nan("");
  auto made = XfemBody::create(def);
  ASSERT_FALSE(made.ok());
  EXPECT_NE(made.error().message.find("blades[0]"), std::string::npos) << made.error().message;
  EXPECT_NE(made.error().message.find("not finite"), std::string::npos) << made.error().message;
}

}  // namespace
}  // namespace gf::detail
