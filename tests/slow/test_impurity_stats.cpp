// Impurity statistics over many seeds (thesis sec 5.5, issue 18's acceptance figures; 2-4 min
// on a loaded 2-core machine): the load at first fracture of a bar in tension over 20 seeds
// (degradation lowers it, upgradation raises it, more with a larger sigma), Gaussian against
// uniform noise of equal variance (similar fragment counts), the damp log's broken-edge count at
// dt and dt / 2, and the painted-band slab parting along its band over widths, potencies, seeds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/impurity_bar.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

struct Stats {
  double mean = 0, sd = 0, lo = 0, hi = 0;
};

Stats stats(const std::vector<double>& v) {
  Stats s;
  for (double x : v) s.mean += x / double(v.size());
  for (double x : v) s.sd += (x - s.mean) * (x - s.mean) / double(v.size() - 1);
  s.sd = std::sqrt(s.sd);
  s.lo = *std::min_element(v.begin(), v.end());
  s.hi = *std::max_element(v.begin(), v.end());
  return s;
}

using test::impurityFirstBreakStress;

TEST(ImpuritySlow, FirstFractureLoadOver20Seeds) {
  const double pure = impurityFirstBreakStress({});
  std::printf("pure bar: first break at %.4e Pa\n", pure);
  double shift[2][2] = {};
  const double sigmas[2] = {1, 3};
  for (int m = 0; m < 2; ++m)
    for (int k = 0; k < 2; ++k) {
      std::vector<double> rel;
      for (uint64_t seed = 1; seed <= 20; ++seed) {
        ImpuritySettings imp;
        imp.enabled = true;
        imp.sigma = sigmas[k];
        imp.seed = seed;
        imp.mode = m == 0 ? ImpurityMode::Degradation : ImpurityMode::Upgradation;
        rel.push_back(impurityFirstBreakStress(imp) / pure);
      }
      const Stats s = stats(rel);
      shift[m][k] = s.mean - 1;
      std::printf(
          "%s sigma %.0f, 20 seeds: first-break load / pure = %.4f +- %.4f (min %.4f, "
          "max %.4f)\n",
          m == 0 ? "degradation" : "upgradation", sigmas[k], s.mean, s.sd, s.lo, s.hi);
      if (m == 0) {
        EXPECT_LT(s.hi, 1.0 + 1e-9);
        EXPECT_LT(s.mean, 1.0);
      } else {
        EXPECT_GT(s.lo, 1.0 - 1e-9);
        EXPECT_GT(s.mean, 1.0);
      }
    }
  // The effect grows with sigma.
  EXPECT_LT(shift[0][1], shift[0][0]);
  EXPECT_GT(shift[1][1], shift[1][0]);
}

struct Torn {
  int fragments = 0, pieces = 0, broken = 0;
};

// Slab 0.4 x 0.1 x 0.02 (1 cm cells) torn by grips at 2 cm/s for 1 s (it stops carrying load
// after ~0.8 s): all fragments, pieces of at least 10 nodes, broken edges. Mass damping keeps the
// grips from tearing their own faces off at the first step, so the count is the crack's, not the
// grips'.
Torn tornSlab(ImpurityNoise noise, uint64_t seed) {
  BodyDef def;
  def.mesh = gen::box(0.4, 0.1, 0.02, 40, 10, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.massDamping = 5;
  def.fracture.enabled = true;
  def.fracture.strength = 3e4;
  def.fracture.impurities.enabled = true;
  def.fracture.impurities.sigma = 3;
  def.fracture.impurities.noise = noise;
  def.fracture.impurities.seed = seed;
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes =
      test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.4 - 1e-9; });
  left.velocity = glm::vec3(-0.02f, 0, 0);
  right.velocity = glm::vec3(0.02f, 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  if (!id.ok()) return {};
  for (int s = 0; s < 60; ++s) (void)world.step(1.0 / 60);
  Torn t;
  t.fragments = world.fractureStats(id.value()).fragments;
  t.broken = world.fractureStats(id.value()).brokenEdges;
  std::vector<int> size(size_t(t.fragments), 0);
  for (int32_t f : world.nodeFragments(id.value())) ++size[size_t(f)];
  for (int n : size) t.pieces += n >= 10;
  return t;
}

TEST(ImpuritySlow, GaussianAndUniformNoiseGiveSimilarFragmentCounts) {
  std::vector<double> fg, fu, pg, pu, bg, bu;
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    const Torn g = tornSlab(ImpurityNoise::Gaussian, seed);
    const Torn u = tornSlab(ImpurityNoise::Uniform, seed);
    fg.push_back(g.fragments);
    fu.push_back(u.fragments);
    pg.push_back(g.pieces);
    pu.push_back(u.pieces);
    bg.push_back(g.broken);
    bu.push_back(u.broken);
  }
  const Stats sg = stats(fg), su = stats(fu), qg = stats(pg), qu = stats(pu), eg = stats(bg),
              eu = stats(bu);
  std::printf(
      "torn slab over 10 seeds: fragments Gaussian %.1f +- %.1f (%.0f-%.0f), uniform %.1f +- "
      "%.1f (%.0f-%.0f); pieces >= 10 nodes %.1f +- %.1f vs %.1f +- %.1f; broken edges %.0f +- "
      "%.0f vs %.0f +- %.0f\n",
      sg.mean, sg.sd, sg.lo, sg.hi, su.mean, su.sd, su.lo, su.hi, qg.mean, qg.sd, qu.mean, qu.sd,
      eg.mean, eg.sd, eu.mean, eu.sd);
  // The seeds matter (else "similar" would say nothing). Pieces are printed, not checked: the
  // torn slab stays one graph piece plus loose nodes (docs/validation.md, known limits).
  EXPECT_GT(sg.sd, 0);
  EXPECT_GT(su.sd, 0);
  // Similar: the means differ by less than a quarter of the larger one.
  EXPECT_LT(std::fabs(sg.mean - su.mean), 0.25 * std::max(sg.mean, su.mean));
  EXPECT_LT(std::fabs(eg.mean - eu.mean), 0.25 * std::max(eg.mean, eu.mean));
}

int dampLogBroken(double dt, uint64_t seed) {
  BodyDef def;
  def.mesh = gen::cylinder(0.04, 0.6, 12, 30, 2);
  def.material = Material::stableNeoHookean(1e10, 0.45, 1000);
  def.solver.linearSolver = LinearSolverKind::Direct;
  def.fracture.enabled = true;
  def.fracture.strength = 1.5e9;
  def.fracture.impurities.enabled = true;
  def.fracture.impurities.sigma = 4;
  def.fracture.impurities.seed = seed;
  Grip pin, pull;
  pin.nodes = test::selectNodes(def.mesh, [](double, double y, double) { return y < 1e-9; });
  pull.nodes = test::selectNodes(def.mesh, [](double, double y, double) { return y > 0.6 - 1e-9; });
  pull.velocity = glm::vec3(0, 0.5f, 0);
  def.grips = {pin, pull};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok()) << (id.ok() ? "" : id.error().message);
  const int steps = int(std::lround(0.3 / dt));
  for (int s = 0; s < steps; ++s) (void)world.step(dt);
  return world.fractureStats(id.value()).brokenEdges;
}

TEST(ImpuritySlow, DampLogBreaksAsMuchAtHalfTheTimeStep) {
  std::vector<double> a, b;
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    a.push_back(dampLogBroken(0.005, seed));
    b.push_back(dampLogBroken(0.0025, seed));
  }
  const Stats sa = stats(a), sb = stats(b);
  std::printf(
      "damp log, broken edges at t = 0.3 s over 4 seeds: dt 5 ms %.1f +- %.1f, dt 2.5 ms "
      "%.1f +- %.1f (change %.1f %%)\n",
      sa.mean, sa.sd, sb.mean, sb.sd, 100 * (sb.mean / sa.mean - 1));
  EXPECT_GT(sa.mean, 0);
  EXPECT_LT(std::fabs(sb.mean / sa.mean - 1), 0.10);
}

// Eight slab runs (~10-30 s): the slow label, not CI's physics label.
// The random-graph slab parts, along the band, for two band widths, two potencies and two
// seeds of background impurities. Before severed edges were released (an unbroken edge whose
// every tet had split carried no stress the criterion could see), the crack stopped a few
// edges short and the slab never parted (docs/validation.md).
TEST(ImpuritySlow, PaintedBandPartsTheSlabAlongItForWidthsPotenciesAndSeeds) {
  for (double width : {0.03, 0.04})
    for (double potency : {0.5, 0.3})
      for (uint64_t seed : {1u, 2u}) {
        const test::BandRun r = test::paintedBandSlab(true, width, potency, 1.0, seed);
        std::printf(
            "band %.0f mm, potency %.1f, seed %d: parted %d after %d steps, %d fragments, "
            "%.1f %% of %d broken edges in the band, %.1f %% of the parting edges\n",
            1e3 * width, potency, int(seed), int(r.parted), r.steps, r.fragments,
            100 * r.brokenInBand, r.broken, 100 * r.partingInBand);
        EXPECT_TRUE(r.parted) << width << " " << potency << " " << seed;
        EXPECT_GE(r.partingInBand, 0.8) << width << " " << potency << " " << seed;
      }
}

}  // namespace
}  // namespace gf
