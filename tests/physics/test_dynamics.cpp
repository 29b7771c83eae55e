// Dynamics against conservation laws: energy with damping off, linear and angular momentum
// with no external forces.
#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

#include "common/sim_helpers.h"

namespace gf {
namespace {

SolverSettings fullNewton() {
  SolverSettings s;
  s.newtonIterations = 30;
  s.newtonTolerance = 1e-10;
  s.linearSolver = LinearSolverKind::Direct;
  return s;
}

// A clamped beam released with a smooth transverse velocity vibrates in its first mode.
// Backward Euler dissipates ~(omega dt)^2 of the energy per step, so dt is chosen with
// omega_1 dt ~ 1e-3: the test bounds drift and checks that energy never grows.
TEST(Energy, UndampedVibratingBeamDriftsLessThanOnePercent) {
  const double L = 1.0, h = 0.05;
  BodyDef def;
  def.mesh = gen::box(L, h, h, 20, 2, 2);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.solver = fullNewton();
  Grip clamp;
  clamp.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  def.grips.push_back(clamp);
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  std::vector<double> v(3 * def.mesh.nodeCount(), 0.0);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double s = def.mesh.positions[3 * n] / L;
    v[3 * n + 1] = 0.1 * s * s;  // first-mode-like shape, 0.1 m/s at the tip
  }
  ASSERT_TRUE(world.setVelocities(id.value(), v).ok());
  const double E0 = test::totalEnergy(world.stats(id.value()));
  double worst = 0, maxGain = 0;
  for (int s = 0; s < 1000; ++s) {
    const StepStatus st = world.step(5e-4);
    ASSERT_TRUE(st.ok()) << st.flags << " " << st.message << " step " << s;
    const double E = test::totalEnergy(world.stats(id.value()));
    worst = std::max(worst, std::abs(E - E0) / E0);
    maxGain = std::max(maxGain, (E - E0) / E0);
  }
  std::printf("undamped beam, 1000 steps of 0.5 ms: max |dE|/E0 = %.4f%%, max gain %.2e\n",
              100 * worst, maxGain);
  EXPECT_LT(worst, 0.01);
  EXPECT_LT(maxGain, 1e-6);  // backward Euler must never create energy
}

// A free, pre-stretched, spinning block: no external force. Linear momentum is conserved to
// round-off (internal forces sum to zero). Plain backward Euler changes angular momentum by
// dt^2 sum v x f per step; the co-rotated step (SolverSettings::corotatedInertia) gives the
// free body its angular momentum back exactly, and its energy never rises.
struct MomentumDrift {
  double linear = 0, angular = 0, energyRise = 0;
};

MomentumDrift spinFreeBody(double dt, double duration, bool corotated = true) {
  BodyDef def;
  def.mesh = gen::box(0.4, 0.2, 0.1, 4, 2, 2);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1000);
  def.solver = fullNewton();
  def.solver.corotatedInertia = corotated;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  EXPECT_TRUE(id.ok());
  const size_t nn = def.mesh.nodeCount();
  std::vector<double> x(def.mesh.positions), v(3 * nn);
  const glm::dvec3 omega(0.3, 1.0, 2.0), vlin(0.5, -0.2, 0.1);
  for (size_t n = 0; n < nn; ++n) {
    x[3 * n] *= 1.1;  // stretched: the body vibrates while it spins
    const glm::dvec3 r(x[3 * n] - 0.22, x[3 * n + 1] - 0.1, x[3 * n + 2] - 0.05);
    const glm::dvec3 vi = vlin + glm::cross(omega, r);
    for (int i = 0; i < 3; ++i) v[3 * n + i] = vi[i];
  }
  EXPECT_TRUE(world.setPositions(id.value(), x).ok());
  EXPECT_TRUE(world.setVelocities(id.value(), v).ok());
  const BodyStats s0 = world.stats(id.value());
  MomentumDrift d;
  const int steps = int(std::lround(duration / dt));
  for (int s = 0; s < steps; ++s) {
    EXPECT_TRUE(world.step(dt).ok());
    const BodyStats st = world.stats(id.value());
    d.linear = std::max(d.linear, glm::length(st.linearMomentum - s0.linearMomentum) /
                                      glm::length(s0.linearMomentum));
    d.angular = std::max(d.angular, glm::length(st.angularMomentum - s0.angularMomentum) /
                                        glm::length(s0.angularMomentum));
    d.energyRise = std::max(
        d.energyRise, (test::totalEnergy(st) - test::totalEnergy(s0)) / test::totalEnergy(s0));
  }
  return d;
}

TEST(Momentum, FreeSpinningBodyConservesMomentum) {
  for (const double dt : {1e-3, 1.0 / 60}) {
    const MomentumDrift d = spinFreeBody(dt, 0.5);
    std::printf(
        "free body over 0.5 s at dt %.4f: linear momentum rel. error %.2e, angular %.2e, "
        "energy rise %.2e\n",
        dt, d.linear, d.angular, d.energyRise);
    EXPECT_LT(d.linear, 1e-10);
    EXPECT_LT(d.angular, 1e-10);
    EXPECT_LE(d.energyRise, 1e-12);
  }
  // Plain backward Euler loses angular momentum at first order in dt: the check above can fail.
  const MomentumDrift coarse = spinFreeBody(1e-3, 0.1, false),
                      fine = spinFreeBody(5e-4, 0.1, false);
  std::printf("plain backward Euler over 0.1 s: angular %.3e (dt 1 ms) / %.3e (dt 0.5 ms)\n",
              coarse.angular, fine.angular);
  EXPECT_GT(coarse.angular / fine.angular, 1.5);
  EXPECT_LT(coarse.angular / fine.angular, 2.5);
  EXPECT_GT(fine.angular, 1e-4);
}

}  // namespace
}  // namespace gf
