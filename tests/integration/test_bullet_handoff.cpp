// Hand-off of fragments to Bullet: conservation across the hand-off, exact
// mass properties against analytic boxes, a fragment resting on a Bullet floor, and bad API use.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <vector>

#include "common/bullet_world.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

BodyDef breakableBox(double sx, double sy, double sz, int nx, int ny, int nz) {
  BodyDef def;
  def.mesh = gen::box(sx, sy, sz, nx, ny, nz);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;  // only cuts break it
  return def;
}

glm::dvec3 toGlm(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

// Rigid-body momenta as Bullet holds them: m v and, about the origin, c x m v + I w.
void bulletMomenta(const btRigidBody& rb, glm::dvec3& p, glm::dvec3& L, glm::dvec3& spin) {
  const double m = 1.0 / rb.getInvMass();
  p = m * toGlm(rb.getLinearVelocity());
  const btMatrix3x3 I = rb.getInvInertiaTensorWorld().inverse();
  spin = toGlm(I * rb.getAngularVelocity());
  L = glm::cross(toGlm(rb.getCenterOfMassPosition()), p) + spin;
}

double rel(glm::dvec3 a, glm::dvec3 b) { return glm::length(a - b) / glm::length(b); }

// A cut through the plane x = x0 that splits a box of [0,1]^3 scale in two.
Blade planeBlade(double x0) {
  Blade b;
  b.vertices = {
      {float(x0), -10, -10}, {float(x0), 10, -10}, {float(x0), 10, 10}, {float(x0), -10, 10}};
  b.triangles = {0, 1, 2, 0, 2, 3};
  return b;
}

TEST(BulletHandoff, ConservesMomentumAndAngularMomentum) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(breakableBox(0.3, 0.2, 0.1, 6, 4, 2)).value();
  // A tumbling, slightly deformed body whose velocity field is not rigid, so L is not I w of
  // any one field the hand-off could copy.
  const std::span<const double> x0 = world.positions(id);
  std::vector<double> x(x0.begin(), x0.end()), v(x.size());
  const glm::dvec3 v0(0.3, -0.2, 0.1), w0(2, -1, 3), c0(0.15, 0.1, 0.05);
  for (size_t n = 0; n < x.size() / 3; ++n) {
    glm::dvec3 p(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
    const glm::dvec3 r = p - c0;
    const glm::dvec3 vn =
        v0 + glm::cross(w0, r) +
        0.05 * glm::dvec3(std::sin(7.0 * n), std::cos(3.0 * n), std::sin(5.0 * n + 1));
    p += 0.01 * glm::dvec3(r.y * r.x, std::sin(9.0 * n) * 0.02, r.z * r.z);  // small strain
    for (int i = 0; i < 3; ++i) {
      x[3 * n + i] = p[i];
      v[3 * n + i] = vn[i];
    }
  }
  ASSERT_TRUE(world.setPositions(id, x).ok());
  ASSERT_TRUE(world.setVelocities(id, v).ok());
  const BodyStats before = world.stats(id);

  test::BulletWorld dyn(btVector3(0, 0, 0));
  bullet::Bridge bridge(world, dyn.world);
  Result<btRigidBody*> rb = bridge.handOff(id, 0);
  ASSERT_TRUE(rb.ok()) << rb.error().message;
  glm::dvec3 p, L, spin;
  bulletMomenta(*rb.value(), p, L, spin);
  const glm::dvec3 c = toGlm(rb.value()->getCenterOfMassPosition());
  const glm::dvec3 spinFem = before.angularMomentum - glm::cross(c, before.linearMomentum);
  std::printf("hand-off: mass %.9g vs %.9g; |dp|/|p| = %.2e, |dL|/|L| = %.2e, spin %.2e\n",
              1.0 / rb.value()->getInvMass(), before.mass, rel(p, before.linearMomentum),
              rel(L, before.angularMomentum), rel(spin, spinFem));
  EXPECT_LT(std::abs(1.0 / rb.value()->getInvMass() - before.mass), 1e-6 * before.mass);
  EXPECT_LT(rel(p, before.linearMomentum), 1e-6);
  EXPECT_LT(rel(L, before.angularMomentum), 1e-4);
  EXPECT_LT(rel(spin, spinFem), 1e-4);
  ASSERT_EQ(world.handoffEvents().size(), 1u);
  EXPECT_EQ(world.handoffEvents()[0].fragment, 0);
}

TEST(BulletHandoff, BoxMassAndInertiaMatchAnalytic) {
  const double a = 0.3, b = 0.2, c = 0.1, rho = 1000;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(breakableBox(a, b, c, 6, 4, 2)).value();
  // Turned and moved: the info must report the pose and the inertia in world axes.
  const glm::dquat q = glm::angleAxis(0.7, glm::normalize(glm::dvec3(1, 2, -1)));
  const glm::dvec3 t(1, -2, 0.5);
  const glm::dmat3 R = glm::mat3_cast(q);
  std::vector<double> x(world.positions(id).begin(), world.positions(id).end());
  for (size_t n = 0; n < x.size() / 3; ++n) {
    const glm::dvec3 p = R * glm::dvec3(x[3 * n], x[3 * n + 1], x[3 * n + 2]) + t;
    for (int i = 0; i < 3; ++i) x[3 * n + i] = p[i];
  }
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const RigidFragmentInfo info = world.fragmentInfo(id, 0).value();
  const double m = rho * a * b * c;
  const glm::dmat3 Ibox(m / 12 * (b * b + c * c), 0, 0, 0, m / 12 * (a * a + c * c), 0, 0, 0,
                        m / 12 * (a * a + b * b));
  const glm::dmat3 expected = R * Ibox * glm::transpose(R);
  double err = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) err = std::max(err, std::abs(info.inertia[j][i] - expected[j][i]));
  const glm::dvec3 centre = R * glm::dvec3(a / 2, b / 2, c / 2) + t;
  std::printf("box: mass %.12g (analytic %.12g), max |I - I_box| / I_max = %.2e, |c| err %.2e\n",
              info.mass, m, err / (m / 12 * (a * a + b * b)),
              glm::length(info.centreOfMass - centre));
  EXPECT_LT(std::abs(info.mass - m), 1e-10 * m);
  EXPECT_LT(err, 1e-2 * m / 12 * (a * a + b * b));
  EXPECT_LT(glm::length(info.centreOfMass - centre), 1e-12);
  EXPECT_LT(glm::length(info.translation - t), 1e-10);
  EXPECT_GT(std::abs(glm::dot(info.rotation, q)), 1 - 1e-12);

  // Split in two by a cut: the pieces' corner cells partition the box, so their inertias,
  // moved to the common centre (parallel axes), add up to the box's.
  World w2(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id2 = w2.createBody(breakableBox(a, b, c, 6, 4, 2)).value();
  ASSERT_TRUE(w2.cut(id2, planeBlade(0.125)).ok());
  (void)w2.step(1e-4);
  ASSERT_EQ(w2.fractureStats(id2).fragments, 2);
  glm::dmat3 sum(0.0);
  double mass = 0;
  const glm::dvec3 cb(a / 2, b / 2, c / 2);
  for (int32_t f = 0; f < 2; ++f) {
    const RigidFragmentInfo fi = w2.fragmentInfo(id2, f).value();
    const glm::dvec3 d = fi.centreOfMass - cb;
    sum += fi.inertia + fi.mass * (glm::dot(d, d) * glm::dmat3(1.0) - glm::outerProduct(d, d));
    mass += fi.mass;
  }
  double err2 = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) err2 = std::max(err2, std::abs(sum[j][i] - Ibox[j][i]));
  std::printf("two pieces: mass sum %.12g, parallel-axis sum vs box: %.2e relative\n", mass,
              err2 / Ibox[2][2]);
  EXPECT_LT(std::abs(mass - m), 1e-10 * m);
  EXPECT_LT(err2, 1e-6 * Ibox[2][2]);  // 1e-4 s of gravity-free motion: nearly rigid

  // Bullet gets the principal moments of the box.
  test::BulletWorld dyn(btVector3(0, 0, 0));
  bullet::Bridge bridge(world, dyn.world);
  btRigidBody* rb = bridge.handOff(id, 0).value();
  const btVector3 inv = rb->getInvInertiaDiagLocal();
  double got[3] = {1 / inv.x(), 1 / inv.y(), 1 / inv.z()};
  double want[3] = {Ibox[0][0], Ibox[1][1], Ibox[2][2]};
  std::sort(got, got + 3);
  std::sort(want, want + 3);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], 1e-2 * want[i]);
}

TEST(BulletHandoff, FragmentsFallOntoBulletFloorAndSurfaceFollows) {
  WorldDef wd;
  wd.backend = Backend::Cpu;
  World world(wd);
  BodyDef def = breakableBox(0.2, 0.2, 0.2, 4, 4, 4);
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += 0.5;
  const BodyId id = world.createBody(def).value();
  const SurfaceView s0 = world.surface(id);
  ASSERT_FALSE(s0.positions.empty());
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  bullet::Bridge bridge(world, dyn.world);
  ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
  ASSERT_TRUE(world.cut(id, planeBlade(0.125)).ok());
  size_t handoffs = 0;
  for (int frame = 0; frame < 120; ++frame) {
    const StepStatus st = bridge.step(1.0 / 60);
    EXPECT_FALSE(st.has(kStepInvalidInput)) << st.message;
    handoffs += world.handoffEvents().size();
  }
  EXPECT_EQ(handoffs, 2u);
  ASSERT_EQ(bridge.fragments().size(), 2u);
  const std::span<const double> x = world.positions(id);
  const std::span<const double> v = world.velocities(id);
  double lowest = 1e300, vmax = 0;
  for (size_t n = 0; n < x.size() / 3; ++n) lowest = std::min(lowest, x[3 * n + 1]);
  for (double vi : v) vmax = std::max(vmax, std::abs(vi));
  const SurfaceView s = world.surface(id);
  double surfLowest = 1e300;
  for (size_t i = 1; i < s.positions.size(); i += 3)
    surfLowest = std::min<double>(surfLowest, s.positions[i]);
  std::printf("after 2 s: lowest node y = %.4f, lowest surface vertex y = %.4f, max |v| = %.3g\n",
              lowest, surfLowest, vmax);
  EXPECT_GT(lowest, -0.005);  // on the floor, not through it
  EXPECT_LT(lowest, 0.03);    // it fell 0.5 m and rests (hull margin <= 1 cm)
  EXPECT_LT(vmax, 0.05);
  EXPECT_NEAR(surfLowest, lowest, 1e-4);  // the render surface moved with the nodes
}

TEST(BulletHandoff, BadApiUseReturnsErrorsAndChangesNothing) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = breakableBox(0.2, 0.1, 0.1, 4, 2, 2);
  Grip grip;
  grip.nodes = test::selectNodes(def.mesh, [](double xx, double, double) { return xx < 1e-9; });
  def.grips = {grip};
  const BodyId id = world.createBody(def).value();
  BodyDef plain = breakableBox(0.1, 0.1, 0.1, 2, 2, 2);
  plain.fracture.enabled = false;
  const BodyId noFracture = world.createBody(plain).value();
  const BodyId stale{id.index, id.generation + 7};
  const uint64_t hash = world.stateHash();
  const glm::dquat q(1, 0, 0, 0);
  EXPECT_FALSE(world.detachFragment(stale, 0).ok());
  EXPECT_FALSE(world.detachFragment(noFracture, 0).ok());
  EXPECT_FALSE(world.detachFragment(id, 1).ok());
  EXPECT_FALSE(world.detachFragment(id, -1).ok());
  const Result<RigidFragmentInfo> gripped = world.detachFragment(id, 0);
  ASSERT_FALSE(gripped.ok());
  EXPECT_NE(gripped.error().message.find("grip"), std::string::npos) << gripped.error().message;
  EXPECT_FALSE(world.fragmentInfo(stale, 0).ok());
  EXPECT_FALSE(world.setFragmentTransform(id, 0, glm::dvec3(0), q, {}, {}).ok());  // not detached
  EXPECT_EQ(world.stateHash(), hash);
  EXPECT_TRUE(world.handoffEvents().empty());

  // A free body: detach once, then the transform's arguments are checked.
  World free(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId fid = free.createBody(breakableBox(0.2, 0.1, 0.1, 4, 2, 2)).value();
  ASSERT_TRUE(free.detachFragment(fid, 0).ok());
  EXPECT_FALSE(free.detachFragment(fid, 0).ok());  // already detached
  const uint64_t h2 = free.stateHash();
  const double nan = std::nan("");
  EXPECT_FALSE(free.setFragmentTransform(fid, 0, glm::dvec3(nan, 0, 0), q, {}, {}).ok());
  EXPECT_FALSE(
      free.setFragmentTransform(fid, 0, glm::dvec3(0), glm::dquat(0, 0, 0, 0), {}, {}).ok());
  EXPECT_FALSE(free.setFragmentTransform(fid, 0, glm::dvec3(0), q, glm::dvec3(0, nan, 0), {}).ok());
  EXPECT_FALSE(free.setFragmentTransform(fid, 1, glm::dvec3(0), q, {}, {}).ok());
  EXPECT_EQ(free.stateHash(), h2);
  test::BulletWorld dyn(btVector3(0, 0, 0));
  bullet::Bridge bridge(free, dyn.world);
  EXPECT_FALSE(bridge.handOff(fid, 0).ok());  // detached by the world already
  EXPECT_FALSE(bridge.setPolicy(fid, bullet::HandoffPolicy::BelowVolume, -1).ok());
  EXPECT_FALSE(bridge.setPolicy(noFracture, bullet::HandoffPolicy::EveryFragment).ok());

  // Both worlds still step, and the gripped body still hangs from its grip.
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(world.step(1.0 / 60).flags & (kStepNanContained | kStepInvalidInput), 0u);
    EXPECT_EQ(free.step(1.0 / 60).flags & (kStepNanContained | kStepInvalidInput), 0u);
  }
  EXPECT_TRUE(test::stateFinite(world, id));
  EXPECT_TRUE(test::stateFinite(free, fid));
  // A detached fragment is held by its rigid motion: here, at rest, it does not fall.
  const RigidFragmentInfo after = free.fragmentInfo(fid, 0).value();
  EXPECT_LT(glm::length(after.linearVelocity), 1e-12);
}

// Kinetic energy and momenta of every handed-off piece as Bullet holds them.
struct RigidTotals {
  glm::dvec3 p{0}, L{0};
  double kinetic = 0;
};
RigidTotals rigidTotals(const bullet::Bridge& bridge) {
  RigidTotals t;
  for (const bullet::RigidFragment& f : bridge.fragments()) {
    const btRigidBody& rb = *f.rigidBody;
    glm::dvec3 p, L, spin;
    bulletMomenta(rb, p, L, spin);
    const glm::dvec3 v = toGlm(rb.getLinearVelocity()), w = toGlm(rb.getAngularVelocity());
    t.p += p;
    t.L += L;
    t.kinetic += 0.5 * (glm::dot(p, v) + glm::dot(spin, w));
  }
  return t;
}

// A bar cut in three and handed to Bullet (no gravity): from the FEM state just before the
// hand-off to the Bullet state after its first step and over the next 0.1 s, momentum is
// conserved and no kinetic energy appears, whatever the step. Apart: the pieces drift 4 cm
// apart before they are handed off. Touching: they are handed off the step they are cut, face
// to face (their node hulls a node spacing apart, wider than two margins). Pressed: the bar also
// lies 3 mm deep in a frictionless Bullet floor the FEM body does not see (as a body pressed into
// the floor by its contact's penalty is): each new hull starts penetrating it, and Bullet must push
// it out without making it fly (Baumgarte's push, erp depth / h, grows as the step shrinks). The
// bar translates only, so the pieces' inertias barely enter (but see the spin below).
enum class Contact { Apart, Touching, Pressed };
std::string contactName(Contact c) {
  return c == Contact::Apart ? "apart" : c == Contact::Touching ? "touching" : "pressed";
}
struct HandoffCase {
  int substeps;
  Contact contact;
};
class HandoffEnergy : public ::testing::TestWithParam<HandoffCase> {};

TEST_P(HandoffEnergy, ConservesMomentumAndGainsNoKineticEnergy) {
  const HandoffCase c = GetParam();
  const double h = 1.0 / 60 / c.substeps;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = breakableBox(0.3, 0.1, 0.1, 6, 2, 2);
  def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
  const double depth = c.contact == Contact::Pressed ? 0.003 : 0;
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] -= depth;
  const BodyId id = world.createBody(def).value();
  const glm::dvec3 v0(1.0, 0, 0.3);
  // spread: the pieces drift apart along the bar at this speed per metre from its middle.
  const auto setVelocity = [&](double spread) {
    const std::span<const double> x = world.positions(id);
    std::vector<double> v(x.size());
    for (size_t n = 0; n < x.size() / 3; ++n) {
      const glm::dvec3 vn = v0 + glm::dvec3(spread * (x[3 * n] - 0.15), 0, 0);
      for (int i = 0; i < 3; ++i) v[3 * n + i] = vn[i];
    }
    ASSERT_TRUE(world.setVelocities(id, v).ok());
  };
  setVelocity(0);
  test::BulletWorld dyn(btVector3(0, 0, 0), /*withFloor=*/c.contact == Contact::Pressed);
  if (dyn.floor) dyn.floor->setFriction(0);
  bullet::Bridge bridge(world, dyn.world);
  if (c.contact != Contact::Apart) {
    ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
  }
  ASSERT_TRUE(world.cut(id, planeBlade(0.125)).ok());
  ASSERT_TRUE(world.cut(id, planeBlade(0.225)).ok());
  (void)world.step(h);
  ASSERT_EQ(world.fractureStats(id).fragments, 3);
  if (c.contact == Contact::Apart) {
    setVelocity(0.4);  // the end pieces leave the middle one at 4 cm/s each, for 1 s
    for (double t = 0; t < 1.0; t += h) (void)world.step(h);
    ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
    (void)world.step(h);
  }
  const BodyStats before = world.stats(id);
  // The kinetic energy the hand-off gives the pieces (rigid motions carrying their momenta).
  double given = 0;
  for (int32_t f = 0; f < 3; ++f) {
    const RigidFragmentInfo fi = world.fragmentInfo(id, f).value();
    given += 0.5 * fi.mass * glm::dot(fi.linearVelocity, fi.linearVelocity) +
             0.5 * glm::dot(fi.angularVelocity, fi.inertia * fi.angularVelocity);
  }
  ASSERT_EQ(bridge.handOffNewFragments(), 3);
  dyn.world.stepSimulation(btScalar(h), 0);
  bridge.syncFromDynamics();
  const RigidTotals after = rigidTotals(bridge);
  double most = after.kinetic;
  for (double t = 0; t < 0.1; t += h) {
    dyn.world.stepSimulation(btScalar(h), 0);
    most = std::max(most, rigidTotals(bridge).kinetic);
  }
  bridge.syncFromDynamics();
  double lowest = 1e300;
  const std::span<const double> x = world.positions(id);
  for (size_t n = 1; n < x.size(); n += 3) lowest = std::min(lowest, x[n]);
  std::printf(
      "%2d substeps, %-8s: kinetic %.6g J (FEM) -> %.6g J (hand-off) -> %.6g J (Bullet, "
      "first step), at most %.6g J in 0.1 s; |dp|/|p| = %.2e (y: %.3g kg m/s); lowest "
      "node %.4f m\n",
      c.substeps, contactName(c.contact).c_str(), before.kineticEnergy, given, after.kinetic, most,
      rel(after.p, before.linearMomentum), after.p.y - before.linearMomentum.y, lowest);
  // The floor may push along y; it has no friction, so nothing else changes p.
  glm::dvec3 p = after.p, pFem = before.linearMomentum;
  if (c.contact == Contact::Pressed) p.y = pFem.y = 0;
  EXPECT_LT(rel(p, pFem), 1e-5);
  // Bullet adds nothing to what the hand-off gives.
  EXPECT_LE(after.kinetic, given * (1 + 1e-5));
  EXPECT_LE(most, given * (1 + 1e-5));
  // The hand-off itself may give a little more than the FEM had: the pieces' centres of mass
  // are their corner cells' (the continuum's), their momenta the lumped nodes', whose centre
  // is up to a fraction of a cell away, so a translating end piece gets a spin (0.04-0.14 %
  // here). Known, not fixed (Bullet would need the lumped centre and inertia).
  EXPECT_LE(given, before.kineticEnergy * (1 + 2e-3));
  // And a piece pressed into the floor is pushed out of it.
  if (c.contact == Contact::Pressed) {
    EXPECT_GT(lowest, 0);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Substeps, HandoffEnergy,
    ::testing::Values(HandoffCase{1, Contact::Apart}, HandoffCase{64, Contact::Apart},
                      HandoffCase{1, Contact::Touching}, HandoffCase{64, Contact::Touching},
                      HandoffCase{1, Contact::Pressed}, HandoffCase{4, Contact::Pressed},
                      HandoffCase{16, Contact::Pressed}, HandoffCase{64, Contact::Pressed}),
    [](const ::testing::TestParamInfo<HandoffCase>& i) {
      return std::to_string(i.param.substeps) + "_substeps_" + contactName(i.param.contact);
    });

// A body pulverised into single nodes is all chips (FractureStats::chips): loose nodes with no
// whole tet, which stay FEM particles, so nothing of it enters Bullet (a glass bunny hit at
// 20 m/s once put 5016 overlapping one-node bodies and 5 million pairs into Bullet and ran out
// of memory). They fall onto the floor collider and stay on it.
TEST(BulletHandoff, PulverisedBodyStaysFemParticlesOnTheFloor) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, 8, 8, 8);  // 729 nodes
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += 0.05;
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1;  // [Pa]: every edge of a stretched body breaks
  const BodyId id = world.createBody(def).value();
  // Stretched by 30 % in every direction about its centre: tension along every edge.
  std::vector<double> stretched(def.mesh.positions);
  for (size_t i = 0; i < stretched.size(); ++i) {
    const double c = i % 3 == 1 ? 0.15 : 0.1;
    stretched[i] = c + 1.3 * (stretched[i] - c);
  }
  ASSERT_TRUE(world.setPositions(id, stretched).ok());
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  bullet::Bridge bridge(world, dyn.world);
  ASSERT_TRUE(bridge.addCollider(dyn.floor.get()).ok());
  ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
  for (int s = 0; s < 60; ++s) (void)bridge.step(1.0 / 120);
  const FractureStats fs = world.fractureStats(id);
  const std::span<const double> x = world.positions(id), v = world.velocities(id);
  double lowest = 1e300, fastest = 0;
  for (size_t n = 0; n < x.size() / 3; ++n) {
    lowest = std::min(lowest, x[3 * n + 1]);
    fastest = std::max(fastest, std::abs(v[3 * n + 1]));
  }
  std::printf(
      "%d fragments, %d chips, %zu in Bullet; lowest node %.2e m, fastest vertical "
      "%.2e m/s after 0.5 s\n",
      fs.fragments, fs.chips, bridge.fragments().size(), lowest, fastest);
  EXPECT_EQ(fs.fragments, 729);  // it did pulverise
  EXPECT_EQ(fs.chips, 729);
  EXPECT_EQ(bridge.fragments().size(), 0u);
  EXPECT_TRUE(test::stateFinite(world, id));
  EXPECT_GT(lowest, -1e-3);
  EXPECT_LT(lowest, 1e-3);
  EXPECT_LT(fastest, 1e-2);
}

// A body cut into more pieces than kMaxRigidFragments puts that many into Bullet, the biggest
// first, and none of its chips, so Bullet's pair count stays bounded; the rest stay FEM. Blades
// half a cell past every other node layer of a 34 x 34 x 1-cell slab, in x and in y, leave
// 17 x 17 pieces of whole cells and the chips of the layers x = 0 and y = 0.
TEST(BulletHandoff, BodyCutIntoManyPiecesPutsABoundedNumberIntoBullet) {
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const int cells = 34;
  const double h = 0.01;
  BodyDef def = breakableBox(cells * h, cells * h, h, cells, cells, 1);
  def.fracture.releaseEveryBatch = true;
  for (size_t i = 2; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += 0.02;
  const BodyId id = world.createBody(def).value();
  for (int k = 0; k < cells / 2; ++k) {
    const float c = float((2 * k + 0.5) * h);
    Blade across = planeBlade(c);
    ASSERT_TRUE(world.cut(id, across).ok());
    for (glm::vec3& p : across.vertices) std::swap(p.x, p.y);  // the plane y = c
    ASSERT_TRUE(world.cut(id, across).ok());
  }
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  bullet::Bridge bridge(world, dyn.world);
  ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
  ASSERT_TRUE(bridge.addCollider(dyn.floor.get()).ok());
  for (int s = 0; s < 10; ++s) (void)bridge.step(1.0 / 120);
  const FractureStats fs = world.fractureStats(id);
  const std::span<const uint8_t> chip = world.chipFlags(id);
  std::vector<int> nodes(size_t(fs.fragments), 0);
  for (int32_t f : world.nodeFragments(id)) ++nodes[size_t(f)];
  int smallestIn = 1 << 30, largestOut = 0, chipsIn = 0;
  for (int32_t f = 0; f < fs.fragments; ++f) {
    const bool in = bridge.rigidBody(id, f) != nullptr;
    chipsIn += in && chip[size_t(f)] ? 1 : 0;
    if (in) smallestIn = std::min(smallestIn, nodes[size_t(f)]);
    if (!in && !chip[size_t(f)]) largestOut = std::max(largestOut, nodes[size_t(f)]);
  }
  const int pairs = dyn.world.getBroadphase()->getOverlappingPairCache()->getNumOverlappingPairs();
  std::printf(
      "%d fragments, %d chips, %zu in Bullet (%d chips), %d overlapping pairs; nodes of "
      "the smallest piece in Bullet %d, of the largest left out %d\n",
      fs.fragments, fs.chips, bridge.fragments().size(), chipsIn, pairs, smallestIn, largestOut);
  EXPECT_EQ(fs.fragments - fs.chips, (cells / 2) * (cells / 2));
  EXPECT_EQ(bridge.fragments().size(), size_t(bullet::kMaxRigidFragments));
  EXPECT_EQ(chipsIn, 0);
  EXPECT_GE(smallestIn, largestOut);
  EXPECT_LE(pairs, bullet::kMaxRigidFragments * (bullet::kMaxRigidFragments + 1) / 2);
  EXPECT_TRUE(test::stateFinite(world, id));
}

}  // namespace
}  // namespace gf
