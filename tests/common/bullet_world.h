// A Bullet dynamics world for the integration tests, with its collaborators declared in the
// order Bullet needs them torn down, and an optional static floor plane at y = 0.
#pragma once

#include <btBulletDynamicsCommon.h>

#include <memory>

namespace gf::test {

struct BulletWorld {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
  btStaticPlaneShape floorShape{btVector3(0, 1, 0), 0};
  std::unique_ptr<btRigidBody> floor;  ///< Null without a floor.

  explicit BulletWorld(btVector3 gravity, bool withFloor = true) {
    world.setGravity(gravity);
    if (!withFloor) return;
    floor = std::make_unique<btRigidBody>(0, nullptr, &floorShape);
    world.addRigidBody(floor.get());
  }
  ~BulletWorld() {
    if (floor) world.removeRigidBody(floor.get());
  }
  BulletWorld(const BulletWorld&) = delete;
  BulletWorld& operator=(const BulletWorld&) = delete;
};

}  // namespace gf::test
