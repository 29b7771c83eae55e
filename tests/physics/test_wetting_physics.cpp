// Wet clay is softer (thesis sec 7.2.2, fig 7.12-7.13): the same push on a wetted region moves
// it further, and a proxy pressed to the same depth feels less force than on the dry body.
// Water stays in the piece it is in once a crack separates the body.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <iostream>

namespace gf {
namespace {

WorldDef worldDef(float gravityY) {
  WorldDef d;
  d.gravity = {0, gravityY, 0};
  return d;
}

constexpr double kDt = 1.0 / 60;
const glm::vec3 kTop{0.05f, 0.1f, 0.05f};  // a node of the 6x6x6 grid, top face centre

BodyDef clayCube() {
  BodyDef def;
  def.mesh = gen::box(0.1, 0.1, 0.1, 6, 6, 6);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  def.wetting.diffusivity = 0;  // the wet region stays where the brush put it
  def.grips.push_back({});
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n + 1] < 1e-9) def.grips[0].nodes.push_back(int32_t(n));
  return def;
}

int32_t nodeAt(const TetMesh& m, glm::vec3 p) {
  for (size_t n = 0; n < m.nodeCount(); ++n)
    if (std::abs(m.positions[3 * n] - p.x) < 1e-6 &&
        std::abs(m.positions[3 * n + 1] - p.y) < 1e-6 &&
        std::abs(m.positions[3 * n + 2] - p.z) < 1e-6)
      return int32_t(n);
  return -1;
}

// Saturates the top centre (radius 3.5 cm) in one step when `wet`; otherwise steps once dry.
void prepare(World& world, BodyId id, bool wet) {
  if (wet) {
    WetBrush brush;
    brush.centre = kTop;
    brush.radius = 0.035f;
    brush.rate = 1000;
    ASSERT_TRUE(world.wet(id, brush));
  }
  ASSERT_TRUE(world.step(kDt).ok());
}

// Downward displacement of the top centre under 1 N held there for 2 s.
double pushDisplacement(bool wet) {
  World world(worldDef(0));
  const BodyDef def = clayCube();
  const int32_t node = nodeAt(def.mesh, kTop);
  EXPECT_GE(node, 0);
  const BodyId id = world.createBody(def).value();
  prepare(world, id, wet);
  for (int k = 0; k < 120; ++k) {
    EXPECT_TRUE(world.applyForce(id, kTop, {0, -1, 0}));
    EXPECT_TRUE(world.step(kDt).ok());
  }
  return kTop.y - world.positions(id)[3 * size_t(node) + 1];
}

// Force on a sphere proxy pressed 1 cm into the top centre over 0.5 s, then held for 1 s: what
// the probe publishes after the last step.
double proxyForce(bool wet) {
  Collider proxy;
  proxy.kind = Collider::Kind::Sphere;
  proxy.radius = 0.03f;
  proxy.point = {kTop.x, kTop.y + proxy.radius, kTop.z};
  proxy.velocity = {0, -0.02f, 0};
  WorldDef wd = worldDef(0);
  wd.colliders.push_back(proxy);
  World world(wd);
  HapticProbe probe;
  EXPECT_TRUE(world.attachHapticProbe(&probe, 0));
  const BodyId id = world.createBody(clayCube()).value();
  proxy.velocity = {0, 0, 0};
  prepare(world, id, wet);
  for (int k = 1; k < 30; ++k) EXPECT_TRUE(world.step(kDt).ok());
  proxy.point = world.colliders()[0].point;
  EXPECT_NEAR(proxy.point.y, kTop.y + 0.03f - 0.01f, 1e-5);
  EXPECT_TRUE(world.setColliders({&proxy, 1}));
  for (int k = 0; k < 60; ++k) EXPECT_TRUE(world.step(kDt).ok());
  const HapticSample s = probe.poll();
  EXPECT_EQ(s.sequence, 90u);
  EXPECT_DOUBLE_EQ(s.time, world.time());
  const glm::dvec3 expected = -world.colliderImpulses()[0] / kDt;
  EXPECT_EQ(s.force.y, expected.y);
  return s.force.y;  // the body pushes the proxy up
}

TEST(WettingPhysics, TheSamePushMovesAWetRegionFurther) {
  const double dry = pushDisplacement(false), wet = pushDisplacement(true);
  std::cout << "[ wetting ] 1 N push, top-centre displacement: dry " << dry * 1e3 << " mm, wet "
            << wet * 1e3 << " mm (x" << wet / dry << ")\n";
  EXPECT_GT(dry, 0);
  EXPECT_GT(wet, 1.1 * dry);
}

TEST(WettingPhysics, APressedProxyFeelsLessForceOnAWetRegion) {
  const double dry = proxyForce(false), wet = proxyForce(true);
  std::cout << "[ wetting ] proxy pressed 1 cm, force: dry " << dry << " N, wet " << wet << " N (x"
            << wet / dry << ")\n";
  EXPECT_GT(dry, 0);
  EXPECT_GT(wet, 0);
  EXPECT_LT(wet, 0.9 * dry);
}

// Water and cracks: a 20 cm bar (8 x 2 x 2 cells) cut in two by a blade through
// (10.5, 2.5, 2.5) cm, across or tilted, its left end then saturated and left to diffuse for
// 2 s. Each tet's water belongs to the fragment of most of its nodes; no water may reach the
// right fragment's tets, the left one's spreads up to the cut, and the total is kept. The same
// bar uncut lets water past the plane.
struct SplitBar {
  double right = 0, leftAtCut = 0, total = 0, totalBefore = 0;
  int fragments = 0;
};

SplitBar wetAfterCut(bool cut, glm::dvec3 normal) {
  World world(worldDef(0));
  BodyDef def;
  def.mesh = gen::box(0.2, 0.05, 0.05, 8, 2, 2);
  def.material = Material::stableNeoHookean(1e5, 0.3, 1800);
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;  // only the blade breaks edges
  def.wetting.diffusivity = 1e-3;
  const BodyId id = world.createBody(def).value();
  const glm::dvec3 p(0.105, 0.025, 0.025), n = glm::normalize(normal);
  const glm::dvec3 u = 0.1 * glm::normalize(glm::cross(n, glm::dvec3(0, 0, 1))),
                   v = 0.1 * glm::normalize(glm::cross(n, u));
  if (cut) {
    Blade blade;
    blade.vertices = {glm::vec3(p - u - v), glm::vec3(p + u - v), glm::vec3(p + u + v),
                      glm::vec3(p - u + v)};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    EXPECT_TRUE(world.cut(id, blade).ok());
  }
  EXPECT_TRUE(world.step(kDt).ok());
  SplitBar r;
  r.fragments = world.fractureStats(id).fragments;
  WetBrush brush;
  brush.centre = {0, 0.025f, 0.025f};
  brush.radius = 0.03f;
  brush.rate = 1000;
  EXPECT_TRUE(world.wet(id, brush).ok());
  EXPECT_TRUE(world.step(kDt).ok());
  const auto sums = [&](SplitBar& out) {
    out.right = out.leftAtCut = out.total = 0;
    const std::span<const double> water = world.waterMass(id);
    for (size_t t = 0; t < def.mesh.tetCount(); ++t) {
      int left = 0;
      double nearest = 1;
      for (int k = 0; k < 4; ++k) {
        const size_t a = 3 * size_t(def.mesh.tets[4 * t + size_t(k)]);
        const glm::dvec3 x(def.mesh.positions[a], def.mesh.positions[a + 1],
                           def.mesh.positions[a + 2]);
        const double d = glm::dot(n, x - p);
        left += d < 0;
        nearest = std::min(nearest, std::abs(d));
      }
      out.total += water[t];
      if (left < 2) out.right += water[t];
      if (left > 2 && nearest < 0.03) out.leftAtCut += water[t];
    }
  };
  sums(r);
  r.totalBefore = r.total;
  for (int k = 0; k < 120; ++k) EXPECT_TRUE(world.step(kDt).ok());
  sums(r);
  std::printf(
      "%s, normal (%.2f, %.2f, %.2f): %d fragment(s); water right of the plane %.3e kg, left "
      "within 3 cm of it %.3e kg, of %.6e kg (drift %.1e)\n",
      cut ? "cut" : "uncut", n.x, n.y, n.z, r.fragments, r.right, r.leftAtCut, r.total,
      r.total / r.totalBefore - 1);
  return r;
}

TEST(WettingPhysics, WaterDoesNotCrossACrackThatSeparatesTheBody) {
  for (const glm::dvec3 normal : {glm::dvec3(1, 0, 0), glm::dvec3(1, 0.4, 0.2)}) {
    const SplitBar cut = wetAfterCut(true, normal), whole = wetAfterCut(false, normal);
    ASSERT_EQ(cut.fragments, 2);
    ASSERT_EQ(whole.fragments, 1);
    EXPECT_EQ(cut.right, 0.0);
    EXPECT_GT(cut.leftAtCut, 0.0);
    EXPECT_NEAR(cut.total, cut.totalBefore, 1e-12 * cut.totalBefore);
    // Uncut, the water has gone past the same plane.
    EXPECT_GT(whole.right, 1e-3 * whole.total);
    EXPECT_NEAR(whole.total, whole.totalBefore, 1e-12 * whole.totalBefore);
  }
}

}  // namespace
}  // namespace gf
