#include "graphfrac/bullet/bridge.h"

#include <btBulletDynamicsCommon.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>

// integration/CMakeLists.txt links the single-precision libraries; a header that disagrees
// would give every Bullet object another layout than the library's.
static_assert(sizeof(btScalar) == sizeof(float),
              "graphfrac_bullet is built against single-precision Bullet: "
              "BT_USE_DOUBLE_PRECISION must not be defined");

namespace gf::bullet {

namespace {
btVector3 toBt(glm::dvec3 v) { return {btScalar(v.x), btScalar(v.y), btScalar(v.z)}; }
glm::dvec3 toGlm(const btVector3& v) { return {v.x(), v.y(), v.z()}; }
btMatrix3x3 toBt(const glm::dmat3& m) {                             // glm is column-major
  return {btScalar(m[0][0]), btScalar(m[1][0]), btScalar(m[2][0]),  //
          btScalar(m[0][1]), btScalar(m[1][1]), btScalar(m[2][1]),  //
          btScalar(m[0][2]), btScalar(m[1][2]), btScalar(m[2][2])};
}
glm::dmat3 toGlm(const btMatrix3x3& m) {
  glm::dmat3 g;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) g[j][i] = m[i][j];
  return g;
}

// Collision margin of a fragment's hull: Bullet's default 4 cm would swamp centimetre pieces.
constexpr double kMarginFraction = 0.05, kMinMargin = 1e-4, kMaxMargin = 0.02;
}  // namespace

struct Bridge::Entry {
  std::unique_ptr<btConvexHullShape> shape;
  std::unique_ptr<btRigidBody> body;
  glm::dmat3 principal{1.0};  // principal axes in rest coordinates (columns), det +1
  glm::dvec3 restCentre{0};
};

Bridge::Bridge(World& world, btDiscreteDynamicsWorld& dynamics)
    : m_world(world), m_dynamics(dynamics), m_worldColliders(world.colliders().size()) {
  // A piece is born where the FEM body was: sunk into the floor or a ball as deep as the FEM
  // contact let it, inside its hull margin, overlapping its neighbours' margins. Bullet resolves
  // an overlap shallower than m_splitImpulsePenetrationThreshold (default 4 cm) by Baumgarte:
  // a velocity of erp * depth / h that the piece keeps once the overlap is gone, so it flies
  // off faster the smaller the step (the demo's shattered bunny: pieces 2.5 m away at 16
  // substeps, 18 m at 64).
  // The split impulse pushes bodies apart by position only, at any depth.
  btContactSolverInfo& solver = dynamics.getSolverInfo();
  solver.m_splitImpulse = 1;
  solver.m_splitImpulsePenetrationThreshold = BT_LARGE_FLOAT;
}

Bridge::~Bridge() {
  for (const auto& e : m_entries) m_dynamics.removeRigidBody(e->body.get());
}

Result<void> Bridge::setPolicy(BodyId body, HandoffPolicy policy, double maxVolume) {
  if (!m_world.isValid(body)) return fail("Bridge::setPolicy: stale or null BodyId");
  // A body in CutMode::Xfem has no edges but has pieces (fragmentInfo answers for it).
  if (m_world.fractureStats(body).edgeCount == 0 && !m_world.fragmentInfo(body, 0))
    return fail("Bridge::setPolicy: the body was created without fracture (BodyDef.fracture)");
  if (policy == HandoffPolicy::BelowVolume && !(std::isfinite(maxVolume) && maxVolume > 0))
    return fail("Bridge::setPolicy: maxVolume must be positive and finite for BelowVolume");
  auto it = std::lower_bound(m_policies.begin(), m_policies.end(), body.index,
                             [](const Policy& p, uint32_t i) { return p.body.index < i; });
  if (it == m_policies.end() || !(it->body == body)) {
    if (it != m_policies.end() && it->body.index == body.index) it = m_policies.erase(it);
    it = m_policies.insert(it, Policy{body});
  }
  it->policy = policy;
  it->maxVolume = maxVolume;
  it->seenFragments = 1;  // rescan at the next hand-off
  return {};
}

StepStatus Bridge::step(double dt) {
  mirrorColliders();
  StepStatus st = m_world.step(dt);
  if (st.has(kStepInvalidInput)) return st;
  applyContactImpulses();
  handOffNewFragments();
  m_dynamics.stepSimulation(btScalar(dt), 0);
  syncFromDynamics();
  return st;
}

Result<int32_t> Bridge::addCollider(btRigidBody* body) {
  if (!body) return fail("Bridge::addCollider: body is null");
  if (std::find(m_colliders.begin(), m_colliders.end(), body) != m_colliders.end())
    return fail("Bridge::addCollider: body is already registered");
  const int type = body->getCollisionShape()->getShapeType();
  if (type == STATIC_PLANE_PROXYTYPE && !body->isStaticObject())
    return fail("Bridge::addCollider: a btStaticPlaneShape must belong to a static body");
  if (type != SPHERE_SHAPE_PROXYTYPE && type != BOX_SHAPE_PROXYTYPE &&
      type != CAPSULE_SHAPE_PROXYTYPE && type != STATIC_PLANE_PROXYTYPE)
    return fail("Bridge::addCollider: shape type ", std::to_string(type),
                " is not supported (btSphereShape, btBoxShape, btCapsuleShape, "
                "btStaticPlaneShape)");
  m_colliders.push_back(body);
  mirrorColliders();
  return int32_t(m_worldColliders + m_colliders.size() - 1);
}

Result<void> Bridge::removeCollider(btRigidBody* body) {
  const auto it = std::find(m_colliders.begin(), m_colliders.end(), body);
  if (it == m_colliders.end()) return fail("Bridge::removeCollider: body is not registered");
  m_colliders.erase(it);
  if (!m_colliders.empty()) {
    mirrorColliders();
  } else {  // mirrorColliders does nothing then: keep only the world's own colliders
    const std::span<const Collider> current = m_world.colliders();
    (void)m_world.setColliders(std::vector<Collider>(
        current.begin(), current.begin() + std::min(current.size(), m_worldColliders)));
  }
  return {};
}

void Bridge::mirrorColliders() {
  if (m_colliders.empty()) return;
  const std::span<const Collider> current = m_world.colliders();
  std::vector<Collider> all(current.begin(),
                            current.begin() + std::min(current.size(), m_worldColliders));
  for (const btRigidBody* b : m_colliders) {
    const btCollisionShape* shape = b->getCollisionShape();
    const btTransform& T = b->getCenterOfMassTransform();
    Collider c;
    c.point = glm::vec3(toGlm(T.getOrigin()));
    // A static or kinematic body's friction is met with sqrt(friction * BodyDef::friction), a
    // kinematic one's surface moving with its velocity and spin (a platform or turntable the
    // game drives carries what rests on it). A dynamic one is frictionless unless
    // setDynamicFriction: the exchange is explicit (the body moves at its old velocity during
    // the FEM step), and a ball resting in a soft block's dimple chatters, its velocity and
    // spin flipping every step (0.024 m/s at 3 s), the reaction overshooting its sliding.
    // (A kinematic body made from a massless one keeps Bullet's static flag too.)
    if (b->isStaticOrKinematicObject() || m_dynamicFriction) c.friction = b->getFriction();
    if (b->isKinematicObject() || !b->isStaticObject()) {
      c.velocity = glm::vec3(toGlm(b->getLinearVelocity()));
      c.angularVelocity = glm::vec3(toGlm(b->getAngularVelocity()));
    }
    switch (shape->getShapeType()) {
      case SPHERE_SHAPE_PROXYTYPE:
        c.kind = Collider::Kind::Sphere;
        c.radius = static_cast<const btSphereShape*>(shape)->getRadius();
        break;
      case BOX_SHAPE_PROXYTYPE: {
        c.kind = Collider::Kind::Box;
        c.halfExtents =
            glm::vec3(toGlm(static_cast<const btBoxShape*>(shape)->getHalfExtentsWithMargin()));
        const btQuaternion q = T.getRotation();
        c.rotation = glm::quat(float(q.w()), float(q.x()), float(q.y()), float(q.z()));
        break;
      }
      case CAPSULE_SHAPE_PROXYTYPE: {
        // btCapsuleShapeX and Z share the proxy type; the up axis says which local axis the
        // segment runs along, and a turn onto local y makes it ours.
        const auto* capsule = static_cast<const btCapsuleShape*>(shape);
        c.kind = Collider::Kind::Capsule;
        c.radius = float(capsule->getRadius());
        c.halfLength = float(capsule->getHalfHeight());
        btQuaternion q = T.getRotation();
        const int up = capsule->getUpAxis();
        if (up == 0) q *= btQuaternion(btVector3(0, 0, 1), btScalar(-SIMD_HALF_PI));  // y to x
        if (up == 2) q *= btQuaternion(btVector3(1, 0, 0), btScalar(SIMD_HALF_PI));   // y to z
        c.rotation = glm::quat(float(q.w()), float(q.x()), float(q.y()), float(q.z()));
        break;
      }
      default: {  // STATIC_PLANE_PROXYTYPE (addCollider admits nothing else)
        const auto* plane = static_cast<const btStaticPlaneShape*>(shape);
        const btVector3 n = T.getBasis() * plane->getPlaneNormal();
        c.kind = Collider::Kind::Plane;
        c.normal = glm::vec3(toGlm(n));
        c.point = glm::vec3(toGlm(T * (plane->getPlaneNormal() * plane->getPlaneConstant())));
      }
    }
    all.push_back(c);
  }
  // Cannot fail: Bullet's shapes and poses are valid colliders.
  (void)m_world.setColliders(all);
}

void Bridge::applyContactImpulses() {
  const std::span<const glm::dvec3> J = m_world.colliderImpulses();
  const std::span<const glm::dvec3> L = m_world.colliderAngularImpulses();
  for (size_t i = 0; i < m_colliders.size(); ++i) {
    btRigidBody* b = m_colliders[i];
    const size_t c = m_worldColliders + i;
    if (c >= J.size() || b->isStaticOrKinematicObject()) continue;
    if (J[c] == glm::dvec3(0) && L[c] == glm::dvec3(0)) continue;
    b->activate(true);
    // The impulse includes the friction's, and its moment about the centre of mass the
    // friction's torque: the body loses exactly the tangential momentum the nodes gain.
    b->applyCentralImpulse(toBt(-J[c]));
    b->applyTorqueImpulse(toBt(-L[c]));
    if (m_dynamicFriction) resistRolling(*b, -J[c]);
  }
}

void Bridge::resistRolling(btRigidBody& b, glm::dvec3 reaction) {
  // Bullet's meaning of the coefficients (btSequentialImpulseConstraintSolver's rolling
  // friction rows): at a contact whose normal impulse is N, an angular impulse about the
  // tangent axes of at most rollingFriction * N [m * N s], and about the normal of at most
  // spinningFriction * N, drives the spin relative to the other body towards zero without
  // reversing it. A ball's penalty forces are radial and give it no such torque. The FEM
  // surface's own spin is not known here: the spin resisted is the body's. N is the contact
  // reaction's magnitude (its friction part included, at most sqrt(1 + mu^2) times the normal
  // one) and its direction the normal, as for one contact patch. Bullet's further clamp of the
  // bound to the coefficient itself (a length compared with an angular impulse) is not mirrored.
  const double rolling = b.getRollingFriction(), spinning = b.getSpinningFriction();
  const double N = glm::length(reaction);
  if ((rolling <= 0 && spinning <= 0) || !(N > 0)) return;
  const btMatrix3x3 invI = b.getInvInertiaTensorWorld();
  if (!(std::abs(double(invI.determinant())) > 0)) return;  // locked axes: leave them
  const glm::dmat3 I = glm::inverse(toGlm(invI));
  const glm::dvec3 n = reaction / N;
  const glm::dvec3 w = toGlm(b.getAngularVelocity());
  const glm::dvec3 spin = glm::dot(w, n) * n;
  const std::pair<glm::dvec3, double> parts[] = {{w - spin, rolling}, {spin, spinning}};
  for (const auto& [part, coefficient] : parts) {
    if (coefficient <= 0) continue;
    const glm::dvec3 stop = I * part;  // the angular impulse that ends this part of the spin
    const double length = glm::length(stop);
    if (length > 0) b.applyTorqueImpulse(toBt(-stop * std::min(1.0, coefficient * N / length)));
  }
}

int Bridge::handOffNewFragments() {
  int handed = 0;
  for (Policy& p : m_policies) {
    if (p.policy == HandoffPolicy::Never || !m_world.isValid(p.body)) continue;
    const int32_t count = m_world.fractureStats(p.body).fragments;
    if (count < 2 || count == p.seenFragments) continue;
    p.seenFragments = count;
    m_nodeCount.assign(size_t(count), 0);
    for (int32_t f : m_world.nodeFragments(p.body)) ++m_nodeCount[size_t(f)];
    m_candidates.clear();
    int32_t inBullet = 0;
    // Loose nodes (one-node chips) stay in the FEM body, which steps them as particles once
    // nothing else of it is left: as rigid bodies they would fill Bullet with specks. A chip of
    // several nodes (a slice thinner than a cell, held by edges no tet holds) is a piece.
    const std::span<const uint8_t> chip = m_world.chipFlags(p.body);
    for (int32_t f = 0; f < count; ++f) {
      if (rigidBody(p.body, f))
        ++inBullet;
      else if (size_t(f) >= chip.size() || !chip[size_t(f)] || m_nodeCount[size_t(f)] > 1)
        m_candidates.push_back(f);
    }
    // Most nodes first, then by id: deterministic, and a capped body keeps its big pieces.
    std::stable_sort(m_candidates.begin(), m_candidates.end(), [&](int32_t a, int32_t b) {
      return m_nodeCount[size_t(a)] > m_nodeCount[size_t(b)];
    });
    for (int32_t f : m_candidates) {
      if (inBullet >= kMaxRigidFragments) break;
      if (p.policy == HandoffPolicy::BelowVolume) {
        const Result<RigidFragmentInfo> info = m_world.fragmentInfo(p.body, f);
        if (!info || info.value().volume >= p.maxVolume) continue;
      }
      // A gripped fragment refuses; it is tried again when the body splits next.
      if (handOff(p.body, f)) {
        ++handed;
        ++inBullet;
      }
    }
  }
  return handed;
}

Result<btRigidBody*> Bridge::handOff(BodyId body, int32_t fragment) {
  if (rigidBody(body, fragment))
    return fail("Bridge::handOff: fragment ", std::to_string(fragment), " is already in Bullet");
  const Result<RigidFragmentInfo> detached = m_world.detachFragment(body, fragment);
  if (!detached) return detached.error();
  const RigidFragmentInfo& f = detached.value();
  auto e = std::make_unique<Entry>();
  const glm::dmat3 R0 = glm::mat3_cast(f.rotation);
  e->restCentre = glm::transpose(R0) * (f.centreOfMass - f.translation);
  // Principal axes of the rest inertia, in double (Bullet wants a diagonal local inertia).
  const glm::dmat3 restInertia = glm::transpose(R0) * f.inertia * R0;
  Eigen::Matrix3d I;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) I(i, j) = restInertia[j][i];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(I);
  Eigen::Matrix3d E = eig.eigenvectors();
  if (E.determinant() < 0) E.col(2) *= -1;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) e->principal[j][i] = E(i, j);
  const glm::dvec3 moments(eig.eigenvalues()(0), eig.eigenvalues()(1), eig.eigenvalues()(2));

  // Nodes onto the rigid rest shape at the detach pose, then the hull in the principal frame.
  if (Result<void> r = m_world.setFragmentTransform(body, fragment, f.translation, f.rotation,
                                                    f.linearVelocity, f.angularVelocity);
      !r)
    return r.error();
  const glm::dmat3 B = R0 * e->principal;  // principal frame -> world
  const glm::dmat3 Bt = glm::transpose(B);
  e->shape = std::make_unique<btConvexHullShape>();
  const std::span<const int32_t> nodeFragment = m_world.nodeFragments(body);
  const std::span<const double> x = m_world.positions(body);
  glm::dvec3 lo(1e300), hi(-1e300);
  const auto add = [&](glm::dvec3 point) {
    const glm::dvec3 p = Bt * (point - f.centreOfMass);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
    e->shape->addPoint(toBt(p), false);
  };
  for (size_t n = 0; n < nodeFragment.size(); ++n)
    if (nodeFragment[n] == fragment) add(glm::dvec3(x[3 * n], x[3 * n + 1], x[3 * n + 2]));
  // A piece of a body in CutMode::Xfem (no node fragments: a node may lie in several pieces):
  // the hull of its closed surface, exact cut faces included, at the rigid pose.
  if (nodeFragment.empty()) {
    const SurfaceView s = m_world.surface(body);
    for (size_t i = 0; i < s.vertexFragment.size(); ++i)
      if (s.vertexFragment[i] == fragment)
        add(glm::dvec3(s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]));
  }
  e->shape->recalcLocalAabb();
  e->shape->optimizeConvexHull();
  const glm::dvec3 size = hi - lo;
  e->shape->setMargin(btScalar(
      std::clamp(kMarginFraction * std::max({size.x, size.y, size.z}), kMinMargin, kMaxMargin)));

  btRigidBody::btRigidBodyConstructionInfo ci(btScalar(f.mass), nullptr, e->shape.get(),
                                              toBt(moments));
  ci.m_startWorldTransform = btTransform(toBt(B), toBt(f.centreOfMass));
  e->body = std::make_unique<btRigidBody>(ci);
  e->body->setLinearVelocity(toBt(f.linearVelocity));
  e->body->setAngularVelocity(toBt(f.angularVelocity));
  m_dynamics.addRigidBody(e->body.get());
  btRigidBody* rb = e->body.get();
  m_fragments.push_back({body, fragment, rb});
  m_entries.push_back(std::move(e));
  return rb;
}

void Bridge::syncFromDynamics() {
  size_t keep = 0;
  for (size_t i = 0; i < m_entries.size(); ++i) {
    Entry& e = *m_entries[i];
    const RigidFragment& rf = m_fragments[i];
    if (!m_world.isValid(rf.body)) {
      m_dynamics.removeRigidBody(e.body.get());
      continue;
    }
    // x = Rb p + cb with p = E^T (X - C): rest-to-current rotation Rb E^T.
    const btTransform& T = e.body->getCenterOfMassTransform();
    const glm::dmat3 Q = toGlm(T.getBasis()) * glm::transpose(e.principal);
    const glm::dvec3 t = toGlm(T.getOrigin()) - Q * e.restCentre;
    // Cannot fail: the fragment is detached and Bullet's state is finite.
    (void)m_world.setFragmentTransform(rf.body, rf.fragment, t, glm::quat_cast(Q),
                                       toGlm(e.body->getLinearVelocity()),
                                       toGlm(e.body->getAngularVelocity()));
    if (keep != i) {
      m_entries[keep] = std::move(m_entries[i]);
      m_fragments[keep] = m_fragments[i];
    }
    ++keep;
  }
  m_entries.resize(keep);
  m_fragments.resize(keep);
}

btRigidBody* Bridge::rigidBody(BodyId body, int32_t fragment) const {
  for (const RigidFragment& f : m_fragments)
    if (f.body == body && f.fragment == fragment) return f.rigidBody;
  return nullptr;
}

}  // namespace gf::bullet
