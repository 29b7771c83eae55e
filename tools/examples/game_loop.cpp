// The smallest game loop with graphfrac and Bullet: a breakable slab held at both ends, a
// Bullet floor and ball, a fixed-timestep loop with an accumulator, events printed, clean
// shut-down. Run by ctest (game_loop); exits 1 unless every broken piece ends at rest on the
// Bullet floor or on another piece lying there.
//
// The ball and the floor are registered with the bridge as colliders (two-way contact): the ball
// hits the slab, is slowed by it, and the slab breaks where it hits; the pieces that break off
// are handed to Bullet and land on the floor.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <memory>
#include <utility>
#include <vector>

int main() {
  // Bullet: floor at y = 0 and a ball dropped onto the middle of the slab.
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld dynamics(&dispatcher, &broadphase, &solver, &config);
  dynamics.setGravity(btVector3(0, -9.81f, 0));
  btStaticPlaneShape floorShape(btVector3(0, 1, 0), 0);
  btRigidBody floor(0, nullptr, &floorShape);
  dynamics.addRigidBody(&floor);
  const float radius = 0.04f, ballMass = 1.0f;
  btSphereShape ballShape(radius);
  btVector3 ballInertia;
  ballShape.calculateLocalInertia(ballMass, ballInertia);
  btRigidBody::btRigidBodyConstructionInfo ballInfo(ballMass, nullptr, &ballShape, ballInertia);
  ballInfo.m_startWorldTransform.setOrigin(btVector3(0.2f, 1.0f, 0.1f));
  btRigidBody ball(ballInfo);
  dynamics.addRigidBody(&ball);

  // graphfrac: a slab 0.4 x 0.04 x 0.2 m at y = 0.3, gripped at both ends, breakable.
  gf::World world(gf::WorldDef{glm::vec3(0, -9.81f, 0), gf::Backend::Cpu, nullptr, 1, {}});
  gf::BodyDef def;
  def.mesh = gf::gen::box(0.4, 0.04, 0.2, 16, 2, 8);
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += 0.3;
  def.material = gf::Material::stableNeoHookean(5e6, 0.3, 1000);
  def.material.massDamping = 1;
  def.fracture.enabled = true;
  def.fracture.strength = 1e4;  // weak: a 1 kg ball at 3 m/s breaks through
  gf::Grip ends;
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n) {
    const double x = def.mesh.positions[3 * n];
    if (x < 1e-9 || x > 0.4 - 1e-9) ends.nodes.push_back(int32_t(n));
  }
  def.grips = {ends};
  const gf::Result<gf::BodyId> slab = world.createBody(def);
  if (!slab) {
    std::fprintf(stderr, "createBody: %s\n", slab.error().message.c_str());
    return 1;
  }
  gf::bullet::Bridge bridge(world, dynamics);
  for (btRigidBody* b : {&floor, &ball})
    if (auto r = bridge.addCollider(b); !r) {
      std::fprintf(stderr, "addCollider: %s\n", r.error().message.c_str());
      return 1;
    }
  if (auto r = bridge.setPolicy(slab.value(), gf::bullet::HandoffPolicy::EveryFragment); !r) {
    std::fprintf(stderr, "setPolicy: %s\n", r.error().message.c_str());
    return 1;
  }
  (void)world.surface(slab.value());  // a renderer would copy this every frame

  // Fixed-timestep loop: frames of varying length feed an accumulator drained in fixed steps.
  // 120 Hz: contact acts on the slab's nodes, so the ball (3 m/s) must move well under the
  // slab's thickness (4 cm) per step or it would be past the nodes before they push back.
  const double step = 1.0 / 120, duration = 2.5;
  double accumulator = 0, clock = 0;
  double peakImpulse = 0;
  int frame = 0;
  while (clock < duration) {
    const double frameTime = (frame++ % 3 == 0) ? 1.0 / 40 : 1.0 / 75;  // a jittery renderer
    clock += frameTime;
    accumulator += frameTime;
    while (accumulator >= step) {
      accumulator -= step;
      const gf::StepStatus st = bridge.step(step);
      const double hit = glm::length(world.colliderImpulses()[1]);  // the ball's collider
      if (hit > peakImpulse) {
        peakImpulse = hit;
        std::printf("t=%.3f ball and slab exchange %.3f N s; ball v = %.2f m/s\n", world.time(),
                    hit, double(ball.getLinearVelocity().y()));
      }
      if (st.flags != 0)
        std::printf("t=%.3f step flags %u: %s\n", world.time(), st.flags, st.message.c_str());
      if (!world.fractureEvents().empty())
        std::printf("t=%.3f %zu edges broke\n", world.time(), world.fractureEvents().size());
      for (const gf::FragmentEvent& e : world.fragmentEvents())
        std::printf("t=%.3f fragment %d split from %d: %d nodes, %.4f kg\n", world.time(),
                    e.fragment, e.parent, e.nodeCount, e.mass);
      for (const gf::HandoffEvent& e : world.handoffEvents())
        std::printf("t=%.3f fragment %d handed to Bullet: %.4f kg, v = (%.2f, %.2f, %.2f)\n",
                    world.time(), e.fragment, e.mass, e.velocity.x, e.velocity.y, e.velocity.z);
    }
    // Rendering would interpolate with accumulator / step and copy world.surface(slab).
  }

  // The handed-off pieces must rest on the Bullet floor, or on a piece that does (loose nodes
  // land on the big piece's hull); Bullet's contact manifolds say what touches what.
  std::vector<std::pair<const btCollisionObject*, const btCollisionObject*>> touching;
  for (int m = 0; m < dispatcher.getNumManifolds(); ++m) {
    const btPersistentManifold* c = dispatcher.getManifoldByIndexInternal(m);
    if (c->getNumContacts() > 0) touching.emplace_back(c->getBody0(), c->getBody1());
  }
  std::vector<const btCollisionObject*> grounded = {&floor};
  for (size_t added = 1; added > 0;) {  // grow the set of pieces carried by the floor
    added = 0;
    for (const auto& [a, b] : touching) {
      const bool ia = std::find(grounded.begin(), grounded.end(), a) != grounded.end();
      const bool ib = std::find(grounded.begin(), grounded.end(), b) != grounded.end();
      if (ia != ib) {
        grounded.push_back(ia ? b : a);
        ++added;
      }
    }
  }
  int ok = bridge.fragments().empty() ? 1 : 0;
  const std::span<const int32_t> fragmentOf = world.nodeFragments(slab.value());
  const std::span<const double> x = world.positions(slab.value());
  for (const gf::bullet::RigidFragment& f : bridge.fragments()) {
    double lowest = 1e300;
    for (size_t n = 0; n < fragmentOf.size(); ++n)
      if (fragmentOf[n] == f.fragment) lowest = std::min(lowest, x[3 * n + 1]);
    const double speed = double(f.rigidBody->getLinearVelocity().length());
    const bool carried = std::find(grounded.begin(), grounded.end(), f.rigidBody) != grounded.end();
    std::printf("fragment %d: lowest node y = %.4f m, speed %.3f m/s, %s\n", f.fragment, lowest,
                speed, carried ? "on the floor or a piece" : "touching nothing that rests");
    if (!(lowest > -0.005 && lowest < 0.3 && speed < 0.1 && carried)) ok = 1;
  }
  const btVector3 b = ball.getCenterOfMassPosition();
  std::printf("ball at (%.3f, %.3f, %.3f), peak contact impulse %.3f N s\n", double(b.x()),
              double(b.y()), double(b.z()), peakImpulse);
  std::printf("%zu fragments in Bullet after %.2f s: %s\n", bridge.fragments().size(), world.time(),
              ok == 0 ? "ok" : "FAILED");
  dynamics.removeRigidBody(&ball);
  dynamics.removeRigidBody(&floor);
  return ok;  // the bridge removes its bodies before `dynamics` goes
}
