// Two-way contact between Bullet rigid bodies and FEM bodies: a moving collider's
// reported impulse is the body's momentum change, a Bullet ball or turned box thrown at a free
// soft block conserves the total momentum, the ball takes exactly minus the collider's impulse,
// a ball dropped on a block resting on a Bullet floor comes to rest with the impulses
// balancing the weights, and with Bridge::setDynamicFriction a dynamic crate carries a block
// and Bullet's rolling and spinning friction slow a resting ball's spin.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "common/bullet_world.h"
#include "common/sim_helpers.h"
#include "kernels/contact.h"

namespace gf {
namespace {

glm::dvec3 toGlm(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

// A Bullet ball; declared after the BulletWorld, it leaves the world before the world goes.
struct Ball {
  btSphereShape shape;
  std::unique_ptr<btRigidBody> body;
  btDiscreteDynamicsWorld& world;
  Ball(btDiscreteDynamicsWorld& w, float radius, float mass, btVector3 at, btVector3 v)
      : shape(radius), world(w) {
    btVector3 inertia;
    shape.calculateLocalInertia(mass, inertia);
    btRigidBody::btRigidBodyConstructionInfo ci(mass, nullptr, &shape, inertia);
    ci.m_startWorldTransform.setOrigin(at);
    body = std::make_unique<btRigidBody>(ci);
    body->setLinearVelocity(v);
    body->setActivationState(DISABLE_DEACTIVATION);
    world.addRigidBody(body.get());
  }
  ~Ball() { world.removeRigidBody(body.get()); }
};

// A soft block [0, 0.2]^3 (no momentum-changing mass damping).
BodyDef softBlock(double density, LinearSolverKind solver = LinearSolverKind::Direct) {
  BodyDef def;
  def.solver.linearSolver = solver;
  def.mesh = gen::box(0.2, 0.2, 0.2, 6, 6, 6);
  def.material = Material::stableNeoHookean(2e5, 0.3, density);
  def.material.stiffnessDamping = 0.01;  // sums to zero over the nodes: momentum is kept
  return def;
}

TEST(BulletContact, MovingColliderImpulseIsTheBodysMomentumChange) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 2, {}});
  const BodyId id = world.createBody(softBlock(500)).value();
  Collider ball;
  ball.kind = Collider::Kind::Sphere;
  ball.point = glm::vec3(-0.06f, 0.1f, 0.1f);
  ball.radius = 0.05f;
  ball.velocity = glm::vec3(2, 0, 0);
  ASSERT_TRUE(world.setColliders({&ball, 1}).ok());
  glm::dvec3 total(0), moment(0);
  const glm::dvec3 p0 = world.stats(id).linearMomentum;
  for (int s = 0; s < 12; ++s) {
    ASSERT_EQ(world.step(1.0 / 120).flags, 0u);
    total += world.colliderImpulses()[0];
    moment += world.colliderAngularImpulses()[0];
  }
  const glm::dvec3 dp = world.stats(id).linearMomentum - p0;
  // The collider moved at its velocity: 12 steps of 1/120 s at 2 m/s.
  EXPECT_NEAR(world.colliders()[0].point.x, -0.06 + 0.2, 1e-6);
  const double err = glm::length(dp - total) / glm::length(total);
  std::printf(
      "moving sphere: impulse (%.5f, %.2e, %.2e) N s, body dp (%.5f, %.2e, %.2e), "
      "rel. diff %.2e, |moment| / (r |J|) %.2e\n",
      total.x, total.y, total.z, dp.x, dp.y, dp.z, err,
      glm::length(moment) / (0.05 * glm::length(total)));
  EXPECT_GT(total.x, 0.1);  // it pushed
  EXPECT_LT(err, 1e-3);
  // A frictionless sphere pushes along its radii: no moment about its centre.
  EXPECT_LT(glm::length(moment), 1e-6 * 0.05 * glm::length(total));
}

// An oriented box (Bullet boxes turn) against the same box built axis-aligned in its own frame:
// the depth is the same and the normal turns with the box.
TEST(BulletContact, OrientedBoxPenetrationTurnsWithTheBox) {
  const glm::dquat q = glm::angleAxis(0.6, glm::normalize(glm::dvec3(1, -2, 0.5)));
  const glm::dmat3 R = glm::mat3_cast(q);
  ColliderData box;
  box.kind = kColliderBox;
  box.point = {0.3, -0.2, 0.1};
  box.halfExtents = {0.4, 0.1, 0.25};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) box.rotation(i, j) = R[j][i];
  ColliderData local = box;
  local.point = {0, 0, 0};
  local.rotation = Mat3::identity();
  for (const glm::dvec3 p : {glm::dvec3(0.1, 0.05, -0.2), glm::dvec3(-0.35, 0.0, 0.1),
                             glm::dvec3(0.2, -0.09, 0.2), glm::dvec3(0.5, 0.3, 0.0)}) {
    const glm::dvec3 xw = R * p + glm::dvec3(0.3, -0.2, 0.1);
    Vec3 n, nl;
    const double d = penetration(box, {xw.x, xw.y, xw.z}, n);
    const double dl = penetration(local, {p.x, p.y, p.z}, nl);
    const glm::dvec3 nw = R * glm::dvec3(nl.x, nl.y, nl.z);
    EXPECT_NEAR(d, dl, 1e-12);
    EXPECT_NEAR(glm::length(glm::dvec3(n.x, n.y, n.z) - nw), 0, 1e-12);
  }
}

// Bullet's capsules (along y, x or z, turned and moving) mirror as capsule colliders whose
// segment ends are where Bullet puts them (the transform applied to +-halfHeight on the
// shape's up axis) and whose radius and velocity are Bullet's.
TEST(BulletContact, CapsulesMirrorWithBulletsSegment) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  test::BulletWorld dyn(btVector3(0, 0, 0), /*withFloor=*/false);
  btCapsuleShape alongY(0.05f, 0.3f);
  btCapsuleShapeX alongX(0.02f, 0.1f);
  btCapsuleShapeZ alongZ(0.01f, 0.4f);
  const btCapsuleShape* shapes[3] = {&alongY, &alongX, &alongZ};
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  {
    bullet::Bridge bridge(world, dyn.world);
    for (int i = 0; i < 3; ++i) {
      btRigidBody::btRigidBodyConstructionInfo ci(
          1, nullptr, const_cast<btCapsuleShape*>(shapes[i]), btVector3(1, 1, 1));
      ci.m_startWorldTransform.setOrigin(btVector3(0.1f * i, 1, -0.2f));
      ci.m_startWorldTransform.setRotation(
          btQuaternion(btVector3(1, -2, 0.5f + i).normalized(), 0.4f + 0.3f * i));
      bodies.push_back(std::make_unique<btRigidBody>(ci));
      bodies.back()->setLinearVelocity(btVector3(0, -1, 0.5f * i));
      dyn.world.addRigidBody(bodies.back().get());
      ASSERT_EQ(bridge.addCollider(bodies.back().get()).value(), i);
    }
    ASSERT_EQ(world.colliders().size(), 3u);
    for (int i = 0; i < 3; ++i) {
      const Collider& c = world.colliders()[size_t(i)];
      ASSERT_EQ(c.kind, Collider::Kind::Capsule);
      ASSERT_TRUE(c.check().ok()) << c.check().error().message;
      const btTransform& T = bodies[size_t(i)]->getCenterOfMassTransform();
      btVector3 tip(0, 0, 0);
      tip[shapes[i]->getUpAxis()] = shapes[i]->getHalfHeight();
      const glm::dvec3 axis = glm::dquat(c.rotation) * glm::dvec3(0, double(c.halfLength), 0);
      const glm::dvec3 top = glm::dvec3(c.point) + axis, bottom = glm::dvec3(c.point) - axis;
      EXPECT_NEAR(glm::length(top - toGlm(T * tip)), 0, 1e-6) << i;
      EXPECT_NEAR(glm::length(bottom - toGlm(T * -tip)), 0, 1e-6) << i;
      EXPECT_FLOAT_EQ(c.radius, shapes[i]->getRadius()) << i;
      EXPECT_NEAR(
          glm::length(glm::dvec3(c.velocity) - toGlm(bodies[size_t(i)]->getLinearVelocity())), 0,
          1e-6)
          << i;
    }
    for (auto& b : bodies) ASSERT_TRUE(bridge.removeCollider(b.get()).ok());
  }
  for (auto& b : bodies) dyn.world.removeRigidBody(b.get());
}

TEST(BulletContact, SetCollidersNamesTheBadFieldAndChangesNothing) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {Collider{}}});
  Collider bad[2];
  bad[1].kind = Collider::Kind::Sphere;
  bad[1].radius = -1;
  Result<void> r = world.setColliders(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("colliders[1].radius"), std::string::npos) << r.error().message;
  bad[1].radius = 0.1f;
  bad[0].velocity.y = std::nanf("");
  r = world.setColliders(bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("colliders[0].velocity"), std::string::npos)
      << r.error().message;
  EXPECT_EQ(world.colliders().size(), 1u);
  EXPECT_EQ(world.colliderImpulses().size(), 1u);
}

// Frictionless, no gravity, no floor: what the ball loses the block gains. With either solver
// (the multigrid's fixed V-cycles leave a small linear residual).
class BallThrownAtFreeBlock : public ::testing::TestWithParam<LinearSolverKind> {};

TEST_P(BallThrownAtFreeBlock, ConservesMomentum) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId block = world.createBody(softBlock(300, GetParam())).value();  // 2.4 kg
  test::BulletWorld dyn(btVector3(0, 0, 0), /*withFloor=*/false);
  const float mass = 1.0f, v0 = 3.0f;
  Ball ball(dyn.world, 0.05f, mass, btVector3(-0.1f, 0.1f, 0.1f), btVector3(v0, 0, 0));
  bullet::Bridge bridge(world, dyn.world);
  const Result<int32_t> index = bridge.addCollider(ball.body.get());
  ASSERT_TRUE(index.ok()) << index.error().message;
  auto total = [&] {
    return double(mass) * toGlm(ball.body->getLinearVelocity()) + world.stats(block).linearMomentum;
  };
  const glm::dvec3 before = total();
  double worstMismatch = 0, peak = 0;
  for (int s = 0; s < 60; ++s) {
    const glm::dvec3 vb = toGlm(ball.body->getLinearVelocity());
    ASSERT_EQ(bridge.step(1.0 / 120).flags, 0u);
    // Equal and opposite: the ball's momentum change is minus its collider's impulse.
    const glm::dvec3 J = world.colliderImpulses()[size_t(index.value())];
    const glm::dvec3 dpBall = double(mass) * (toGlm(ball.body->getLinearVelocity()) - vb);
    worstMismatch = std::max(worstMismatch, glm::length(dpBall + J));
    peak = std::max(peak, glm::length(J));
  }
  const glm::dvec3 after = total();
  const double err = glm::length(after - before) / glm::length(before);
  const double ballV = ball.body->getLinearVelocity().x();
  const double blockP = world.stats(block).linearMomentum.x;
  std::printf(
      "ball at block (solver %d): P %.6f -> %.6f N s (rel. error %.2e); ball v %.3f -> %.3f m/s, "
      "block p %.4f N s; peak step impulse %.4f N s, worst |dp_ball + J| %.2e N s\n",
      int(GetParam()), before.x, after.x, err, double(v0), ballV, blockP, peak, worstMismatch);
  EXPECT_LT(err, 1e-2);
  EXPECT_LT(ballV, 0.5 * v0);             // slowed, stopped or bounced
  EXPECT_GT(blockP, 0.5 * before.x);      // pushed
  EXPECT_LT(worstMismatch, 1e-5 * peak);  // single-precision Bullet
}

INSTANTIATE_TEST_SUITE_P(BulletContact, BallThrownAtFreeBlock,
                         ::testing::Values(LinearSolverKind::Direct, LinearSolverKind::Multigrid),
                         [](const ::testing::TestParamInfo<LinearSolverKind>& i) {
                           return i.param == LinearSolverKind::Direct ? "Direct" : "Multigrid";
                         });

// A turned Bullet box thrown at the free block hits it with an edge: linear momentum is
// exchanged exactly and the moment of the contact impulses spins the box up.
TEST(BulletContact, TurnedBoxThrownAtFreeBlockConservesMomenta) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId block = world.createBody(softBlock(300)).value();
  test::BulletWorld dyn(btVector3(0, 0, 0), /*withFloor=*/false);
  btBoxShape shape(btVector3(0.05f, 0.05f, 0.05f));
  const float mass = 2;
  btVector3 inertia;
  shape.calculateLocalInertia(mass, inertia);
  btRigidBody::btRigidBodyConstructionInfo ci(mass, nullptr, &shape, inertia);
  ci.m_startWorldTransform.setOrigin(btVector3(-0.1f, 0.13f, 0.1f));
  ci.m_startWorldTransform.setRotation(btQuaternion(btVector3(0, 0, 1), 0.5f));
  btRigidBody box(ci);
  box.setLinearVelocity(btVector3(2, 0, 0));
  box.setActivationState(DISABLE_DEACTIVATION);
  dyn.world.addRigidBody(&box);
  {
    bullet::Bridge bridge(world, dyn.world);
    ASSERT_EQ(bridge.addCollider(&box).value(), 0);
    auto momenta = [&](glm::dvec3& p, glm::dvec3& L) {
      const BodyStats s = world.stats(block);
      const glm::dvec3 pb = double(mass) * toGlm(box.getLinearVelocity());
      const btMatrix3x3 I = box.getInvInertiaTensorWorld().inverse();
      p = pb + s.linearMomentum;
      L = glm::cross(toGlm(box.getCenterOfMassPosition()), pb) +
          toGlm(I * box.getAngularVelocity()) + s.angularMomentum;
    };
    glm::dvec3 p0, L0, p1, L1;
    momenta(p0, L0);
    for (int s = 0; s < 60; ++s) ASSERT_EQ(bridge.step(1.0 / 120).flags, 0u);
    momenta(p1, L1);
    const double ep = glm::length(p1 - p0) / glm::length(p0);
    const double eL = glm::length(L1 - L0) / glm::length(L0);
    const double spin = box.getAngularVelocity().length();
    std::printf(
        "turned box: |dP|/|P| %.2e, |dL|/|L| %.2e, box spin %.3f rad/s, box v %.3f, "
        "block p %.4f N s\n",
        ep, eL, spin, double(box.getLinearVelocity().x()), world.stats(block).linearMomentum.x);
    EXPECT_LT(ep, 1e-2);
    EXPECT_GT(spin, 0.1);
    dyn.world.removeRigidBody(&box);
  }
}

// A soft block resting on a kinematic Bullet platform (a 10 x 1 x 10 m box the test drives,
// friction 0.5 met with the block's 0.5) that moves at 1 m/s along x, or turns at 0.4 rad/s
// about its vertical axis with the block 0.5 m out: the platform's friction drags the block at
// mu g until it rides along, and the turning one carries it round by w t.
TEST(BulletContact, KinematicPlatformCarriesABlockByFriction) {
  const double g = 9.81, dt = 1.0 / 60, mu = 0.5;
  for (const bool turning : {false, true}) {
    World world(WorldDef{glm::vec3(0, -float(g), 0), Backend::Cpu, nullptr, 1, {}});
    BodyDef def;
    def.mesh = gen::box(0.1, 0.04, 0.1, 4, 2, 4);
    const double offset = turning ? 0.45 : -0.05;  // the block's centre 0.5 m out, or at 0
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] += offset;
      def.mesh.positions[3 * n + 2] -= 0.05;
    }
    def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
    def.friction = mu;
    const BodyId block = world.createBody(def).value();
    test::BulletWorld dyn(btVector3(0, -float(g), 0), /*withFloor=*/false);
    btBoxShape shape(btVector3(5, 0.5, 5));
    btRigidBody platform(0, nullptr, &shape);
    platform.setCollisionFlags(platform.getCollisionFlags() |
                               btCollisionObject::CF_KINEMATIC_OBJECT);
    platform.setActivationState(DISABLE_DEACTIVATION);
    platform.setFriction(btScalar(mu));
    const double omega = 0.4, speed = 1;
    const auto pose = [&](double t) {
      btTransform T;
      T.setIdentity();
      T.setOrigin(btVector3(turning ? 0 : btScalar(speed * t), -0.5f, 0));
      if (turning) T.setRotation(btQuaternion(btVector3(0, 1, 0), btScalar(omega * t)));
      return T;
    };
    platform.setWorldTransform(pose(0));
    platform.setInterpolationWorldTransform(pose(0));
    dyn.world.addRigidBody(&platform);
    {
      bullet::Bridge bridge(world, dyn.world);
      ASSERT_EQ(bridge.addCollider(&platform).value(), 0);
      const auto mean = [](std::span<const double> a) {
        glm::dvec3 sum(0);
        for (size_t n = 0; n < a.size() / 3; ++n)
          sum += glm::dvec3(a[3 * n], a[3 * n + 1], a[3 * n + 2]);
        return sum / double(a.size() / 3);
      };
      double v5 = 0, v10 = 0;
      const int steps = 120;
      for (int s = 1; s <= steps; ++s) {
        platform.setWorldTransform(pose(s * dt));  // Bullet takes its velocity from the motion
        ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
        const double vx = mean(world.velocities(block)).x;
        if (s == 5) v5 = vx;
        if (s == 10) v10 = vx;
      }
      const glm::dvec3 v = mean(world.velocities(block)), x = mean(world.positions(block));
      if (!turning) {
        // mu g takes the block to 1 m/s in 0.2 s: steps 5-10 slip.
        const double accel = (v10 - v5) / (5 * dt);
        std::printf(
            "kinematic platform at 1 m/s: block accelerates at %.4f m/s^2 (mu g %.4f, %+.2f %%), "
            "after 2 s at %.5f m/s\n",
            accel, mu * g, 100 * (accel / (mu * g) - 1), v.x);
        EXPECT_NEAR(accel, mu * g, 0.02 * mu * g);
        EXPECT_NEAR(v.x, speed, 1e-3);
      } else {
        const double turned = std::atan2(-x.z, x.x);
        std::printf("kinematic turntable at 0.4 rad/s: block turned %.4f rad in 2 s (w t %.4f)\n",
                    turned, omega * steps * dt);
        EXPECT_NEAR(turned, omega * steps * dt, 0.05 * omega * steps * dt);
        EXPECT_NEAR(std::hypot(x.x, x.z), 0.5, 0.01);
      }
    }
    dyn.world.removeRigidBody(&platform);
  }
}

// A dynamic Bullet box (20 x 10 x 20 cm, 5 kg, friction mu) resting on a stiff deformable slab
// (friction mu: they meet mu) that lies on the world's floor (friction 1), given v0 along x,
// with Bridge::setDynamicFriction: it should stop after v0^2 / (2 mu g), the box losing the
// tangential momentum the slab gains, the floor's reported impulse taking the rest. DISABLED,
// fails: the staggered penalty contact holds the box 6.5 mm deep in the slab (its nodes'
// penalty), it ploughs the nodes its leading face meets and rocks, and it stops after -56 % to
// +1030 % of that distance (the momentum balance holds to 7e-7 N s while it stays on the slab).
// Frictionless (without setDynamicFriction) it stops too, after -58, -54, +250 and -47 %.
TEST(BulletContact, DISABLED_DynamicBoxSlidingOnASlabStopsAfterItsFrictionDistance) {
  const double g = 9.81, dt = 1.0 / 60, boxMass = 5;
  for (const double mu : {0.3, 0.6}) {
    for (const double v0 : {1.0, 2.0}) {
      Collider floor;  // y = 0
      floor.friction = 1;
      World world(WorldDef{glm::vec3(0, -float(g), 0), Backend::Cpu, nullptr, 1, {floor}});
      BodyDef def;
      def.mesh = gen::box(1.2, 0.04, 0.3, 24, 2, 6);
      def.material = Material::stableNeoHookean(1e7, 0.3, 100);
      def.friction = mu;
      const BodyId slab = world.createBody(def).value();
      test::BulletWorld dyn(btVector3(0, -float(g), 0), /*withFloor=*/false);
      btBoxShape shape(btVector3(0.1f, 0.05f, 0.1f));
      btVector3 inertia;
      shape.calculateLocalInertia(btScalar(boxMass), inertia);
      btRigidBody::btRigidBodyConstructionInfo ci(btScalar(boxMass), nullptr, &shape, inertia);
      ci.m_startWorldTransform.setOrigin(btVector3(0.2f, 0.0905f, 0.15f));
      btRigidBody box(ci);
      box.setFriction(btScalar(mu));
      box.setActivationState(DISABLE_DEACTIVATION);
      dyn.world.addRigidBody(&box);
      {
        bullet::Bridge bridge(world, dyn.world);
        ASSERT_EQ(bridge.addCollider(&box).value(), 1);
        bridge.setDynamicFriction(true);
        for (int s = 0; s < 30; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
        box.setLinearVelocity(btVector3(btScalar(v0), 0, 0));
        const double x0 = box.getCenterOfMassPosition().x();
        const auto px = [&] {
          return boxMass * box.getLinearVelocity().x() + world.stats(slab).linearMomentum.x;
        };
        const double p0 = px();
        double floorJ = 0, stopped = -1, worst = 0;
        for (int s = 0; s < 150 && stopped < 0; ++s) {
          ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
          floorJ += world.colliderImpulses()[0].x;
          // What the box and slab gained together along x is what the floor gave.
          worst = std::max(worst, std::abs(px() - p0 - floorJ));
          if (box.getLinearVelocity().x() <= 0.01 * v0) stopped = box.getCenterOfMassPosition().x();
        }
        const double expected = v0 * v0 / (2 * mu * g);
        std::printf(
            "box on slab, mu %.1f, v0 %.0f m/s: stops after %.4f m (v0^2 / (2 mu g) %.4f, "
            "%+.2f %%); worst |d(p_box + p_slab) - J_floor| %.2e N s (m v0 %.1f)\n",
            mu, v0, stopped - x0, expected, 100 * ((stopped - x0) / expected - 1), worst,
            boxMass * v0);
        ASSERT_GE(stopped, 0) << "the box did not stop";
        EXPECT_NEAR(stopped - x0, expected, 0.05 * expected);
        EXPECT_LT(worst, 1e-5 * boxMass * v0);  // single-precision Bullet
      }
      dyn.world.removeRigidBody(&box);
    }
  }
}

// A stiff block (10 cm, 1 kg, friction mu 0.5) resting on a dynamic Bullet crate (1 x 0.2 x 1
// m, 50 kg, friction mu; they meet mu) that runs on frictionless rails (Bullet's linear and
// angular factors hold it level; on a Bullet floor plane it rocked and sank 2 cm in 0.5 s
// with or without the block's friction), pushed along x at a < mu g: with
// Bridge::setDynamicFriction the crate's friction carries the block. The coupling is
// staggered, so the block follows the crate's velocity of one step before: a dt behind, and
// a dt t behind in position. Crate and block together gain exactly the push's momentum.
TEST(BulletContact, DynamicCratePushedAlongCarriesABlockByFriction) {
  const double g = 9.81, dt = 1.0 / 60, mu = 0.5, crateMass = 50;
  for (const double accel : {1.0, 3.0}) {
    World world(WorldDef{glm::vec3(0, -float(g), 0), Backend::Cpu, nullptr, 1, {}});
    BodyDef def;
    def.mesh = gen::box(0.1, 0.1, 0.1, 4, 4, 4);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
      def.mesh.positions[3 * n] -= 0.05;
      def.mesh.positions[3 * n + 1] += 0.2;
      def.mesh.positions[3 * n + 2] -= 0.05;
    }
    def.material = Material::stableNeoHookean(1e7, 0.3, 1000);
    def.friction = mu;
    const BodyId block = world.createBody(def).value();
    test::BulletWorld dyn(btVector3(0, -float(g), 0), /*withFloor=*/false);
    btBoxShape shape(btVector3(0.5f, 0.1f, 0.5f));
    btVector3 inertia;
    shape.calculateLocalInertia(btScalar(crateMass), inertia);
    btRigidBody::btRigidBodyConstructionInfo ci(btScalar(crateMass), nullptr, &shape, inertia);
    ci.m_startWorldTransform.setOrigin(btVector3(0, 0.1f, 0));
    btRigidBody crate(ci);
    crate.setFriction(btScalar(mu));
    crate.setLinearFactor(btVector3(1, 0, 1));  // on frictionless rails
    crate.setAngularFactor(0);
    crate.setActivationState(DISABLE_DEACTIVATION);
    dyn.world.addRigidBody(&crate);
    {
      bullet::Bridge bridge(world, dyn.world);
      ASSERT_EQ(bridge.addCollider(&crate).value(), 0);
      bridge.setDynamicFriction(true);
      const auto mean = [](std::span<const double> a) {
        glm::dvec3 sum(0);
        for (size_t n = 0; n < a.size() / 3; ++n)
          sum += glm::dvec3(a[3 * n], a[3 * n + 1], a[3 * n + 2]);
        return sum / double(a.size() / 3);
      };
      for (int s = 0; s < 30; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
      const double blockX0 = mean(world.positions(block)).x;
      const double crateX0 = crate.getCenterOfMassPosition().x();
      const double blockMass = world.stats(block).mass;
      const auto px = [&] {
        return crateMass * crate.getLinearVelocity().x() + world.stats(block).linearMomentum.x;
      };
      const double p0 = px(), force = (crateMass + blockMass) * accel;
      double worst = 0;
      for (int s = 1; s <= 60; ++s) {
        // Bullet clears applied forces after each of its steps.
        crate.applyCentralForce(btVector3(btScalar(force), 0, 0));
        ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
        // Friction only moves momentum between them: together they gain the push's.
        worst = std::max(worst, std::abs(px() - p0 - force * s * dt));
      }
      const double crateV = crate.getLinearVelocity().x();
      const double blockV = mean(world.velocities(block)).x;
      const double slip = (mean(world.positions(block)).x - blockX0) -
                          (crate.getCenterOfMassPosition().x() - crateX0);
      std::printf(
          "crate pushed at %.0f m/s^2: after 1 s crate %.4f m/s (a t %.4f), block %.4f m/s, "
          "slipped %.2e m; worst |d(p_crate + p_block) - F t| %.2e N s\n",
          accel, crateV, accel * 60 * dt, blockV, slip, worst);
      EXPECT_NEAR(crateV, accel * 60 * dt, 0.01 * accel * 60 * dt);
      EXPECT_NEAR(blockV, crateV - accel * dt, 0.01 * crateV);
      EXPECT_NEAR(slip, -accel * dt * 60 * dt, 0.2 * accel * dt * 60 * dt);
      EXPECT_LT(worst, 1e-5 * force * 60 * dt);  // single-precision Bullet
    }
    dyn.world.removeRigidBody(&crate);
  }
}

// Bullet's rolling and spinning friction on a ball resting on a frictionless soft block (the
// contact's reaction purely normal, so only they turn the spin), with
// Bridge::setDynamicFriction: spun about a horizontal axis (rolling friction c) or the vertical
// (spinning friction c), its spin falls at c M g / I, Bullet's bound coefficient x normal
// impulse per step, until it stops.
TEST(BulletContact, RollingAndSpinningFrictionSlowABallsSpinAtCMgOverI) {
  const double g = 9.81, dt = 1.0 / 60, ballMass = 2, radius = 0.04, c = 0.002, w0 = 10;
  for (const bool rolling : {true, false}) {
    World world(WorldDef{glm::vec3(0, -float(g), 0), Backend::Cpu, nullptr, 1, {}});
    BodyDef def = softBlock(300);
    def.material.massDamping = 2;
    def.friction = 0;
    world.createBody(def).value();
    test::BulletWorld dyn(btVector3(0, -float(g), 0), /*withFloor=*/false);
    btStaticPlaneShape floorShape(btVector3(0, 1, 0), 0);
    btRigidBody floor(0, nullptr, &floorShape);
    dyn.world.addRigidBody(&floor);
    {
      Ball ball(dyn.world, float(radius), float(ballMass), btVector3(0.1f, 0.24f, 0.1f),
                btVector3(0, 0, 0));
      (rolling ? ball.body->setRollingFriction(btScalar(c))
               : ball.body->setSpinningFriction(btScalar(c)));
      bullet::Bridge bridge(world, dyn.world);
      bridge.setDynamicFriction(true);
      ASSERT_EQ(bridge.addCollider(&floor).value(), 0);
      ASSERT_EQ(bridge.addCollider(ball.body.get()).value(), 1);
      for (int s = 0; s < 60; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
      const btVector3 axis = rolling ? btVector3(1, 0, 0) : btVector3(0, 1, 0);
      ball.body->setAngularVelocity(btScalar(w0) * axis);
      const int steps = 10;
      for (int s = 0; s < steps; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
      const double inertia = 0.4 * ballMass * radius * radius;
      const double expected = w0 - c * ballMass * g * steps * dt / inertia;
      const double w = ball.body->getAngularVelocity().dot(axis);
      const double off = (ball.body->getAngularVelocity() - btScalar(w) * axis).length();
      std::printf(
          "%s friction %.3f m: spin %.4f rad/s after %.3f s (w0 - c M g t / I %.4f), "
          "%.2e off its axis\n",
          rolling ? "rolling" : "spinning", c, w, steps * dt, expected, off);
      EXPECT_NEAR(w0 - w, w0 - expected, 0.05 * (w0 - expected));
      // The contact's moment turns the spin off its axis by 0.1-0.15 rad/s, with or without
      // these coefficients.
      EXPECT_LT(off, 0.05 * w0);
      for (int s = 0; s < 20; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
      const double after = ball.body->getAngularVelocity().dot(axis);
      std::printf("  after another %.3f s: %.2e rad/s about the axis\n", 20 * dt, after);
      EXPECT_LT(std::abs(after), 1e-3 * w0);  // stopped, not reversed
    }
    dyn.world.removeRigidBody(&floor);
  }
}

// Gravity, a Bullet floor mirrored as a static plane: the block rests on it, a ball dropped on
// the block comes to rest on it, and at rest the impulses balance the weights (statics). 3 s:
// on the floor's friction (Bullet's default 0.5) the block's base does not spread, and the
// ball rings on it for longer than on a frictionless floor (at 2 s 7e-3 m/s and its impulse
// 5 % over its weight; at 3 s 1.7e-3 m/s and 0.13 %; at 4 s 1e-4 m/s and 3e-5).
TEST(BulletContact, BallDroppedOnBlockRestingOnBulletFloorStops) {
  const double g = 9.81, dt = 1.0 / 60, ballMass = 2;  // a 4 cm steel ball
  World world(WorldDef{glm::vec3(0, -float(g), 0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = softBlock(300);
  def.material.massDamping = 2;
  const BodyId block = world.createBody(def).value();
  test::BulletWorld dyn(btVector3(0, -float(g), 0), /*withFloor=*/false);
  btStaticPlaneShape floorShape(btVector3(0, 1, 0), 0);
  btRigidBody floor(0, nullptr, &floorShape);
  dyn.world.addRigidBody(&floor);
  {
    Ball ball(dyn.world, 0.04f, float(ballMass), btVector3(0.1f, 0.4f, 0.1f), btVector3(0, 0, 0));
    bullet::Bridge bridge(world, dyn.world);
    ASSERT_EQ(bridge.addCollider(&floor).value(), 0);
    ASSERT_EQ(bridge.addCollider(ball.body.get()).value(), 1);
    for (int s = 0; s < 180; ++s) ASSERT_EQ(bridge.step(dt).flags & kStepNanContained, 0u);
    double lowest = 1e300;
    const std::span<const double> x = world.positions(block);
    for (size_t n = 0; n < x.size() / 3; ++n) lowest = std::min(lowest, x[3 * n + 1]);
    const double ballY = ball.body->getCenterOfMassPosition().y();
    const double ballV = ball.body->getLinearVelocity().length();
    const double blockMass = world.stats(block).mass;
    const glm::dvec3 floorJ = world.colliderImpulses()[0], ballJ = world.colliderImpulses()[1];
    std::printf(
        "after 3 s: block lowest y %.4f, ball centre y %.4f, speed %.2e m/s; impulses "
        "per step: ball %.5f (M g dt %.5f), floor %.5f ((M + m) g dt %.5f) N s\n",
        lowest, ballY, ballV, -ballJ.y, ballMass * g * dt, floorJ.y,
        (ballMass + blockMass) * g * dt);
    EXPECT_GT(lowest, -0.005);  // the floor holds the block
    EXPECT_GT(ballY, 0.15);     // the block holds the ball (its top is at 0.2)
    EXPECT_LT(ballV, 0.01);
    EXPECT_NEAR(-ballJ.y, ballMass * g * dt, 0.01 * ballMass * g * dt);
    EXPECT_NEAR(floorJ.y, (ballMass + blockMass) * g * dt, 0.01 * (ballMass + blockMass) * g * dt);
    // Unregistering the floor: the ball moves down to index 0.
    ASSERT_TRUE(bridge.removeCollider(&floor).ok());
    EXPECT_FALSE(bridge.removeCollider(&floor).ok());
    ASSERT_EQ(world.colliders().size(), 1u);
    EXPECT_EQ(world.colliders()[0].kind, Collider::Kind::Sphere);
    dyn.world.removeRigidBody(&floor);
  }
}

}  // namespace
}  // namespace gf
