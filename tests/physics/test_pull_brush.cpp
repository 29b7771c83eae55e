// The pull brush (World::pull, thesis sec 7.2.3.4): nodes tied to moving targets by springs
// inside the implicit step. Checked against backward Euler's closed form where the body does
// not strain, against the momentum the springs must have given it where it does, and as
// sculpting: clay with plasticity keeps a pulled bump, an elastic block lets it go.
#include <graphfrac/sculpt.h>
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "common/mesh_checks.h"

namespace gf {
namespace {

WorldDef noGravity(int substeps) {
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  wd.substeps = substeps;
  return wd;
}

glm::dvec3 momentum(const World& world, BodyId id, const std::vector<double>& mass) {
  glm::dvec3 p(0);
  const std::span<const double> v = world.velocities(id);
  for (size_t n = 0; n < mass.size(); ++n)
    p += mass[n] * glm::dvec3(v[3 * n], v[3 * n + 1], v[3 * n + 2]);
  return p;
}

// Every node of a free box pulled by the same offset: the box does not strain, so each node
// follows backward Euler's scalar recurrence for a spring of k per unit mass,
//   x' = (x + h v + h^2 k t) / (1 + h^2 k),  v' = (x' - x) / h,
// over every substep. Stiffnesses from barely felt to a near-rigid tie, time steps and substep
// counts a game uses.
TEST(PullBrush, AnUnstrainedBodyFollowsBackwardEulersSpring) {
  const glm::dvec3 offset(0.01, 0.02, -0.005);
  double worst = 0;
  for (double k : {1e2, 1e4, 1e6, 1e9})
    for (double dt : {1.0 / 60, 1.0 / 240})
      for (int substeps : {1, 3}) {
        World world(noGravity(substeps));
        BodyDef def;
        def.mesh = gen::box(0.1, 0.05, 0.08, 3, 2, 2);
        const BodyId id = world.createBody(def).value();
        const std::vector<double> x0(world.positions(id).begin(), world.positions(id).end());
        std::vector<int32_t> nodes;
        std::vector<glm::dvec3> targets;
        for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
          nodes.push_back(int32_t(n));
          targets.emplace_back(glm::dvec3(x0[3 * n], x0[3 * n + 1], x0[3 * n + 2]) + offset);
        }
        const std::vector<double> mass = test::lumpedMasses(def.mesh, def.material.density);
        double u = 0, v = 0;  // the predicted displacement along the offset, as a fraction
        const double h = dt / substeps;
        for (int frame = 0; frame < 3; ++frame) {
          PullBrush pull;
          pull.nodes = nodes;
          pull.targets = targets;
          pull.stiffness = k;
          ASSERT_TRUE(world.pull(id, pull).ok());
          const glm::dvec3 p0 = momentum(world, id, mass);
          ASSERT_TRUE(world.step(dt).ok());
          double impulse = 0;  // along the offset, per unit mass
          for (int s = 0; s < substeps; ++s) {
            const double u1 = (u + h * v + h * h * k) / (1 + h * h * k);
            impulse += h * k * (1 - u1);
            v = (u1 - u) / h;
            u = u1;
          }
          double err = 0;
          for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
            for (int i = 0; i < 3; ++i) {
              const size_t j = 3 * n + size_t(i);
              err = std::max(err, std::abs(world.positions(id)[j] - x0[j] - u * offset[i]));
              err = std::max(err, h * std::abs(world.velocities(id)[j] - v * offset[i]));
            }
          err /= glm::length(offset);
          worst = std::max(worst, err);
          EXPECT_LT(err, 1e-9) << "k " << k << ", dt " << dt << ", substeps " << substeps;
          // The force the body reports is the one that moved it: sum m k (t - x') per substep,
          // averaged over the step. It is k times a lag that shrinks as 1 / (h^2 k), so it
          // carries the solve's position error (1e-10 of the body's size allowed) times M k.
          double totalMass = 0;
          for (double m : mass) totalMass += m;
          const glm::dvec3 expected = totalMass * (impulse / dt) * offset;
          const glm::dvec3 got = world.pullForce(id);
          const double slack = totalMass * k * 1e-11;
          EXPECT_LT(glm::length(got - expected), 1e-9 * glm::length(expected) + slack)
              << "k " << k << ", dt " << dt << ", substeps " << substeps << ", frame " << frame;
          const glm::dvec3 dp = momentum(world, id, mass) - p0;
          EXPECT_LT(glm::length(dp - got * dt), (1e-9 * glm::length(expected) + slack) * dt);
        }
      }
  std::printf("worst distance from backward Euler's spring, over the offset: %.2e\n", worst);
}

// A patch of a free elastic block pulled away from it: the block strains, but its internal
// forces sum to zero, so the momentum it gains over a step is exactly what World::pullForce
// reports times the step (to the Newton tolerance), for any substep count; the step after,
// without a pull, reports zero and keeps the momentum.
TEST(PullBrush, TheBodyGainsThePullForceTimesTheStep) {
  for (int substeps : {1, 2, 5}) {
    World world(noGravity(substeps));
    BodyDef def;
    def.mesh = gen::box(0.1, 0.1, 0.1, 4, 4, 4);
    def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
    const BodyId id = world.createBody(def).value();
    const std::vector<double> mass = test::lumpedMasses(def.mesh, def.material.density);
    std::vector<int32_t> nodes;
    std::vector<glm::dvec3> targets;
    const std::span<const double> x = world.positions(id);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
      if (x[3 * n + 1] > 0.1 - 1e-9 && std::hypot(x[3 * n] - 0.05, x[3 * n + 2] - 0.05) < 0.03) {
        nodes.push_back(int32_t(n));
        targets.emplace_back(x[3 * n] + 0.002, x[3 * n + 1] + 0.01, x[3 * n + 2]);
      }
    ASSERT_GE(nodes.size(), 5u);
    double worst = 0;
    for (int frame = 0; frame < 5; ++frame) {
      PullBrush pull;
      pull.nodes = nodes;
      pull.targets = targets;
      pull.stiffness = 1e5;
      ASSERT_TRUE(world.pull(id, pull).ok());
      const glm::dvec3 p0 = momentum(world, id, mass);
      const StepStatus st = world.step(1.0 / 60);
      ASSERT_TRUE(st.ok()) << st.message;
      const glm::dvec3 dp = momentum(world, id, mass) - p0, j = world.pullForce(id) / 60.0;
      // Later the body's own momentum carries the patch past its target and the pull reverses.
      if (frame == 0) {
        EXPECT_GT(j.y, 0);
      }
      worst = std::max(worst, glm::length(dp - j) / glm::length(j));
    }
    std::printf("%d substep(s): momentum gained against pullForce * dt, worst %.2e\n", substeps,
                worst);
    EXPECT_LT(worst, 1e-6);
    const glm::dvec3 p0 = momentum(world, id, mass);
    ASSERT_TRUE(world.step(1.0 / 60).ok());
    EXPECT_EQ(world.pullForce(id), glm::dvec3(0));
    EXPECT_LT(glm::length(momentum(world, id, mass) - p0), 1e-9 * glm::length(p0));
  }
}

struct Pulled {
  double bumpMax = 0, bumpEnd = 0;  // the pulled patch's centre above the top's rim [m]
  double lag = 0;                   // the patch centre's distance from its target at the end
  double force = 0;                 // pullForce's y at the end of the pull [N]
};

// A 10 cm clay block on a pinned base: the tool grabs the top within 1.5 cm of its centre and
// rises 1 cm in 20 frames, with a deform brush at the tool so the clay yields around it, then
// lets go; the block rests 2 s.
Pulled pullClay(bool plastic) {
  World world(noGravity(1));
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 6, 6, 6);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  def.plasticity.enabled = plastic;
  def.plasticity.yieldStress = 2e3;
  Grip base;
  std::vector<int32_t> patch, rim;
  int32_t centre = -1;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double x = def.mesh.positions[3 * n], y = def.mesh.positions[3 * n + 1],
                 z = def.mesh.positions[3 * n + 2];
    if (y < 1e-9) base.nodes.push_back(int32_t(n));
    if (y < 0.1 - 1e-9) continue;
    if (std::hypot(x - 0.05, z - 0.05) < 0.015) patch.push_back(int32_t(n));
    if (std::hypot(x - 0.05, z - 0.05) < 1e-9) centre = int32_t(n);
    if (x < 1e-9 || z < 1e-9 || x > 0.1 - 1e-9 || z > 0.1 - 1e-9) rim.push_back(int32_t(n));
  }
  EXPECT_GE(centre, 0);
  def.grips.push_back(base);
  const BodyId id = world.createBody(def).value();
  const std::vector<double> rest(world.positions(id).begin(), world.positions(id).end());
  const auto bump = [&] {
    const std::span<const double> x = world.positions(id);
    double rimY = 0;
    for (int32_t n : rim) rimY += x[3 * size_t(n) + 1];
    return x[3 * size_t(centre) + 1] - rimY / double(rim.size());
  };
  Pulled r;
  const int frames = 20;
  for (int k = 1; k <= frames; ++k) {
    const double rise = 0.01 * k / frames;
    std::vector<glm::dvec3> targets;
    for (int32_t n : patch)
      targets.emplace_back(rest[3 * size_t(n)], rest[3 * size_t(n) + 1] + rise,
                           rest[3 * size_t(n) + 2]);
    PullBrush pull;
    pull.nodes = patch;
    pull.targets = targets;
    EXPECT_TRUE(world.pull(id, pull).ok());
    DeformBrush clay;
    clay.centre = {0.05f, float(0.1 + rise), 0.05f};
    clay.radius = 0.03f;
    clay.k1 = 30;
    clay.k2 = 30;
    EXPECT_TRUE(world.deform(id, clay).ok());
    const StepStatus st = world.step(1.0 / 60);
    EXPECT_TRUE(st.ok()) << st.message;
    if (k == frames) {
      r.lag = rest[3 * size_t(centre) + 1] + rise - world.positions(id)[3 * size_t(centre) + 1];
      r.force = world.pullForce(id).y;
    }
  }
  r.bumpMax = bump();
  for (int k = 0; k < 120; ++k) {
    const StepStatus st = world.step(1.0 / 60);
    EXPECT_TRUE(st.ok()) << k << ": " << st.message;
  }
  r.bumpEnd = bump();
  std::printf(
      "plastic %d: bump %.2f mm at the end of the pull (centre %.2f mm behind its target, "
      "force on the body %.3f N), %.2f mm 2 s after\n",
      plastic, 1e3 * r.bumpMax, 1e3 * r.lag, r.force, 1e3 * r.bumpEnd);
  return r;
}

TEST(PullBrush, ClayKeepsThePulledBumpAnElasticBlockLetsItGo) {
  const Pulled clay = pullClay(true), elastic = pullClay(false);
  // The default stiffness drags the grabbed patch along: it trails the tool by a small part of
  // the 1 cm travel, and the clay around it rises with it.
  EXPECT_LT(clay.lag, 2e-3);
  EXPECT_GT(clay.bumpMax, 7e-3);
  EXPECT_GT(clay.force, 0);  // the body is pulled up, the tool down
  // The bump is the material's: it stays with plasticity and springs back without.
  EXPECT_GT(clay.bumpEnd, 0.35 * clay.bumpMax);
  EXPECT_LT(elastic.bumpEnd, 0.1 * elastic.bumpMax);
  // The elastic block resists harder: nothing yields.
  EXPECT_GT(elastic.force, clay.force);
}

TEST(PullBrush, BadBrushIsAClearErrorAndQueuesNothing) {
  World world(noGravity(1));
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 2, 2, 2);
  def.grips.push_back(Grip{{0}, {0, 0, 0}});
  const BodyId id = world.createBody(def).value();
  const int32_t nodes[] = {1, 2, 27};
  const glm::dvec3 targets[] = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  const auto expectError = [&](BodyId body, const PullBrush& b, const std::string& word) {
    const Result<void> r = world.pull(body, b);
    ASSERT_FALSE(r.ok()) << word;
    EXPECT_NE(r.error().message.find(word), std::string::npos) << r.error().message;
  };
  PullBrush b;
  b.nodes = std::span<const int32_t>(nodes, 2);
  b.targets = std::span<const glm::dvec3>(targets, 2);
  expectError(BodyId{}, b, "BodyId");
  b.nodes = {};
  expectError(id, b, "empty");
  b.nodes = std::span<const int32_t>(nodes, 2);
  b.targets = std::span<const glm::dvec3>(targets, 1);
  expectError(id, b, "targets");
  // The bad node comes last: the good ones before it must not have been queued.
  b.nodes = nodes;
  b.targets = targets;
  expectError(id, b, "nodes[2]");
  const glm::dvec3 farTargets[] = {{0, 1, 0}, {0, 2e9, 0}};
  b.nodes = std::span<const int32_t>(nodes, 2);
  b.targets = farTargets;
  expectError(id, b, "targets[1]");
  b.targets = std::span<const glm::dvec3>(targets, 2);
  for (double k : {0.0, -1.0, double(NAN), 1e13}) {
    b.stiffness = k;
    expectError(id, b, "stiffness");
  }
  // Nothing was queued: the body rests through a step.
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  for (double v : world.velocities(id)) EXPECT_LT(std::abs(v), 1e-12);
  EXPECT_EQ(world.pullForce(id), glm::dvec3(0));
  // A pinned node is not pulled: a pull on it alone changes nothing and reports no force.
  const int32_t pinned[] = {0};
  b.nodes = pinned;
  b.targets = std::span<const glm::dvec3>(targets, 1);
  b.stiffness = 1e6;
  ASSERT_TRUE(world.pull(id, b).ok());
  ASSERT_TRUE(world.step(1.0 / 60).ok());
  for (double v : world.velocities(id)) EXPECT_LT(std::abs(v), 1e-12);
  EXPECT_EQ(world.pullForce(id), glm::dvec3(0));
}

}  // namespace
}  // namespace gf
