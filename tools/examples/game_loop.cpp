// The smallest game loop with graphfrac and Bullet: a breakable slab held at both ends, a
// Bullet floor and ball, a fixed-timestep loop with an accumulator, events printed, clean
// shut-down. Run by ctest (game_loop); exits 1 if the broken piece did not end up resting on
// the Bullet floor.
//
// Bullet bodies do not touch FEM bodies yet (no two-way contact in this slice), so when the
// ball reaches the slab the game itself breaks it: a cut on each side of the ball and the
// ball's momentum as an impulse. The piece cut out is handed to Bullet and lands next to it.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

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
  def.fracture.strength = 1e7;
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
  if (auto r = bridge.setPolicy(slab.value(), gf::bullet::HandoffPolicy::EveryFragment); !r) {
    std::fprintf(stderr, "setPolicy: %s\n", r.error().message.c_str());
    return 1;
  }
  (void)world.surface(slab.value());  // a renderer would copy this every frame

  // Fixed-timestep loop: frames of varying length feed an accumulator drained in 1/60 s steps.
  const double step = 1.0 / 60, duration = 2.5;
  double accumulator = 0, clock = 0;
  bool smashed = false;
  int frame = 0;
  while (clock < duration) {
    const double frameTime = (frame++ % 3 == 0) ? 1.0 / 40 : 1.0 / 75;  // a jittery renderer
    clock += frameTime;
    accumulator += frameTime;
    while (accumulator >= step) {
      accumulator -= step;
      const btVector3 b = ball.getCenterOfMassPosition();
      if (!smashed && b.y() - radius < 0.34f) {
        // The game's stand-in for ball-slab contact: cut out the piece under the ball.
        smashed = true;
        for (float cx : {b.x() - 0.06f, b.x() + 0.06f}) {
          gf::Blade blade;
          blade.vertices = {{cx, 0, -1}, {cx, 1, -1}, {cx, 1, 1}, {cx, 0, 1}};
          blade.triangles = {0, 1, 2, 0, 2, 3};
          if (auto r = world.cut(slab.value(), blade); !r)
            std::fprintf(stderr, "cut: %s\n", r.error().message.c_str());
        }
        const btVector3 p = ballMass * ball.getLinearVelocity();
        (void)world.applyImpulse(slab.value(), glm::vec3(b.x(), 0.32f, b.z()),
                                 glm::vec3(p.x(), p.y(), p.z()));
        std::printf("t=%.3f ball reaches the slab: cut and impulse %.2f N s\n", world.time(),
                    double(p.length()));
      }
      const gf::StepStatus st = bridge.step(step);
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

  // The handed-off pieces must rest on the Bullet floor.
  int ok = bridge.fragments().empty() ? 1 : 0;
  const std::span<const int32_t> fragmentOf = world.nodeFragments(slab.value());
  const std::span<const double> x = world.positions(slab.value());
  for (const gf::bullet::RigidFragment& f : bridge.fragments()) {
    double lowest = 1e300;
    for (size_t n = 0; n < fragmentOf.size(); ++n)
      if (fragmentOf[n] == f.fragment) lowest = std::min(lowest, x[3 * n + 1]);
    const double speed = double(f.rigidBody->getLinearVelocity().length());
    std::printf("fragment %d: lowest node y = %.4f m, speed %.3f m/s\n", f.fragment, lowest, speed);
    if (!(lowest > -0.005 && lowest < 0.05 && speed < 0.1)) ok = 1;
  }
  std::printf("%zu fragments in Bullet after %.2f s: %s\n", bridge.fragments().size(), world.time(),
              ok == 0 ? "ok" : "FAILED");
  dynamics.removeRigidBody(&ball);
  dynamics.removeRigidBody(&floor);
  return ok;  // the bridge removes its bodies before `dynamics` goes
}
