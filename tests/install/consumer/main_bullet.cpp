// The smallest engine with the Bullet bridge, from an installed graphfrac: a soft box dropped on
// a Bullet floor that is registered as a two-way collider. After 1.5 s it rests on the floor,
// and the floor carries its weight: the contact impulse per step is m g dt.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>
#include <graphfrac/mesh.h>
#include <graphfrac/world.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

int main() {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher(&config);
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld dynamics(&dispatcher, &broadphase, &solver, &config);
  dynamics.setGravity(btVector3(0, -9.81f, 0));
  btStaticPlaneShape floorShape(btVector3(0, 1, 0), 0);
  btRigidBody floor(0, nullptr, &floorShape);
  dynamics.addRigidBody(&floor);

  constexpr double kDensity = 500, kSize = 0.2, kDt = 1.0 / 120;
  gf::World world(gf::WorldDef{});
  gf::BodyDef def;
  def.mesh = gf::gen::box(kSize, kSize, kSize, 3, 3, 3);
  for (size_t i = 1; i < def.mesh.positions.size(); i += 3) def.mesh.positions[i] += 0.1;
  def.material = gf::Material::stableNeoHookean(1e5, 0.3, kDensity);
  def.material.massDamping = 2;
  const gf::Result<gf::BodyId> box = world.createBody(def);
  if (!box) {
    std::printf("createBody: %s\n", box.error().message.c_str());
    return 1;
  }
  {
    gf::bullet::Bridge bridge(world, dynamics);
    if (gf::Result<int32_t> r = bridge.addCollider(&floor); !r) {
      std::printf("addCollider: %s\n", r.error().message.c_str());
      return 1;
    }
    for (int i = 0; i < 180; ++i)
      if (gf::StepStatus s = bridge.step(kDt); !s.ok()) {
        std::printf("step %d: %s\n", i, s.message.c_str());
        return 1;
      }
  }
  double lowest = 1e300;
  const std::span<const double> x = world.positions(box.value());
  for (size_t n = 1; n < x.size(); n += 3) lowest = std::min(lowest, x[n]);
  const double weightImpulse = kDensity * kSize * kSize * kSize * 9.81 * kDt;
  const double floorImpulse = world.colliderImpulses()[0].y;
  std::printf("lowest node y = %.4f m, floor impulse %.5f N s per step (weight x dt %.5f)\n",
              lowest, floorImpulse, weightImpulse);
  const bool ok = std::abs(lowest) < 0.01 && std::abs(floorImpulse / weightImpulse - 1) < 0.02;
  std::printf("graphfrac bullet consumer: %s\n", ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
