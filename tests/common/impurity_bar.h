// The impurity tests' bar in uniaxial tension (nu = 0, grips pulling both ends apart) and the
// painted-band slab, shared by tests/physics/test_impurity.cpp and
// tests/slow/test_impurity_stats.cpp.
#pragma once

#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "common/sim_helpers.h"

namespace gf::test {

constexpr double kBarLength = 1.0, kBarE = 1e6, kBarGripSpeed = 0.01, kBarStrength = 2e4;

inline BodyDef impurityTensionBar(const ImpuritySettings& imp) {
  BodyDef def;
  def.mesh = gen::box(kBarLength, 0.1, 0.1, 20, 2, 2);
  // nu = 0: the stress is uniaxial, so an edge at angle theta to x sees sigma cos^2 theta.
  def.material = Material::stableNeoHookean(kBarE, 0.0, 1000);
  def.material.massDamping = 5;
  def.fracture.enabled = true;
  def.fracture.strength = kBarStrength;
  def.fracture.impurities = imp;
  Grip left, right;
  left.nodes = selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes =
      selectNodes(def.mesh, [](double x, double, double) { return x > kBarLength - 1e-9; });
  left.velocity = glm::vec3(-kBarGripSpeed, 0, 0);
  right.velocity = glm::vec3(kBarGripSpeed, 0, 0);
  def.grips = {left, right};
  return def;
}

/// Nominal stress E * strain at the step of the bar's first break (-1: none in 30 s).
inline double impurityFirstBreakStress(const ImpuritySettings& imp) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(impurityTensionBar(imp));
  EXPECT_TRUE(id.ok()) << (id.ok() ? "" : id.error().message);
  if (!id.ok()) return 0;
  const double dt = 1e-2;
  for (int s = 1; s < 3000; ++s) {
    const double stress = kBarE * (2 * kBarGripSpeed * (s - 1) * dt) / kBarLength;
    (void)world.step(dt);
    if (!world.fractureEvents().empty()) return stress;
  }
  return -1;
}

// Slab 0.3 x 0.1 x 0.02 (cells of 1 cm) pulled along x until it parts (at most 5 s; shared by
// tests/physics/test_impurity.cpp and tests/slow/test_impurity_stats.cpp), with a
// band of the given width and potency painted through it along a diagonal the load alone would
// not pick, optionally on background impurities (sigma 1, degradation). Measures, 10 steps
// after it parts, the fraction of broken edges whose rest midpoint lies in the band and the
// fraction of the edges between the two grips' fragments (the crack that parted it) that do.
struct BandRun {
  bool parted = false;  ///< the two grips are in different fragments
  int steps = 0, broken = 0, fragments = 0;
  double brokenInBand = 0, partingInBand = 0;
};

inline BandRun paintedBandSlab(bool randomGraph, double width, double potency, double sigma,
                               uint64_t seed) {
  const double speed = 0.01;
  BodyDef def;
  const double Lx = 0.3, Ly = 0.1, Lz = 0.02;
  def.mesh = gen::box(Lx, Ly, Lz, 30, 10, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.massDamping = 5;
  def.fracture.enabled = true;
  def.fracture.strength = 3e4;
  def.fracture.impurities.enabled = sigma > 0;
  def.fracture.impurities.sigma = sigma;
  def.fracture.impurities.seed = seed;
  def.fracture.impurities.randomGraph = randomGraph;
  ImpurityMap band;
  const glm::dvec3 p0(0.12, 0, Lz), p1(0.18, Ly, Lz);
  band.points = {p0, p1};
  band.width = width;
  band.depth = Lz;
  band.potency = potency;
  def.fracture.impurityMaps = {band};
  Grip left, right;
  left.nodes = selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = selectNodes(def.mesh, [&](double x, double, double) { return x > Lx - 1e-9; });
  left.velocity = glm::vec3(-float(speed), 0, 0);
  right.velocity = glm::vec3(float(speed), 0, 0);
  def.grips = {left, right};
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok()) << (id.ok() ? "" : id.error().message);
  BandRun run;
  if (!id.ok()) return run;
  auto parted = [&] {
    const auto frag = world.nodeFragments(id.value());
    return frag[size_t(left.nodes[0])] != frag[size_t(right.nodes[0])];
  };
  for (; run.steps < 300 && !parted(); ++run.steps) (void)world.step(1.0 / 60);
  run.parted = parted();
  for (int s = 0; s < 10; ++s) (void)world.step(1.0 / 60);
  const auto edges = world.edges(id.value());
  const auto broken = world.brokenEdges(id.value());
  const auto frag = world.nodeFragments(id.value());
  const int32_t fl = frag[size_t(left.nodes[0])], fr = frag[size_t(right.nodes[0])];
  int inBand = 0, parting = 0, partingIn = 0;
  const glm::dvec2 a(p0), d = glm::normalize(glm::dvec2(p1) - glm::dvec2(p0));
  for (size_t e = 0; e < broken.size(); ++e) {
    if (!broken[e]) continue;
    const int32_t i = edges[2 * e], j = edges[2 * e + 1];
    const double* x0 = &def.mesh.positions[3 * size_t(i)];
    const double* x1 = &def.mesh.positions[3 * size_t(j)];
    const glm::dvec2 r = glm::dvec2(0.5 * (x0[0] + x1[0]), 0.5 * (x0[1] + x1[1])) - a;
    const bool in = std::fabs(r.x * d.y - r.y * d.x) <= 0.5 * width;
    ++run.broken;
    inBand += in;
    const int32_t fi = frag[size_t(i)], fj = frag[size_t(j)];
    if ((fi == fl && fj == fr) || (fi == fr && fj == fl)) {
      ++parting;
      partingIn += in;
    }
  }
  run.fragments = world.fractureStats(id.value()).fragments;
  run.brokenInBand = run.broken ? double(inBand) / run.broken : 0;
  run.partingInBand = parting ? double(partingIn) / parting : 0;
  return run;
}

}  // namespace gf::test
