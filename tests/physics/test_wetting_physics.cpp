// Wet clay is softer (thesis sec 7.2.2, fig 7.12-7.13): the same push on a wetted region moves
// it further, and a proxy pressed to the same depth feels less force than on the dry body.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <cmath>
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

}  // namespace
}  // namespace gf
