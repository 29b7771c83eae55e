// Coulomb friction against colliders, checked against the analytic block on an incline: at
// rest when tan(angle) < mu, else sliding down with acceleration g (sin - mu cos).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/sim_helpers.h"

namespace gf {
namespace {

constexpr double kG = 9.81;

struct Slide {
  double acceleration = 0;  ///< Down the slope, from the velocity between 0.5 s and 1.5 s.
  double travel = 0;        ///< Down the slope over the whole run [m].
  double endSpeed = 0;
};

// A 10 cm block (E = 1e6) released on a plane tilted by `angle` about z, both surfaces with
// friction mu (so the pair has mu), stepped at 60 Hz for 1.5 s.
Slide slideOnIncline(double angle, double mu) {
  const glm::dvec3 down(-std::cos(angle), -std::sin(angle), 0);  // along the slope, downhill
  const glm::dvec3 normal(-std::sin(angle), std::cos(angle), 0);
  WorldDef wd{glm::vec3(0, float(-kG), 0), Backend::Cpu, nullptr, 1, {}};
  Collider plane;
  plane.normal = glm::vec3(normal);
  plane.friction = mu;
  wd.colliders.push_back(plane);
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.04, 0.1, 4, 2, 4);
  // Local (along the slope, along the normal, z) to world; the block's base on the plane.
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    double* p = &def.mesh.positions[3 * n];
    const glm::dvec3 w = -(p[0] - 0.05) * down + p[1] * normal + glm::dvec3(0, 0, p[2] - 0.05);
    for (int a = 0; a < 3; ++a) p[a] = w[a];
  }
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  def.friction = mu;
  const BodyId id = world.createBody(def).value();
  const auto along = [&](std::span<const double> v) {
    glm::dvec3 sum(0);
    for (size_t n = 0; n < v.size() / 3; ++n)
      sum += glm::dvec3(v[3 * n], v[3 * n + 1], v[3 * n + 2]);
    return glm::dot(sum / double(v.size() / 3), down);
  };
  const double start = along(world.positions(id));
  Slide out;
  double v1 = 0;
  const double dt = 1.0 / 60;
  for (int s = 1; s <= 90; ++s) {
    EXPECT_TRUE(world.step(dt).ok());
    if (s == 30) v1 = along(world.velocities(id));
  }
  out.endSpeed = along(world.velocities(id));
  out.acceleration = (out.endSpeed - v1) / (60 * dt);
  out.travel = along(world.positions(id)) - start;
  return out;
}

TEST(Friction, BlockOnInclineSlidesOrStaysAsCoulombSays) {
  for (const double mu : {0.2, 0.6}) {
    // Sliding: 15 degrees steeper than the friction angle.
    const double steep = std::atan(mu) + 15 * M_PI / 180;
    const Slide slides = slideOnIncline(steep, mu);
    const double expected = kG * (std::sin(steep) - mu * std::cos(steep));
    std::printf(
        "mu %.1f, %.1f deg: acceleration %.4f m/s^2, analytic g (sin - mu cos) %.4f "
        "(%+.2f %%)\n",
        mu, steep * 180 / M_PI, slides.acceleration, expected,
        100 * (slides.acceleration / expected - 1));
    EXPECT_NEAR(slides.acceleration, expected, 0.05 * expected);
    // At rest: half the friction angle's tangent.
    const double gentle = std::atan(0.5 * mu);
    const Slide stays = slideOnIncline(gentle, mu);
    std::printf("mu %.1f, %.1f deg: moved %.3f mm in 1.5 s, end speed %.2e m/s\n", mu,
                gentle * 180 / M_PI, 1e3 * stays.travel, stays.endSpeed);
    EXPECT_LT(std::abs(stays.travel), 2e-3);
    EXPECT_LT(std::abs(stays.endSpeed), 1e-3);
  }
  // Without friction (the default collider) the same block slides at g sin.
  const double angle = 20 * M_PI / 180;
  const Slide ice = slideOnIncline(angle, 0);
  std::printf("frictionless, 20 deg: acceleration %.4f, analytic %.4f\n", ice.acceleration,
              kG * std::sin(angle));
  EXPECT_NEAR(ice.acceleration, kG * std::sin(angle), 0.05 * kG * std::sin(angle));
}

// A block pushed along a level floor at 2 m/s with mu = 0.5 stops after v^2 / (2 mu g), within
// 5 % (it starts just touching, and the normal force is the step's start's, so its first step
// slides free); its momentum changes by exactly what the floor and gravity gave it
// (World::colliderImpulses includes friction), to the direct solver's round-off.
TEST(Friction, SlidingBlockStopsWhereCoulombSaysAndTheFloorReportsTheImpulse) {
  const double mu = 0.5, v0 = 2;
  WorldDef wd{glm::vec3(0, float(-kG), 0), Backend::Cpu, nullptr, 1, {}};
  Collider floor;
  floor.friction = mu;
  wd.colliders.push_back(floor);
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.04, 0.1, 4, 2, 4);
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  def.friction = mu;
  def.solver.linearSolver = LinearSolverKind::Direct;
  def.initialVelocity = glm::vec3(float(v0), 0, 0);
  const BodyId id = world.createBody(def).value();
  const auto momentum = [&] {
    const BodyStats s = world.stats(id);
    return s.linearMomentum;
  };
  const double mass = world.stats(id).mass;
  double worst = 0;
  const double dt = 1.0 / 60;
  for (int s = 0; s < 60; ++s) {
    const glm::dvec3 before = momentum();
    ASSERT_TRUE(world.step(dt).ok());
    const glm::dvec3 expected =
        before + world.colliderImpulses()[0] + glm::dvec3(0, -kG * mass * dt, 0);
    worst = std::max(worst, glm::length(momentum() - expected) / (mass * v0));
  }
  double meanX = 0;
  const auto x = world.positions(id);
  for (size_t n = 0; n < x.size() / 3; ++n) meanX += x[3 * n] - def.mesh.positions[3 * n];
  meanX /= double(x.size() / 3);
  const double analytic = v0 * v0 / (2 * mu * kG);
  std::printf(
      "block at %.0f m/s, mu %.1f: stopped after %.4f m (v^2 / (2 mu g) = %.4f m, %+.2f "
      "%%); momentum balance off by %.1e of m v0\n",
      v0, mu, meanX, analytic, 100 * (meanX / analytic - 1), worst);
  EXPECT_NEAR(meanX, analytic, 0.05 * analytic);
  EXPECT_LT(worst, 1e-6);  // without friction's share it would be 0.04 a step
  EXPECT_LT(std::abs(momentum().x), 1e-3 * mass * v0);
}

// A block on a level floor with friction mu (both surfaces, so the pair has mu), centred on
// (r, 0, 0): the floor a turntable (Collider::angularVelocity w about the vertical through the
// origin) or a conveyor (Collider::velocity, the turntable's surface velocity w x r = -w r z
// under the block's start). 60 Hz.
struct DraggedBlock {
  World world;
  BodyId id;
  DraggedBlock(double r, double omega, bool conveyor, double mu)
      : world(WorldDef{glm::vec3(0, float(-kG), 0), Backend::Cpu, nullptr, 1, {}}) {
    Collider floor;
    floor.friction = mu;
    if (conveyor)
      floor.velocity = glm::vec3(0, 0, float(-omega * r));
    else
      floor.angularVelocity = glm::vec3(0, float(omega), 0);
    const Collider floors[] = {floor};
    EXPECT_TRUE(world.setColliders(floors).ok());
    BodyDef def;
    def.mesh = gen::box(0.1, 0.04, 0.1, 4, 2, 4);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] += r - 0.05;
      def.mesh.positions[3 * n + 2] -= 0.05;
    }
    def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
    def.friction = mu;
    id = world.createBody(def).value();
  }
  glm::dvec3 mean(std::span<const double> a) const {
    glm::dvec3 sum(0);
    for (size_t n = 0; n < a.size() / 3; ++n)
      sum += glm::dvec3(a[3 * n], a[3 * n + 1], a[3 * n + 2]);
    return sum / double(a.size() / 3);
  }
};

// A turntable drags what rests on it along its surface's velocity: far out (2 m, 4 m/s under
// the block, faster than it can follow for the 0.5 s) the block slides as on a conveyor of
// that speed, whatever the friction law gives there; near the axis and slow (0.2 m/s) it is
// carried round with the surface. Without the spin the floor holds the block still.
TEST(Friction, TurntableDragsABlockAlongItsSurface) {
  const double mu = 0.5, dt = 1.0 / 60;
  DraggedBlock table(2, 2, false, mu), belt(2, 2, true, mu);
  for (int s = 0; s < 30; ++s) {
    ASSERT_TRUE(table.world.step(dt).ok());
    ASSERT_TRUE(belt.world.step(dt).ok());
  }
  const glm::dvec3 vt = table.mean(table.world.velocities(table.id)),
                   vb = belt.mean(belt.world.velocities(belt.id));
  // The conveyor's block went straight along -z; the turntable's turned with the surface's
  // velocity under it, w x (its position) = w (z, 0, -x), by about z / r.
  const glm::dvec3 c = table.mean(table.world.positions(table.id));
  const double turnedSurface = std::atan2(c.z, c.x), turnedBlock = std::atan2(-vt.x, -vt.z);
  std::printf(
      "after 0.5 s: turntable block %.4f m/s, conveyor block %.4f m/s (%+.2f %%; mu g t = "
      "%.4f); the turntable's block turned %.4f rad, the surface under it %.4f\n",
      glm::length(vt), glm::length(vb), 100 * (glm::length(vt) / glm::length(vb) - 1),
      mu * kG * 0.5, turnedBlock, -turnedSurface);
  EXPECT_NEAR(glm::length(vt), glm::length(vb), 0.01 * glm::length(vb));
  EXPECT_GT(glm::length(vb), 0.8 * mu * kG * 0.5);  // it did slide under friction
  EXPECT_GT(turnedBlock, 0);                        // bent towards the surface's velocity
  EXPECT_LT(turnedBlock, -turnedSurface);

  DraggedBlock slow(0.5, 0.4, false, mu);
  for (int s = 0; s < 120; ++s) ASSERT_TRUE(slow.world.step(dt).ok());
  const glm::dvec3 x = slow.mean(slow.world.positions(slow.id)),
                   v = slow.mean(slow.world.velocities(slow.id));
  const glm::dvec3 surface = glm::cross(glm::dvec3(0, 0.4, 0), glm::dvec3(x.x, 0, x.z));
  const double turned = std::atan2(-x.z, x.x);
  std::printf(
      "0.2 m/s turntable: after 2 s at radius %.4f m, turned %.3f rad (w t = 0.800), velocity "
      "off the surface's by %.2e m/s\n",
      std::hypot(x.x, x.z), turned, glm::length(glm::dvec3(v.x, 0, v.z) - surface));
  EXPECT_NEAR(turned, 0.8, 0.05 * 0.8);
  EXPECT_LT(glm::length(glm::dvec3(v.x, 0, v.z) - surface), 0.05 * 0.2);

  DraggedBlock still(2, 0, false, mu);
  for (int s = 0; s < 30; ++s) ASSERT_TRUE(still.world.step(dt).ok());
  const glm::dvec3 v0 = still.mean(still.world.velocities(still.id));
  EXPECT_LT(std::hypot(v0.x, v0.z), 1e-3);
}

// A block at rest on a conveyor belt (Collider::velocity V along -z) is dragged along by
// kinetic friction: while it slips, the floor's reported friction impulse is mu times its
// normal impulse, and the block gains mu g a second until it rides with the belt. For mu 0.2
// and 0.6 and belts at 1, 3 and 6 m/s; each at 60 Hz.
TEST(Friction, ConveyorDragsABlockAtMuGUntilItRidesWithTheBelt) {
  const double dt = 1.0 / 60;
  for (const double mu : {0.2, 0.6})
    for (const double speed : {1.0, 3.0, 6.0}) {
      DraggedBlock belt(2, speed / 2, true, mu);  // belt velocity -w r z
      // Lagged normal force: the first step that touches has none, so count from the second.
      double normal = 0, along = 0, gained = 0, v0 = 0;
      int slipping = 0, riding = 0;
      const double slipSteps = speed / (mu * kG * dt);
      const int steps = int(slipSteps) + 30;
      for (int s = 0; s < steps; ++s) {
        ASSERT_TRUE(belt.world.step(dt).ok());
        const glm::dvec3 v = belt.mean(belt.world.velocities(belt.id));
        if (s == 1) v0 = -v.z;
        if (s >= 2 && -v.z < speed - 2 * mu * kG * dt) {
          const glm::dvec3 j = belt.world.colliderImpulses()[0];
          normal += j.y;
          along += -j.z;
          gained = -v.z - v0;
          ++slipping;
        }
        if (s == steps - 1) riding = std::abs(-v.z - speed) < 1e-3 * speed;
      }
      const double accel = gained / (slipping * dt);
      std::printf(
          "mu %.1f, belt %.0f m/s: friction / normal impulse %.5f over %d slipping steps, "
          "acceleration %.4f m/s^2 (mu g %.4f, %+.2f %%), rides with the belt: %d\n",
          mu, speed, along / normal, slipping, accel, mu * kG, 100 * (accel / (mu * kG) - 1),
          riding);
      ASSERT_GT(slipping, 3);
      EXPECT_NEAR(along / normal, mu, 0.01 * mu);  // lagged normal force against the end's
      EXPECT_NEAR(accel, mu * kG, 0.01 * mu * kG);
      EXPECT_TRUE(riding);
    }
}

TEST(Friction, CoefficientsAreChecked) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 1, 1, 1);
  def.friction = -0.1;
  const Result<BodyId> r = world.createBody(def);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("friction: must lie in [0, 1e3], got -0.1"), std::string::npos)
      << r.error().message;
  Collider c;
  c.friction = std::nan("");
  const Result<void> rc = world.setColliders(std::span<const Collider>(&c, 1));
  ASSERT_FALSE(rc.ok());
  EXPECT_NE(rc.error().message.find("friction"), std::string::npos) << rc.error().message;
}

}  // namespace
}  // namespace gf
