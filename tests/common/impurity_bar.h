// The impurity tests' bar in uniaxial tension (nu = 0, grips pulling both ends apart), shared
// by tests/physics/test_impurity.cpp and tests/slow/test_impurity_stats.cpp.
#pragma once

#include <graphfrac/world.h>
#include <gtest/gtest.h>

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

}  // namespace gf::test
