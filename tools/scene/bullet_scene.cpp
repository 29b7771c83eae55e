#include "scene/bullet_scene.h"

#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>

#include <chrono>
#include <glm/gtc/type_ptr.hpp>
#include <string>

#include "cli/progress.h"

namespace gf::scene {
namespace {

using Clock = std::chrono::steady_clock;
using cli::msSince;

btVector3 bt(const glm::dvec3& v) { return btVector3(btScalar(v.x), btScalar(v.y), btScalar(v.z)); }

bullet::HandoffPolicy policyOf(SceneHandoff::Policy p) {
  switch (p) {
    case SceneHandoff::Policy::Every:
      return bullet::HandoffPolicy::EveryFragment;
    case SceneHandoff::Policy::BelowVolume:
      return bullet::HandoffPolicy::BelowVolume;
    case SceneHandoff::Policy::Never:
      break;
  }
  return bullet::HandoffPolicy::Never;
}

}  // namespace

/// Bullet's collaborators in the order it needs them torn down (declaration order reversed),
/// and the scene's rigid bodies, taken out of the world before anything else goes.
struct BulletScene::BulletObjects {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld dynamics{&dispatcher, &broadphase, &solver, &config};
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btRigidBody>> bodies;  ///< Parallel to Scene::rigidBodies.

  ~BulletObjects() {
    for (const auto& b : bodies) dynamics.removeRigidBody(b.get());
  }
};

Result<std::unique_ptr<BulletScene>> BulletScene::create(const Scene& scene, int threads) {
  std::unique_ptr<BulletScene> s(new BulletScene());
  s->m_dt = scene.dt;
  s->m_substeps = std::max(scene.world.substeps, 1);
  s->m_cuts = scene.cuts;
  const int n = threads < 0 ? scene.threads : threads;
  if (n != 1) s->m_jobs = std::make_unique<ThreadPoolJobSystem>(n);
  WorldDef def = scene.world;
  def.jobs = s->m_jobs.get();
  def.substeps = 1;  // taken at the bridge (see the header)
  // The tool's collider goes in before the bridge counts the world's own colliders.
  s->m_strokes = StrokePlayer(scene, def);
  s->m_world = std::make_unique<World>(def);
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneBody& b = scene.bodies[i];
    Result<BodyId> id = addBody(*s->m_world, b);
    if (!id) {
      return fail(scene.source, ": bodies[", std::to_string(i), "] (\"", b.name,
                  "\"): ", id.error().message);
    }
    s->m_bodies.push_back(id.value());
  }

  s->m_bullet = std::make_unique<BulletObjects>();
  BulletObjects& bo = *s->m_bullet;
  const glm::vec3 g = scene.world.gravity;
  bo.dynamics.setGravity(btVector3(g.x, g.y, g.z));
  s->m_bridge = std::make_unique<bullet::Bridge>(*s->m_world, bo.dynamics);
  for (size_t i = 0; i < scene.rigidBodies.size(); ++i) {
    const SceneRigidBody& r = scene.rigidBodies[i];
    std::unique_ptr<btCollisionShape> shape;
    switch (r.shape) {
      case SceneRigidBody::Shape::Sphere:
        shape = std::make_unique<btSphereShape>(btScalar(r.radius));
        break;
      case SceneRigidBody::Shape::Box:
        shape = std::make_unique<btBoxShape>(bt(r.halfExtents));
        break;
      case SceneRigidBody::Shape::Plane:
        shape = std::make_unique<btStaticPlaneShape>(bt(r.normal), btScalar(r.offset));
        break;
      case SceneRigidBody::Shape::Capsule:  // Bullet's height is the segment's length
        shape = std::make_unique<btCapsuleShape>(btScalar(r.radius), btScalar(2 * r.halfLength));
        break;
    }
    btVector3 inertia(0, 0, 0);
    if (r.mass > 0) shape->calculateLocalInertia(btScalar(r.mass), inertia);
    btRigidBody::btRigidBodyConstructionInfo ci(btScalar(r.mass), nullptr, shape.get(), inertia);
    const glm::dquat& q = r.orientation;
    ci.m_startWorldTransform.setRotation(
        btQuaternion(btScalar(q.x), btScalar(q.y), btScalar(q.z), btScalar(q.w)));
    ci.m_startWorldTransform.setOrigin(bt(r.position));
    ci.m_friction = btScalar(r.friction);
    ci.m_rollingFriction = btScalar(r.rollingFriction);
    ci.m_restitution = btScalar(r.restitution);
    auto body = std::make_unique<btRigidBody>(ci);
    if (r.mass > 0) {
      body->setLinearVelocity(bt(r.velocity));
      body->setAngularVelocity(bt(r.angularVelocity));
    }
    bo.dynamics.addRigidBody(body.get());
    bo.shapes.push_back(std::move(shape));
    bo.bodies.push_back(std::move(body));
    if (r.touchesBodies) {
      if (Result<int32_t> c = s->m_bridge->addCollider(bo.bodies.back().get()); !c) {
        return fail(scene.source, ": rigid_bodies[", std::to_string(i), "] (\"", r.name,
                    "\"): ", c.error().message);
      }
    }
  }
  for (size_t i = 0; i < scene.bodies.size(); ++i) {
    const SceneHandoff& h = scene.bodies[i].handoff;
    if (h.policy == SceneHandoff::Policy::Never) continue;
    if (Result<void> r = s->m_bridge->setPolicy(s->m_bodies[i], policyOf(h.policy), h.maxVolume);
        !r) {
      return fail(scene.source, ": bodies[", std::to_string(i), "] (\"", scene.bodies[i].name,
                  "\").handoff: ", r.error().message);
    }
  }
  return s;
}

BulletScene::~BulletScene() = default;

StepStatus BulletScene::step() {
  const auto t0 = Clock::now();
  m_timings = {};
  m_fractureEvents.clear();
  m_fragmentEvents.clear();
  m_handoffEvents.clear();
  ++m_frame;
  // Cuts break their edges at the start of the next World step, so they go in before it.
  for (; m_nextCut < m_cuts.size() && m_cuts[m_nextCut].frame <= m_frame; ++m_nextCut) {
    const SceneCut& c = m_cuts[m_nextCut];
    if (Result<void> r = m_world->cut(m_bodies[c.bodyIndex], c.blade); !r) {
      StepStatus st;
      st.flags = kStepInvalidInput;
      st.message = "cut of body \"" + c.body + "\" at frame " + std::to_string(c.frame) + ": " +
                   r.error().message;
      return st;
    }
  }
  StepStatus st;
  const double h = m_dt / m_substeps;
  for (int k = 0; k < m_substeps; ++k) {
    if (Result<void> r = m_strokes.apply(*m_world, m_bodies, m_frame, k, m_substeps); !r) {
      st.flags |= kStepInvalidInput;
      st.message = r.error().message;
      break;
    }
    const StepStatus sub = m_bridge->step(h);
    const StepTimings& t = m_world->timings();
    m_timings.world.fractureMs += t.fractureMs;
    m_timings.world.surfaceMs += t.surfaceMs;
    m_timings.world.elementsMs += t.elementsMs;
    m_timings.world.assemblyMs += t.assemblyMs;
    m_timings.world.solveMs += t.solveMs;
    m_timings.world.contactMs += t.contactMs;
    m_timings.world.contactPairs += t.contactPairs;
    m_timings.world.totalMs += t.totalMs;
    const World& w = *m_world;
    m_fractureEvents.insert(m_fractureEvents.end(), w.fractureEvents().begin(),
                            w.fractureEvents().end());
    m_fragmentEvents.insert(m_fragmentEvents.end(), w.fragmentEvents().begin(),
                            w.fragmentEvents().end());
    m_handoffEvents.insert(m_handoffEvents.end(), w.handoffEvents().begin(),
                           w.handoffEvents().end());
    st.flags |= sub.flags;
    st.newtonIterations += sub.newtonIterations;
    st.linearIterations += sub.linearIterations;
    st.residual = std::max(st.residual, sub.residual);
    if (st.message.empty()) st.message = sub.message;
    if (sub.has(kStepInvalidInput)) break;
  }
  m_timings.totalMs = msSince(t0);
  m_timings.bulletMs = std::max(0.0, m_timings.totalMs - m_timings.world.totalMs);
  return st;
}

glm::mat4 BulletScene::rigidTransform(size_t i) const {
  const btRigidBody& b = *m_bullet->bodies[i];
  if (b.getCollisionShape()->getShapeType() == STATIC_PLANE_PROXYTYPE) return glm::mat4(1.0f);
  btScalar m[16];
  b.getWorldTransform().getOpenGLMatrix(m);  // column-major, as glm
  return glm::make_mat4(m);
}

size_t BulletScene::rigidBodyCount() const { return m_bullet->bodies.size(); }

size_t BulletScene::handedOff() const { return m_bridge->fragments().size(); }

btDiscreteDynamicsWorld& BulletScene::dynamics() { return m_bullet->dynamics; }

}  // namespace gf::scene
