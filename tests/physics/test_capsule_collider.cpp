// A body on capsule colliders (rounded edges: the lab tests' strikers and anvils), checked
// against statics and the momentum balance: a block at rest on one or two capsules is held up
// by exactly its weight (World::colliderImpulses over dt), at several time steps and with the
// capsules turned off the world's axes, and every step's momentum change is gravity's impulse
// plus the capsules'.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <vector>

#include "graphfrac/world.h"

namespace gf {
namespace {

constexpr double kG = 9.81;

struct Rest {
  double support = 0;       ///< mean upward collider force over the last third [N]
  double weight = 0;        ///< m g [N]
  double worstBalance = 0;  ///< largest per-step momentum mismatch / (m g dt)
  double endSpeed = 0;      ///< largest node speed at the end [m/s]
  double lowest = 0;        ///< lowest node y at the end [m]
};

// A 10 x 4 x 10 cm block (E = 1e7) placed just above the given capsules and left to settle
// for 1.5 s at time step dt.
Rest restOn(const std::vector<Collider>& capsules, double dt, double baseY) {
  WorldDef wd{glm::vec3(0, float(-kG), 0), Backend::Cpu, nullptr, 1, capsules};
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.04, 0.1, 5, 2, 5);
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    def.mesh.positions[3 * n] -= 0.05;
    def.mesh.positions[3 * n + 1] += baseY;
    def.mesh.positions[3 * n + 2] -= 0.05;
  }
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  def.solver.linearSolver = LinearSolverKind::Direct;
  const BodyId id = world.createBody(def).value();
  Rest r;
  const double mass = world.stats(id).mass;
  r.weight = mass * kG;
  const int steps = int(std::lround(1.5 / dt));
  int counted = 0;
  for (int s = 0; s < steps; ++s) {
    const glm::dvec3 before = world.stats(id).linearMomentum;
    const StepStatus st = world.step(dt);
    EXPECT_TRUE(st.ok()) << st.flags;
    glm::dvec3 J(0);
    for (const glm::dvec3& j : world.colliderImpulses()) J += j;
    const glm::dvec3 expected = before + J + glm::dvec3(0, -kG * mass * dt, 0);
    if (s >= 2 * steps / 3) {
      // Settled: the balance holds to the linear solver's tolerance (steps in which a node
      // enters or leaves contact are balanced only to the last Newton step's linearisation).
      r.worstBalance =
          std::max(r.worstBalance,
                   glm::length(world.stats(id).linearMomentum - expected) / (mass * kG * dt));
      r.support += J.y / dt;
      ++counted;
    }
  }
  r.support /= counted;
  const auto v = world.velocities(id);
  const auto x = world.positions(id);
  r.lowest = 1e300;
  for (size_t n = 0; n < v.size() / 3; ++n) {
    r.endSpeed =
        std::max(r.endSpeed, glm::length(glm::dvec3(v[3 * n], v[3 * n + 1], v[3 * n + 2])));
    r.lowest = std::min(r.lowest, double(x[3 * n + 1]));
  }
  return r;
}

Collider capsuleAt(glm::vec3 centre, glm::vec3 axis, float radius, float halfLength) {
  Collider c;
  c.kind = Collider::Kind::Capsule;
  c.point = centre;
  c.radius = radius;
  c.halfLength = halfLength;
  // The automatic penalty (k dt^2 = 100 per unit node mass) lets a light corner node that
  // carries a quarter of the block sink millimetres at 60 Hz and slide off a cap's flank; a
  // stiff one keeps the contacts where the geometry puts them.
  c.stiffness = 1e7;
  // Local y onto the axis.
  const glm::vec3 y(0, 1, 0), u = glm::normalize(axis);
  c.rotation = glm::normalize(glm::quat(1 + glm::dot(y, u), glm::cross(y, u)));
  return c;
}

TEST(CapsuleCollider, BlockRestingOnCapsulesIsHeldUpByItsWeight) {
  struct Case {
    const char* name;
    std::vector<Collider> capsules;
  };
  // Contact is at nodes, and a node feels the collider's normal, not the face's: a row of nodes
  // on a frictionless crown is balanced on a hill (a flat face on a rod would be neutral, its
  // contact point moving with it), and the block slides off two rods along z under its node
  // rows x = +-0.03. So the block rests on two rods turned 30 degrees (which cross its rows),
  // or with friction on one fat rod or on four upright capsules' rounded tops under its nodes.
  const glm::vec3 turned(std::sin(0.5236f), 0, std::cos(0.5236f));
  Collider crown = capsuleAt({0, -0.05f, 0}, {0, 0, 1}, 0.05f, 0.1f);
  crown.friction = 0.5;  // with the body's 0.6: mu 0.55
  std::vector<Collider> caps;
  for (const float x : {-0.03f, 0.03f})
    for (const float z : {-0.03f, 0.03f}) {
      caps.push_back(capsuleAt({x, -0.015f, z}, {0, 1, 0}, 0.01f, 0.005f));
      caps.back().friction = 0.5;
    }
  const std::vector<Case> cases = {
      {"two rods r 1 cm turned 30 deg",
       {capsuleAt({-0.03f, -0.01f, 0}, turned, 0.01f, 0.1f),
        capsuleAt({0.03f, -0.01f, 0}, turned, 0.01f, 0.1f)}},
      {"four upright capsules r 1 cm with friction", caps},
      {"one rod r 5 cm with friction (crown)", {crown}},
  };
  for (const Case& c : cases)
    for (const double dt : {1.0 / 60, 1.0 / 240}) {
      const Rest r = restOn(c.capsules, dt, 0.0005);
      std::printf(
          "  %s, dt %.4f: support %.5f N, weight %.5f N (%+.3f %%), momentum balance off by "
          "%.1e of m g dt, end speed %.1e m/s, lowest node y %.4f m\n",
          c.name, dt, r.support, r.weight, 100 * (r.support / r.weight - 1), r.worstBalance,
          r.endSpeed, r.lowest);
      EXPECT_NEAR(r.support, r.weight, 1e-3 * r.weight) << c.name << " dt " << dt;
      EXPECT_LT(r.worstBalance, 1e-4) << c.name << " dt " << dt;
      EXPECT_LT(r.endSpeed, 1e-2) << c.name << " dt " << dt;
      // Held up: it has not slid off or sunk through (the rods' tops are at y = 0).
      EXPECT_GT(r.lowest, -0.01) << c.name << " dt " << dt;
    }
}

}  // namespace
}  // namespace gf
