// A box cut through by a plane with Is-XFEM (thesis ch 3), checked against exact truths: each
// piece's volume is the exact split of the box; the cut polygons lie on the plane and tile its
// section; with one end held, the free piece falls at exactly g (its centre of mass follows the
// implicit Euler recurrence of free fall, so the gap opens as g t^2 / 2) while the held piece only
// sags; without gravity the momentum of the body and of each piece is conserved; and the
// stable enrichment (k = 0.1) keeps the step matrix far better conditioned than classic XFEM
// (k = 0) when the plane passes 1e-3 to 1e-6 of a cell from a node layer (slivers).
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <random>

#include "xfem/cut_body.h"

namespace gf::detail {
namespace {

constexpr double kG = 9.81;

// x = a + b y + c z across the box [0,2]x[0,1]x[0,1]: the positive side is x above it.
struct SlantedCut {
  double a = 0.93, b = 0.2, c = 0.1;
  CutPlane plane() const {
    const double len = std::sqrt(1 + b * b + c * c);
    return {{1 / len, -b / len, -c / len}, a / len};
  }
  double leftVolume() const { return a + b / 2 + c / 2; }  // integral of x over y, z in [0,1]
  double sectionArea() const { return std::sqrt(1 + b * b + c * c); }
};

XfemBodyDef slantedBox(double k) {
  XfemBodyDef def;
  def.mesh = gen::box(2, 1, 1, 4, 2, 2);
  def.planes = {SlantedCut{}.plane()};
  def.k = k;
  def.material = {1e7, 0.3, 1000};
  def.dt = 1e-3;
  return def;
}

TEST(XfemCutBody, PieceVolumesAndCutFacesAreExact) {
  const SlantedCut cut;
  for (double k : {0.1, 0.0}) {
    auto made = XfemBody::create(slantedBox(k));
    ASSERT_TRUE(made.ok()) << made.error().message;
    const XfemBody& body = *made.value();
    ASSERT_EQ(body.pieces().size(), 2u);
    const int l = body.pieceWithMask(0u), r = body.pieceWithMask(1u);
    ASSERT_GE(l, 0);
    ASSERT_GE(r, 0);
    const double left = body.pieces()[size_t(l)].volume, right = body.pieces()[size_t(r)].volume;
    const double leftErr = std::abs(left - cut.leftVolume()) / cut.leftVolume();
    const double rightErr = std::abs(right - (2 - cut.leftVolume())) / (2 - cut.leftVolume());
    double offPlane = 0, area = 0;
    for (const XfemCutFace& f : body.cutFaces()) {
      for (int i = 0; i < f.polygon.count; ++i)
        offPlane = std::max(offPlane, std::abs(planeDistance(cut.plane(), f.polygon.v[i])));
      area += polygonArea(f.polygon);
    }
    const double areaErr = std::abs(area - cut.sectionArea()) / cut.sectionArea();
    std::printf(
        "k = %.1f: %d cut tets, %d enriched functions; piece volumes rel. error %.2e / "
        "%.2e; cut-face vertices off the plane <= %.2e (box size 2); %zu cut polygons, "
        "area rel. error %.2e\n",
        k, body.cutTetCount(), body.enrichedCount(), leftErr, rightErr, offPlane,
        body.cutFaces().size(), areaErr);
    EXPECT_LE(leftErr, 1e-10);
    EXPECT_LE(rightErr, 1e-10);
    EXPECT_LE(offPlane, 1e-12);
    EXPECT_LE(areaErr, 1e-12);
    EXPECT_GT(body.cutTetCount(), 0);
  }
}

TEST(XfemCutBody, FreePieceFallsAwayFromHeldPiece) {
  for (double k : {0.1, 0.0}) {
    XfemBodyDef def = slantedBox(k);
    for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
      if (def.mesh.positions[3 * size_t(n)] == 0) def.fixedNodes.push_back(n);
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    XfemBody& body = *made.value();
    const int steps = 200;
    for (int s = 0; s < steps; ++s) body.step();
    const double t = steps * def.dt;
    // Implicit Euler free fall: v_n = n g dt, y_n = g dt^2 n (n + 1) / 2.
    const double discrete = kG * def.dt * def.dt * steps * (steps + 1) / 2;
    const double continuous = kG * t * t / 2;
    ASSERT_EQ(body.pieces().size(), 2u);
    const Vec3 free = body.pieceMeanDisplacement(body.pieceWithMask(1u)),
               held = body.pieceMeanDisplacement(body.pieceWithMask(0u));
    const double gap = held.y - free.y;
    std::printf(
        "k = %.1f, t = %.3f s: free piece fell %.9f m (implicit Euler free fall %.9f, "
        "g t^2/2 = %.9f), held piece moved %.2e m, gap %.6f m (g t^2/2 %+.2f%%)\n",
        k, t, -free.y, discrete, continuous, norm(held), gap,
        100 * (gap - continuous) / continuous);
    EXPECT_NEAR(-free.y, discrete, 1e-9 * discrete);
    EXPECT_NEAR(free.x, 0, 1e-9 * discrete);
    EXPECT_NEAR(free.z, 0, 1e-9 * discrete);
    // The held piece only sags elastically (E = 1e7 Pa): under 2% of the fall.
    EXPECT_LT(norm(held), 0.02 * continuous);
    // The gap is g t^2 / 2 up to the scheme's dt / t and the held piece's sag.
    EXPECT_NEAR(gap, continuous, continuous * (1.0 / steps) + norm(held));
  }
}

TEST(XfemCutBody, MomentumIsConservedWithoutGravity) {
  for (double k : {0.1, 0.0}) {
    XfemBodyDef def = slantedBox(k);
    def.gravity = {0, 0, 0};
    auto made = XfemBody::create(def);
    ASSERT_TRUE(made.ok()) << made.error().message;
    XfemBody& body = *made.value();
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (Eigen::Index i = 0; i < body.velocity().size(); ++i) body.velocity()[i] = u(rng);
    ASSERT_EQ(body.pieces().size(), 2u);
    const Vec3 p0 = body.momentum(), left0 = body.momentum(0), right0 = body.momentum(1);
    const double scale = norm(left0) + norm(right0);
    for (int s = 0; s < 100; ++s) body.step();
    const double drift = norm(body.momentum() - p0) / scale;
    const double driftPieces =
        std::max(norm(body.momentum(0) - left0), norm(body.momentum(1) - right0)) / scale;
    std::printf(
        "k = %.1f: momentum drift over 100 steps %.2e (body), %.2e (each piece), of "
        "|p_left| + |p_right| = %.3f kg m/s\n",
        k, drift, driftPieces, scale);
    EXPECT_LE(drift, 1e-12);
    EXPECT_LE(driftPieces, 1e-12);
  }
}

// A NaN put into the state is refused by the step (the factor's back-substitution reports a
// non-finite result) and leaves the state as it was, rather than spreading through the body.
TEST(XfemCutBody, NonFiniteVelocityIsRefusedAndLeavesTheStateUnchanged) {
  auto made = XfemBody::create(slantedBox(0.1));
  ASSERT_TRUE(made.ok()) << made.error().message;
  XfemBody& body = *made.value();
  ASSERT_TRUE(body.step());
  const Eigen::VectorXd u = body.displacement();
  body.velocity()[4] = std::nan("");
  const Eigen::VectorXd v = body.velocity();
  EXPECT_FALSE(body.step());
  EXPECT_EQ((body.displacement() - u).cwiseAbs().maxCoeff(), 0.0);
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    if (i == 4) continue;
    ASSERT_EQ(body.velocity()[i], v[i]) << i;
  }
  body.velocity()[4] = 0;
  EXPECT_TRUE(body.step());
  EXPECT_TRUE(body.displacement().allFinite());
}

double conditionNumber(const Eigen::MatrixXd& a) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(a, Eigen::EigenvaluesOnly);
  const double lo = es.eigenvalues().minCoeff(), hi = es.eigenvalues().maxCoeff();
  return lo > 0 ? hi / lo : INFINITY;
}

TEST(XfemCutBody, StableEnrichmentConditionsSliverCuts) {
  std::printf(
      "cond(M + dt^2 K), unit cube 2x2x2 cells, plane x = 0.5 + eps * 0.5:\n"
      "     eps    k=0.1      k=0  k=0.1 eq3.15  k=0 eq3.15\n");
  for (double eps : {1e-1, 1e-2, 1e-3, 1e-4, 1e-6}) {
    double cond[2][2];
    for (int kk = 0; kk < 2; ++kk) {
      XfemBodyDef def;
      def.mesh = gen::box(1, 1, 1, 2, 2, 2);
      def.planes = {{{1, 0, 0}, 0.5 + eps * 0.5}};
      def.k = kk == 0 ? 0.1 : 0.0;
      def.material = {1e6, 0.3, 1000};
      def.dt = 1e-3;
      auto made = XfemBody::create(def);
      ASSERT_TRUE(made.ok()) << made.error().message;
      const XfemBody& body = *made.value();
      ASSERT_EQ(body.pieces().size(), 2u);
      const double left = body.pieces()[size_t(body.pieceWithMask(0u))].volume;
      EXPECT_NEAR(left, 0.5 + eps * 0.5, 1e-10 * (0.5 + eps * 0.5));
      const Eigen::MatrixXd a(body.stepMatrix());
      const Eigen::VectorXd t = body.volumeRatioScaling();
      cond[kk][0] = conditionNumber(a);
      cond[kk][1] = conditionNumber(t.asDiagonal() * a * t.asDiagonal());  // eq 3.14
      EXPECT_TRUE(std::isfinite(cond[kk][0]) || kk == 1);
    }
    std::printf("  %6.0e %8.2e %8.2e %12.2e %11.2e\n", eps, cond[0][0], cond[1][0], cond[0][1],
                cond[1][1]);
    if (eps <= 1e-3) {
      EXPECT_LE(10 * cond[0][0], cond[1][0]) << eps;
    }
  }
}

}  // namespace
}  // namespace gf::detail
