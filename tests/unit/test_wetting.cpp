// Wetting (thesis sec 7.2.1-7.2.2): the effective elasticity of eq 7.1-7.4 against a literal
// tensor evaluation and its bounds, and the water transport's conservation, bounds and
// validation.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iostream>
#include <numeric>

#include "kernels/wetting.h"
#include "sculpt/wetting.h"

namespace gf {
namespace {

WorldDef worldDef(float gravityY) {
  WorldDef d;
  d.gravity = {0, gravityY, 0};
  return d;
}

using Mat6 = Eigen::Matrix<double, 6, 6>;

// Isotropic stiffness in Mandel notation (normal block, then shear entries 2 mu).
Mat6 mandelStiffness(double k, double mu) {
  const double lambda = k - 2.0 / 3.0 * mu;
  Mat6 e = Mat6::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) e(i, j) = lambda + (i == j ? 2 * mu : 0);
  for (int i = 3; i < 6; ++i) e(i, i) = 2 * mu;
  return e;
}

// Eshelby's tensor of a sphere in a matrix of Poisson ratio nu from its classical components
// (Mura 1987, eq 11.21): S_1111, S_1122, S_1212, in Mandel notation.
Mat6 mandelEshelbySphere(double nu) {
  const double d = 15 * (1 - nu);
  Mat6 p = Mat6::Zero();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p(i, j) = i == j ? (7 - 5 * nu) / d : (5 * nu - 1) / d;
  for (int i = 3; i < 6; ++i) p(i, i) = 2 * (4 - 5 * nu) / d;
  return p;
}

// eq 7.4 as written, S_eff = [1 + phi (Q - P)^-1] S_s with Q = (E_s - E_w)^-1 E_s, read back as
// (k, mu) from the compliance's response to a hydrostatic and a shear stress.
IsoModuli literalEq74(IsoModuli s, IsoModuli w, double phi) {
  const Mat6 es = mandelStiffness(s.k, s.mu), ew = mandelStiffness(w.k, w.mu);
  const double nu = poissonOf(s);
  const Mat6 q = (es - ew).inverse() * es;
  const Mat6 seff =
      (Mat6::Identity() + phi * (q - mandelEshelbySphere(nu)).inverse()) * es.inverse();
  Eigen::Matrix<double, 6, 1> hydro = Eigen::Matrix<double, 6, 1>::Zero();
  hydro.head<3>().setOnes();
  const double volumetric = (seff * hydro).head<3>().sum();
  return {1 / volumetric, 1 / (2 * seff(3, 3))};
}

TEST(WettingElasticity, Eq74MatchesTheLiteralTensorFormula) {
  for (double nu : {0.0, 0.3, 0.45})
    for (double kw : {0.0, 2.2e9}) {
      const IsoModuli s = isoFromYoung(1e6, nu), w{kw, 0};
      // Dilute range, where eq 7.3 does not clamp.
      for (double phi : {0.01, 0.05, 0.1, 0.2}) {
        const IsoModuli ours = eshelbyEffective(s, w, phi), ref = literalEq74(s, w, phi);
        EXPECT_NEAR(ours.k, ref.k, 1e-9 * ref.k) << "nu " << nu << " kw " << kw << " phi " << phi;
        EXPECT_NEAR(ours.mu, ref.mu, 1e-9 * ref.mu) << "nu " << nu << " kw " << kw;
      }
    }
}

TEST(WettingElasticity, BetweenReussAndVoigtAtEverySaturation) {
  for (double nu : {0.0, 0.3, 0.45})
    for (double kw : {0.0, 2.2e9})
      for (double porosity : {0.2, 0.4, 0.95}) {
        const IsoModuli s = isoFromYoung(1e6, nu), w{kw, 0};
        const IsoModuli at0 = eshelbyEffective(s, w, 0);
        EXPECT_EQ(at0.k, s.k);
        EXPECT_EQ(at0.mu, s.mu);
        EXPECT_EQ(youngOf(at0), youngOf(s));
        double prevMu = s.mu;
        for (int i = 0; i <= 1000; ++i) {
          const double saturation = i / 1000.0, phi = porosity * saturation;
          const IsoModuli e = eshelbyEffective(s, w, phi);
          const IsoModuli hi = voigtBound(s, w, phi), lo = reussBound(s, w, phi);
          const double tol = 1e-12 * s.k;
          ASSERT_LE(lo.k, e.k + tol) << "S " << saturation << " nu " << nu << " kw " << kw;
          ASSERT_LE(e.k, hi.k + tol) << "S " << saturation << " nu " << nu << " kw " << kw;
          ASSERT_LE(lo.mu, e.mu + tol) << "S " << saturation << " nu " << nu << " kw " << kw;
          ASSERT_LE(e.mu, hi.mu + tol) << "S " << saturation << " nu " << nu << " kw " << kw;
          // Young's modulus grows with k and mu, so it is bracketed too.
          ASSERT_LE(youngOf(lo), youngOf(e) * (1 + 1e-12));
          ASSERT_LE(youngOf(e), youngOf(hi) * (1 + 1e-12));
          // Water has no shear stiffness: wetter is never stiffer in shear.
          ASSERT_LE(e.mu, prevMu * (1 + 1e-12));
          prevMu = e.mu;
          if (saturation > 0) {
            ASSERT_LT(e.mu, s.mu);
          }
        }
      }
}

TEST(WettingElasticity, DrainedWaterSoftensYoungsModulusSmoothly) {
  const IsoModuli s = isoFromYoung(1e6, 0.3), w{0, 0};
  double prev = youngOf(s), largestJump = 0;
  for (int i = 1; i <= 1000; ++i) {
    const double e = youngOf(eshelbyEffective(s, w, 0.4 * i / 1000.0));
    EXPECT_LT(e, prev);
    largestJump = std::max(largestJump, prev - e);
    prev = e;
  }
  // Continuous: no step of 1/1000 in saturation moves E by more than 0.2 % of the dry value.
  EXPECT_LT(largestJump, 2e-3 * youngOf(s));
  EXPECT_GT(prev, 0.3 * youngOf(s));  // a saturated tet keeps a stiff enough matrix
}

BodyDef cubeBody(double diffusivity) {
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 5, 5, 5);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  def.wetting.diffusivity = diffusivity;
  def.grips.push_back({});
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n + 1] < 1e-9) def.grips[0].nodes.push_back(int32_t(n));
  return def;
}

double total(std::span<const double> v) { return std::accumulate(v.begin(), v.end(), 0.0); }

TEST(Wetting, DiffusionConservesWaterMass) {
  World world(worldDef(0));
  const BodyId id = world.createBody(cubeBody(1e-3)).value();
  WetBrush brush;
  brush.centre = {0, 0.1f, 0};
  brush.radius = 0.04f;
  brush.rate = 30;  // saturates the corner within the first step
  ASSERT_TRUE(world.wet(id, brush));
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  const double m0 = total(world.waterMass(id));
  ASSERT_GT(m0, 0);
  double largestDrift = 0;
  for (int k = 0; k < 120; ++k) {
    ASSERT_TRUE(world.step(1.0 / 60).ok());
    largestDrift = std::max(largestDrift, std::abs(total(world.waterMass(id)) - m0) / m0);
  }
  EXPECT_LE(largestDrift, 1e-12);
  RecordProperty("largest_relative_drift", std::to_string(largestDrift));
  std::cout << "[ wetting ] water mass drift over 120 steps (relative): " << largestDrift << "\n";
  // It spread (the far corner got some) and stays a saturation (max principle).
  const std::span<const double> s = world.saturation(id);
  const auto [lo, hi] = std::minmax_element(s.begin(), s.end());
  EXPECT_GE(*lo, 0.0);
  EXPECT_LE(*hi, 1.0);
  EXPECT_GT(*lo, 0.0);
  EXPECT_LT(*hi, 1.0);
}

TEST(Wetting, StiffDiffusionSubstepsStayBoundedAndReachEquilibrium) {
  // A diffusivity a hundred times past one step's bound: the substeps keep S in [0, 1], and the
  // water evens out to total / capacity.
  BodyDef def = cubeBody(1e-3);
  detail::FemModel model = detail::buildFemModel(def);
  detail::WettingModel w = detail::buildWettingModel(model, WettingSettings{0.4, 1000, 1.0, 0});
  const double dt = 1.0 / 60;
  EXPECT_GT(detail::diffusionSubsteps(w, dt), 100);
  std::vector<double> water(size_t(model.tetCount), 0.0);
  water[0] = w.capacity[0];  // one saturated tet
  const double m0 = total(water), c = total(w.capacity);
  for (int k = 0; k < 20; ++k) {
    detail::advanceWater(model, w, water, model.restPositions.data(), {}, dt, serialJobs());
    for (size_t t = 0; t < water.size(); ++t) {
      ASSERT_GE(water[t], 0.0);
      ASSERT_LE(water[t], w.capacity[t] * (1 + 1e-12));
    }
  }
  EXPECT_NEAR(total(water), m0, 1e-12 * m0);
  for (size_t t = 0; t < water.size(); ++t)
    EXPECT_NEAR(water[t] / w.capacity[t], m0 / c, 1e-6) << "tet " << t;
}

TEST(Wetting, DryingRemovesWaterAndNeverGoesNegative) {
  World world(worldDef(0));
  const BodyId id = world.createBody(cubeBody(0)).value();
  WetBrush brush;
  brush.centre = {0.05f, 0.1f, 0.05f};
  brush.radius = 0.03f;
  brush.rate = 0.5;
  ASSERT_TRUE(world.wet(id, brush));
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  const double wet = total(world.waterMass(id));
  EXPECT_GT(wet, 0);
  brush.rate = 100;
  ASSERT_TRUE(world.dry(id, brush));
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  for (double m : world.waterMass(id)) EXPECT_EQ(m, 0.0);
}

TEST(Wetting, ABodyNeverWettedHoldsNoWaterData) {
  World world(worldDef(0));
  const BodyId id = world.createBody(cubeBody(1e-3)).value();
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  EXPECT_TRUE(world.waterMass(id).empty());
  EXPECT_TRUE(world.saturation(id).empty());
  EXPECT_EQ(world.timings().wettingMs, 0.0);
}

TEST(Wetting, InvalidBrushesAndSettingsNameTheFieldAndChangeNothing) {
  World world(worldDef(0));
  const BodyId id = world.createBody(cubeBody(1e-3)).value();
  WetBrush bad;
  bad.radius = 0;
  auto r = world.wet(id, bad);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("wet: brush.radius"), std::string::npos) << r.error().message;
  bad = {};
  bad.rate = -1;
  r = world.dry(id, bad);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("dry: brush.rate"), std::string::npos) << r.error().message;
  bad = {};
  bad.centre.x = std::nanf("");
  r = world.wet(id, bad);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("brush.centre"), std::string::npos) << r.error().message;
  EXPECT_FALSE(world.wet(BodyId{}, WetBrush{}));
  EXPECT_TRUE(world.waterMass(id).empty());  // nothing was set up

  BodyDef def = cubeBody(1e-3);
  def.wetting.porosity = 1.0;
  auto c = world.createBody(def);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("wetting.porosity"), std::string::npos) << c.error().message;
  def = cubeBody(-1);
  c = world.createBody(def);
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("wetting.diffusivity"), std::string::npos) << c.error().message;
}

TEST(Wetting, SnapshotRestoresWaterBitForBit) {
  World world(worldDef(-9.81f));
  const BodyId id = world.createBody(cubeBody(1e-3)).value();
  WetBrush brush;
  brush.centre = {0.05f, 0.1f, 0.05f};
  brush.radius = 0.03f;
  ASSERT_TRUE(world.wet(id, brush));
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  const WorldSnapshot snap = world.snapshot();
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(world.step(1.0 / 60).ok());
  const std::vector<double> water(world.waterMass(id).begin(), world.waterMass(id).end());
  const uint64_t hash = world.stateHash();
  ASSERT_TRUE(world.restore(snap));
  for (int k = 0; k < 5; ++k) ASSERT_TRUE(world.step(1.0 / 60).ok());
  EXPECT_EQ(world.stateHash(), hash);
  const std::span<const double> again = world.waterMass(id);
  ASSERT_EQ(again.size(), water.size());
  for (size_t t = 0; t < water.size(); ++t) ASSERT_EQ(again[t], water[t]);
}

}  // namespace
}  // namespace gf
