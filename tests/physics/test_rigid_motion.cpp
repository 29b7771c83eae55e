// Rigid motion neither strains nor damps a body: a free cube spinning at game time steps has
// the centrifugal strain of its steady spin (the same body stepped at 1/300 s with stiffness
// damping until its vibrations die is the reference), keeps its angular momentum, never gains
// energy, does not break at five times its real stress, and falls straight while it spins.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <span>
#include <vector>

#include "common/sim_helpers.h"

namespace gf {
namespace {

struct SpinRun {
  double maxStrain = 0, lastStrain = 0;
  double meanStrain = 0;  // the largest strain averaged over the second half of the run
  double angularDrift = 0, energyRise = 0;
  int broken = 0;
  glm::dvec3 centreVelocity{0};
};

// A 0.2 m cube (3072 tets, E = 1e6, rho = 1000) spinning about z at omega, centred at the origin.
SpinRun spin(double omega, double dt, double duration, bool corotated = true,
             double stiffnessDamping = 0, double strength = 0, glm::vec3 gravity = glm::vec3(0),
             double numericalDamping = 1) {
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, 8, 8, 8);
  for (double& p : def.mesh.positions) p -= 0.1;
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.stiffnessDamping = stiffnessDamping;
  def.solver.corotatedInertia = corotated;
  def.solver.numericalDamping = numericalDamping;
  def.fracture.enabled = strength > 0;
  if (strength > 0) def.fracture.strength = strength;
  World world(WorldDef{gravity, Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  std::vector<double> v(world.velocities(id).size());
  const std::span<const double> x = world.positions(id);
  for (size_t n = 0; n < v.size() / 3; ++n) {
    v[3 * n] = -omega * x[3 * n + 1];
    v[3 * n + 1] = omega * x[3 * n];
  }
  EXPECT_TRUE(world.setVelocities(id, v).ok());
  const BodyStats s0 = world.stats(id);
  SpinRun r;
  const int steps = int(std::lround(duration / dt));
  for (int s = 0; s < steps; ++s) {
    const StepStatus st = world.step(dt);
    EXPECT_FALSE(st.has(kStepNanContained)) << st.message;
    r.lastStrain = 0;
    for (double e : world.nodeStrain(id)) r.lastStrain = std::max(r.lastStrain, e);
    r.maxStrain = std::max(r.maxStrain, r.lastStrain);
    if (2 * s >= steps) r.meanStrain += r.lastStrain / (steps - steps / 2);
    const BodyStats b = world.stats(id);
    r.angularDrift =
        std::max(r.angularDrift, std::abs(b.angularMomentum.z / s0.angularMomentum.z - 1));
    r.energyRise = std::max(r.energyRise, test::totalEnergy(b) - test::totalEnergy(s0));
  }
  r.broken = world.fractureStats(id).brokenEdges;
  r.centreVelocity = world.stats(id).linearMomentum / world.stats(id).mass;
  return r;
}

// The steady centrifugal strain: small steps and stiffness damping (overdamping the cube's
// ~160 Hz modes) let the start-up vibration die, and what is left is the stretch that holds
// the spin.
double steadyStrain(double omega) { return spin(omega, 1.0 / 300, 0.3, true, 0.01).lastStrain; }

TEST(RigidMotion, SpinningCubeHasItsCentrifugalStrainAtGameTimeSteps) {
  struct Case {
    double omega, dt;
  };
  for (const Case c : {Case{20, 1.0 / 60}, Case{20, 1.0 / 30}, Case{60, 1.0 / 60}}) {
    const double reference = steadyStrain(c.omega);
    const SpinRun r = spin(c.omega, c.dt, 1.0);
    std::printf("spin %g rad/s, dt 1/%g: largest strain %.3e, steady %.3e (%+.1f %%)\n", c.omega,
                1 / c.dt, r.maxStrain, reference, 100 * (r.maxStrain / reference - 1));
    EXPECT_NEAR(r.maxStrain, reference, 0.2 * reference);
  }
  // Plain backward Euler starts Newton on the tangent x_n + dt v_n and sees several times the
  // real strain: the check above can fail.
  const SpinRun plain = spin(20, 1.0 / 60, 0.1, false);
  std::printf("plain backward Euler: largest strain %.3e\n", plain.maxStrain);
  EXPECT_GT(plain.maxStrain, 3 * steadyStrain(20));
}

TEST(RigidMotion, SpinningCubeKeepsItsCentrifugalStrainWithoutNumericalDamping) {
  // numericalDamping 0 (implicit midpoint) does not damp the start-up vibration of a cube set
  // spinning from its rest shape: its strain swings about the steady one, up to twice it (a
  // load applied at once, undamped). The swing's centre is the centrifugal strain.
  struct Case {
    double omega, dt;
  };
  const double steady20 = steadyStrain(20), steady60 = steadyStrain(60);
  for (const Case c : {Case{20, 1.0 / 60}, Case{20, 1.0 / 30}, Case{60, 1.0 / 60}}) {
    const double reference = c.omega == 20 ? steady20 : steady60;
    const SpinRun r = spin(c.omega, c.dt, 1.0, true, 0, 0, glm::vec3(0), 0);
    std::printf(
        "numericalDamping 0, spin %g rad/s, dt 1/%g: mean strain %.3e (%+.1f %% of steady), "
        "largest %.2f x steady, angular momentum drift %.1e, energy rise %.1e J\n",
        c.omega, 1 / c.dt, r.meanStrain, 100 * (r.meanStrain / reference - 1),
        r.maxStrain / reference, r.angularDrift, r.energyRise);
    EXPECT_NEAR(r.meanStrain, reference, 0.2 * reference);
    EXPECT_LT(r.maxStrain, 2.2 * reference);
    EXPECT_LT(r.angularDrift, 1e-9);
    EXPECT_LE(r.energyRise, 1e-9);
  }
}

TEST(RigidMotion, SpinKeepsAngularMomentumAndNeverGainsEnergy) {
  const SpinRun r = spin(20, 1.0 / 60, 2.0);
  const SpinRun plain = spin(20, 1.0 / 60, 2.0, false);
  std::printf(
      "2 s at dt 1/60: angular momentum drift %.2e (plain backward Euler %.2f), "
      "largest energy rise %.2e J\n",
      r.angularDrift, plain.angularDrift, r.energyRise);
  EXPECT_LT(r.angularDrift, 0.01);
  EXPECT_LE(r.energyRise, 1e-9);
  EXPECT_GT(plain.angularDrift, 0.5);  // the plain step loses most of the spin
}

TEST(RigidMotion, SpinningCubeDoesNotBreakBelowItsStrength) {
  // Five times the real stress, E times the steady strain.
  const double strength = 5 * 1e6 * steadyStrain(20);
  const SpinRun r = spin(20, 1.0 / 60, 2.0, true, 0, strength);
  const SpinRun plain = spin(20, 1.0 / 60, 0.2, false, 0, strength);
  std::printf("strength %.3g Pa: %d edges broke in 2 s (plain backward Euler: %d in 0.2 s)\n",
              strength, r.broken, plain.broken);
  EXPECT_EQ(r.broken, 0);
  EXPECT_GT(plain.broken, 0);
}

TEST(RigidMotion, SpinningCubeFallsStraight) {
  // The turning frame must not turn gravity: the centre falls at exactly g.
  const double t = 1.0;
  const SpinRun r = spin(20, 1.0 / 60, t, true, 0, 0, glm::vec3(0, -9.81f, 0));
  const glm::dvec3 expect(0, double(-9.81f) * t, 0);
  std::printf("spinning fall: centre velocity (%.3e, %.6f, %.3e) m/s after %g s\n",
              r.centreVelocity.x, r.centreVelocity.y, r.centreVelocity.z, t);
  // To the linear solver's tolerance; turning gravity with the cube would give ~3 m/s sideways.
  EXPECT_LT(glm::length(r.centreVelocity - expect), 1e-6 * glm::length(expect));
}

// The pieces of a shattering body that fly into a collider: the glass bunny of
// scenes/bunny_render.json (StVK E = 1e10, brittle, 1 ms steps) thrown at 20 m/s at a ball and
// at a box. Its one-tet shards reach the collider within a step without touching it at the
// step's start; stepped in their turning frame, the contact impulses set their end spin, and
// one spun up to about 3e5 rad/s and was flung at 4.5 km/s when it broke (the bunny's energy
// 335 -> 4156 J in a step, no flag raised). The mechanical energy (kinetic, elastic, gravity,
// the colliders' penalty) may only fall, and no node may outrun the throw by much.
TEST(RigidMotion, ShardsThrownAtAColliderGainNoEnergy) {
  Result<TetMesh> mesh = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  for (const Collider::Kind kind : {Collider::Kind::Sphere, Collider::Kind::Box}) {
    Collider target;
    target.kind = kind;
    target.point = glm::vec3(-0.26f, 0.12f, 0);
    target.radius = 0.08f;
    target.halfExtents = glm::vec3(0.08f);
    World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {target}});
    BodyDef def;
    def.mesh = mesh.value();
    for (double& p : def.mesh.positions) p *= 0.03;
    def.material = Material::stvk(1e10, 0.45, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 5e7;
    def.fracture.radius = 0;
    def.fracture.brittle = true;
    def.fracture.regions = 8;
    def.solver.linearSolver = LinearSolverKind::Direct;
    def.initialVelocity = glm::vec3(-20, 0, 0);
    const BodyId id = world.createBody(def).value();
    auto energy = [&] {
      const BodyStats e = world.stats(id);
      return e.kineticEnergy + e.elasticEnergy + e.gravityEnergy + e.contactEnergy;
    };
    const double e0 = energy();
    double rise = -HUGE_VAL, fastest = 0;
    for (int s = 0; s < 16; ++s) {
      // kStepContactSwept may be raised: a shard crossing the collider's face is swept.
      ASSERT_EQ(world.step(1e-3).flags & ~uint32_t(kStepContactSwept), 0u);
      rise = std::max(rise, energy() - e0);
      const std::span<const double> v = world.velocities(id);
      for (size_t i = 0; i < v.size(); i += 3)
        fastest =
            std::max(fastest, std::sqrt(v[i] * v[i] + v[i + 1] * v[i + 1] + v[i + 2] * v[i + 2]));
    }
    const int32_t fragments = world.fractureStats(id).fragments;
    std::printf("%s: %d fragments, largest energy rise %.3g J of %.4g J, fastest node %.3g m/s\n",
                kind == Collider::Kind::Sphere ? "ball" : "box", fragments, rise, e0, fastest);
    EXPECT_GT(fragments, 20);  // it shatters: the case is the shards'
    EXPECT_LT(rise, 1e-3 * e0);
    EXPECT_LT(fastest, 30.0);
  }
}

}  // namespace
}  // namespace gf
