// Stiff and extreme cases at game time steps: no NaN/Inf, no energy blow-up (total energy
// never exceeds what was put in), and honest step flags when the solver gives up.
#include <gtest/gtest.h>

#include <cmath>

#include "common/beams.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

constexpr double kG = 9.81;

struct RunResult {
  double maxEnergy = -1e300, startEnergy = 0;
  bool finite = true;
  uint32_t flags = 0;
};

// Steps `world` n times, tracking total energy of body `id`.
RunResult runSteps(World& world, BodyId id, int n, double dt) {
  RunResult r;
  r.startEnergy = test::totalEnergy(world.stats(id));
  for (int s = 0; s < n; ++s) {
    const StepStatus st = world.step(dt);
    r.flags |= st.flags;
    r.finite = r.finite && test::stateFinite(world, id);
    r.maxEnergy = std::max(r.maxEnergy, test::totalEnergy(world.stats(id)));
  }
  return r;
}

using test::clampedBeam;

TEST(Stiff, SteelBeamAtGameTimeSteps) {
  for (double dt : {5e-3, 5e-2}) {
    BodyDef def = clampedBeam(Material::stableNeoHookean(2.2e11, 0.28, 7700), 20, 2);
    World world(WorldDef{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    const RunResult r = runSteps(world, id.value(), 100, dt);
    EXPECT_TRUE(r.finite) << "dt " << dt;
    EXPECT_FALSE(r.flags & kStepNanContained);
    // Clamped, no external work: energy may only go down (tolerance: 1e-6 of |E0| + 1 uJ).
    EXPECT_LE(r.maxEnergy, r.startEnergy + 1e-6 * std::abs(r.startEnergy) + 1e-6) << "dt " << dt;
    std::printf("steel dt=%g: E0 %.4e J, max E %.4e J, flags %u\n", dt, r.startEnergy, r.maxEnergy,
                r.flags);
  }
}

TEST(Stiff, NearlyIncompressibleBlockDroppedOnGround) {
  for (double nu : {0.49, 0.499}) {
    BodyDef def;
    def.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.05;
    def.material = Material::stableNeoHookean(1e6, nu, 1000);
    WorldDef wd{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}};
    wd.colliders.push_back(Collider{});  // ground plane y = 0
    World world(wd);
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    const RunResult r = runSteps(world, id.value(), 120, 1.0 / 60);
    EXPECT_TRUE(r.finite) << "nu " << nu;
    EXPECT_LE(r.maxEnergy, r.startEnergy + 1e-3 * std::abs(r.startEnergy)) << "nu " << nu;
    std::printf("nu=%.3f drop: E0 %.4e J, max E %.4e J\n", nu, r.startEnergy, r.maxEnergy);
  }
}

// Minimum det F over the body's tets at its current positions.
double minDetF(const World& world, BodyId id, const TetMesh& rest) {
  const auto x = world.positions(id);
  double worst = 1e300;
  for (size_t e = 0; e < rest.tetCount(); ++e) {
    worst = std::min(worst, det(test::tetDeformationGradient(rest, x, e)));
  }
  return worst;
}

TEST(Stiff, InvertedElementRecovers) {
  for (MaterialModel model :
       {MaterialModel::StableNeoHookean, MaterialModel::Corotated, MaterialModel::NeoHookean}) {
    BodyDef def;
    def.mesh = gen::box(0.1, 0.1, 0.1, 1, 1, 1);
    def.material = Material::stableNeoHookean(1e5, 0.3, 1000);
    def.material.model = model;
    def.material.massDamping = 1.0;
    const TetMesh rest = def.mesh;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    // Push the corner node at (0.1, 0.1, 0.1) through the body to (0.02, 0.02, 0.02)... and
    // beyond: the tets around it invert.
    std::vector<double> x(rest.positions);
    for (size_t n = 0; n < rest.nodeCount(); ++n)
      if (x[3 * n] > 0.09 && x[3 * n + 1] > 0.09 && x[3 * n + 2] > 0.09)
        for (int i = 0; i < 3; ++i) x[3 * n + i] = -0.03;
    ASSERT_TRUE(world.setPositions(id.value(), x).ok());
    const double before = minDetF(world, id.value(), rest);
    ASSERT_LT(before, 0.0);
    for (int s = 0; s < 200; ++s) (void)world.step(1.0 / 60);
    EXPECT_TRUE(test::stateFinite(world, id.value()));
    const double after = minDetF(world, id.value(), rest);
    std::printf("model %d: min det F %.3f -> %.3f after 200 steps\n", int(model), before, after);
    if (model != MaterialModel::NeoHookean) {
      EXPECT_GT(after, 0.5) << "model " << int(model);
    }
  }
}

TEST(Stiff, SliverElementsStayFinite) {
  BodyDef def = clampedBeam(Material::stableNeoHookean(1e7, 0.3, 1000), 10, 2);
  // Flatten the cells next to the tip into slivers: move an interior x-layer almost onto the
  // next one (volume ratio ~1e-4 of a regular tet, still valid).
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    double& x = def.mesh.positions[3 * n];
    if (std::abs(x - 0.9) < 1e-9) x = 1.0 - 1e-5;
  }
  World world(WorldDef{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const RunResult r = runSteps(world, id.value(), 120, 1.0 / 60);
  EXPECT_TRUE(r.finite);
  EXPECT_LE(r.maxEnergy, r.startEnergy + 1e-6 * std::abs(r.startEnergy) + 1e-6);
}

TEST(Stiff, HundredMetresPerSecondImpactOnGround) {
  BodyDef def;
  def.mesh = gen::box(0.3, 0.3, 0.3, 3, 3, 3);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.5;
  def.material = Material::stableNeoHookean(1e7, 0.4, 1000);
  def.initialVelocity = glm::vec3(0, -100, 0);
  WorldDef wd{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}};
  wd.colliders.push_back(Collider{});
  World world(wd);
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  const RunResult r = runSteps(world, id.value(), 120, 1.0 / 60);
  EXPECT_TRUE(r.finite);
  EXPECT_FALSE(r.flags & kStepNanContained);
  EXPECT_LE(r.maxEnergy, r.startEnergy * (1 + 1e-3));
  double minY = 1e300;
  const auto x = world.positions(id.value());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) minY = std::min(minY, x[3 * n + 1]);
  std::printf("100 m/s impact: E0 %.4e J, max E %.4e J, final lowest node y = %.4f m\n",
              r.startEnergy, r.maxEnergy, minY);
  EXPECT_GT(minY, -0.01);  // ends resting on the ground, not through it
}

// numericalDamping 0 (implicit midpoint) keeps every mode ringing, also the stiff ones
// (|R| = 1 at any omega dt): the steel beam stays bounded. Contact is where backward Euler's
// damping is needed: the penalty is one-sided, and extrapolating a step into a collider stores
// energy that comes back as an explosion, so a body touching a collider, or about to, is
// stepped with backward Euler; the drop and the 100 m/s impact then stay calm.
TEST(Stiff, WithoutNumericalDampingAtGameTimeSteps) {
  for (double dt : {5e-3, 5e-2}) {
    BodyDef def = clampedBeam(Material::stableNeoHookean(2.2e11, 0.28, 7700), 20, 2);
    def.solver.numericalDamping = 0;
    World world(WorldDef{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    const RunResult r = runSteps(world, id.value(), 100, dt);
    std::printf("numericalDamping 0, steel dt=%g: E0 %.6e J, max E %.6e J, flags %u\n", dt,
                r.startEnergy, r.maxEnergy, r.flags);
    EXPECT_TRUE(r.finite) << "dt " << dt;
    EXPECT_FALSE(r.flags & kStepNanContained);
    EXPECT_LE(r.maxEnergy, r.startEnergy + 1e-6 * std::abs(r.startEnergy) + 1e-6) << "dt " << dt;
  }
  for (const double speed : {0.0, 100.0}) {
    BodyDef def;
    def.mesh = gen::box(0.3, 0.3, 0.3, 3, 3, 3);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.05;
    def.material = Material::stableNeoHookean(1e7, 0.499, 1000);
    def.initialVelocity = glm::vec3(0, -float(speed), 0);
    def.solver.numericalDamping = 0;
    WorldDef wd{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}};
    wd.colliders.push_back(Collider{});
    World world(wd);
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    const RunResult r = runSteps(world, id.value(), 120, 1.0 / 60);
    double minY = 1e300;
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
      minY = std::min(minY, world.positions(id.value())[3 * n + 1]);
    std::printf(
        "numericalDamping 0, drop at %g m/s: E0 %.4e J, max E %.4e J, lowest node y = %.4f m\n",
        speed, r.startEnergy, r.maxEnergy, minY);
    EXPECT_TRUE(r.finite);
    EXPECT_FALSE(r.flags & kStepNanContained);
    EXPECT_LE(r.maxEnergy, r.startEnergy * (1 + 1e-3));
    EXPECT_GT(minY, -0.01);
  }
}

// A node can also be pushed into a collider by the body's own forces, which no look-ahead along
// the velocity sees: a block squeezed by 20 % and released at rest 1 mm above the ground. A
// step whose extrapolation ends inside the collider is taken again as backward Euler, so the
// block sinks no deeper than with backward Euler throughout and gains no energy.
TEST(Stiff, WithoutNumericalDampingAStepIntoAColliderIsBackwardEuler) {
  double deepest[2] = {0, 0}, rise[2] = {0, 0};
  for (const int damped : {0, 1}) {
    BodyDef def;
    def.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
    def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
    def.solver.numericalDamping = damped;
    WorldDef wd{glm::vec3(0), Backend::Cpu, nullptr, 1, {}};
    wd.colliders.push_back(Collider{});
    World world(wd);
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok()) << id.error().message;
    std::vector<double> x(def.mesh.positions);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) x[3 * n + 1] = 0.001 + 0.8 * x[3 * n + 1];
    ASSERT_TRUE(world.setPositions(id.value(), x).ok());
    const double e0 = test::totalEnergy(world.stats(id.value()));
    for (int s = 0; s < 30; ++s) {
      const StepStatus st = world.step(1.0 / 60);
      EXPECT_FALSE(st.has(kStepNanContained)) << st.message;
      for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
        deepest[damped] = std::max(deepest[damped], -world.positions(id.value())[3 * n + 1]);
      rise[damped] = std::max(rise[damped], test::totalEnergy(world.stats(id.value())) - e0);
    }
  }
  std::printf(
      "squeezed block released over the ground: deepest node %.3f mm, energy rise %.2e J "
      "(numericalDamping 0); %.3f mm, %.2e J (1)\n",
      1e3 * deepest[0], rise[0], 1e3 * deepest[1], rise[1]);
  EXPECT_LE(deepest[0], deepest[1] + 1e-4);
  EXPECT_LE(rise[0], 0.0);
}

TEST(Stiff, NonConvergedSolverIsFlagged) {
  BodyDef def = clampedBeam(Material::stableNeoHookean(2.2e11, 0.28, 7700), 20, 2);
  def.solver.maxLinearIterations = 3;
  World world(WorldDef{glm::vec3(0, -kG, 0), Backend::Cpu, nullptr, 1, {}});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  const StepStatus st = world.step(5e-2);
  EXPECT_TRUE(st.has(kStepNotConverged));
  EXPECT_FALSE(st.message.empty());
  EXPECT_TRUE(test::stateFinite(world, id.value()));
}

TEST(Stiff, InvalidStepIsRejectedAndChangesNothing) {
  BodyDef def = clampedBeam(Material::stableNeoHookean(1e6, 0.3, 1000), 4, 1);
  World world(WorldDef{});
  auto id = world.createBody(def);
  ASSERT_TRUE(id.ok());
  const std::vector<double> before(world.positions(id.value()).begin(),
                                   world.positions(id.value()).end());
  for (double dt : {-1.0, 0.0, std::nan(""), double(INFINITY)}) {
    const StepStatus st = world.step(dt);
    EXPECT_TRUE(st.has(kStepInvalidInput));
  }
  const auto after = world.positions(id.value());
  EXPECT_TRUE(std::equal(before.begin(), before.end(), after.begin()));
  EXPECT_EQ(world.time(), 0.0);
}

}  // namespace
}  // namespace gf
