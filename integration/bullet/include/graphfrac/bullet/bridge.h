// Bullet bridge: fragments that break off a graphfrac body become Bullet rigid
// bodies. After each World::step the bridge reads the fragment events, detaches the fragments
// each body's policy picks (World::detachFragment) and creates a btRigidBody for each: a convex
// hull of the fragment's nodes in its principal frame, the fragment's mass and principal
// inertia, and the linear and angular velocity that carry its momentum and angular momentum
// over. After each Bullet step it moves the fragments' nodes with their rigid bodies
// (World::setFragmentTransform), so their render surface keeps streaming.
//
// Two-way contact: Bullet bodies registered with addCollider (spheres, boxes, static planes)
// are mirrored as World colliders before every FEM step, at their pose and with their linear
// and angular velocity, and after the step each dynamic one takes the opposite of the impulse and
// of its moment that its collider gave the FEM nodes (World::colliderImpulses): equal and opposite.
// The coupling is staggered: during the FEM step the rigid body moves at its old velocity (a
// kinematic obstacle), the reaction enters Bullet's step that follows. Momentum is exchanged
// exactly, but a rigid body much lighter than the FEM nodes it touches in one step gets a
// velocity change far above its own and may bounce too hard (a body resting on a few nodes
// is stable when its mass exceeds roughly 100 dt^2 k times theirs, k the collider stiffness per
// unit node mass; the default makes that 100 times). Contact acts on FEM nodes only: a body
// that moves more than about half the FEM body's thickness or node spacing per step can pass
// between nodes (no continuous detection). A static or kinematic body's friction is the
// collider's (Collider::friction, met with BodyDef::friction), a kinematic one's surface moving
// with its velocity and spin (Collider::angularVelocity); a dynamic body is frictionless unless
// setDynamicFriction (experimental: the friction's reaction goes back to it with the normal
// one, exchanged explicitly, which leaves a body resting on a held FEM body chattering). A
// handed-off fragment collides only with Bullet objects. Concave fragments get the hull of their
// nodes (no convex decomposition yet). A piece of a body in CutMode::Xfem gets the hull of its
// closed surface (its exact cut faces included); the last piece left in that body's Is-XFEM system
// stays there (World::detachFragment refuses it).
//
// Bullet is used in single precision (integration/CMakeLists.txt says why).
#pragma once

#include <graphfrac/world.h>

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

class btDiscreteDynamicsWorld;
class btRigidBody;

namespace gf::bullet {

/// Which fragments of a body the bridge hands to Bullet once the body has split. Under any
/// policy loose nodes (one-node chips, FractureStats::chips) stay in the FEM world, and a body has
/// at most kMaxRigidFragments pieces in Bullet, the ones with most nodes first; the rest stay in
/// the FEM world, where they move as free nodes and meet the colliders. A body pulverised node by
/// node would otherwise put thousands of overlapping bodies into Bullet (a glass bunny hit at 20
/// m/s: 5016 of them, 5 million pairs, memory exhausted).
constexpr int32_t kMaxRigidFragments = 256;
/// Which fragments of a body the bridge hands to Bullet once the body has split.
enum class HandoffPolicy : uint8_t {
  Never,          ///< The default: the body stays deformable whatever breaks.
  EveryFragment,  ///< Every fragment (the parent piece too) that holds no gripped node.
  BelowVolume,    ///< Fragments whose rest volume is below maxVolume; the big piece stays FEM.
};

/// A fragment living in Bullet.
struct RigidFragment {
  BodyId body;
  int32_t fragment = -1;
  btRigidBody* rigidBody = nullptr;  ///< Owned by the bridge; in the dynamics world.
};

class Bridge {
 public:
  /// Both outlive the bridge. The bridge adds rigid bodies to `dynamics` and removes them again
  /// in its destructor. It sets `dynamics`' solver to resolve every penetration by the split
  /// impulse (m_splitImpulse on, m_splitImpulsePenetrationThreshold = BT_LARGE_FLOAT): a piece
  /// handed off inside the floor, a ball or its neighbours' hull margins is moved out without
  /// being given velocity, so the hand-off adds no kinetic energy at any step size. A game that
  /// sets those two fields back brings Bullet's Baumgarte push (erp depth / h) back.
  Bridge(World& world, btDiscreteDynamicsWorld& dynamics);
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  /// The hand-off policy of a body (maxVolume [m^3] only for BelowVolume, > 0). Error for a
  /// stale id, a body without fracture or a bad volume.
  Result<void> setPolicy(BodyId body, HandoffPolicy policy, double maxVolume = 0);

  /// One frame: mirrorColliders(), World::step(dt), applyContactImpulses(),
  /// handOffNewFragments(), a Bullet step of exactly dt (stepSimulation(dt, 0): no
  /// interpolation, the game's loop fixes dt), syncFromDynamics().
  StepStatus step(double dt);

  /// Registers a Bullet body that touches the deformable bodies: a btSphereShape, a btBoxShape
  /// (any orientation) or, for a static body only, a btStaticPlaneShape. Returns its index in
  /// World::colliders() (after the colliders the world had when the bridge was made, which keep
  /// theirs). The body outlives its registration; error for null, another shape, a dynamic
  /// plane or a body registered twice. Do not call World::setColliders while any is registered.
  Result<int32_t> addCollider(btRigidBody* body);
  /// Unregisters a body (before the game deletes it); the ones registered after it move down
  /// one index. Error for a body not registered.
  Result<void> removeCollider(btRigidBody* body);
  /// Experimental, off by default: dynamic registered bodies are mirrored with their friction
  /// too (met as a static body's), the friction's reaction (in colliderImpulses and their
  /// moments) goes back to them, and their getRollingFriction() / getSpinningFriction() resist
  /// their spin as in Bullet's solver (resistRolling). Momentum is exchanged exactly, but
  /// explicitly: a body resting on a FEM body that is held (by a floor, by its stiffness) takes
  /// a reaction that overshoots its sliding each step, and a ball in a soft block's dimple
  /// chatters at +-0.02 m/s instead of coming to rest (docs/validation.md, Spinning colliders).
  void setDynamicFriction(bool on) { m_dynamicFriction = on; }
  /// Before World::step: the registered bodies as colliders at their current pose and velocity.
  void mirrorColliders();
  /// After World::step: each dynamic registered body takes minus its collider's impulse and
  /// moment (static and kinematic bodies take nothing).
  void applyContactImpulses();
  /// After World::step: detaches what the policies pick among the fragments of bodies whose
  /// fragment count changed, and creates their rigid bodies. Returns how many.
  int handOffNewFragments();
  /// After a Bullet step: moves every handed-off fragment's nodes with its rigid body. Rigid
  /// bodies of destroyed graphfrac bodies are removed.
  void syncFromDynamics();

  /// Hands one fragment to Bullet now, whatever the policy. Errors of World::detachFragment.
  Result<btRigidBody*> handOff(BodyId body, int32_t fragment);
  /// Fragments handed off so far, in hand-off order.
  std::span<const RigidFragment> fragments() const { return m_fragments; }
  /// The rigid body of a handed-off fragment, or null.
  btRigidBody* rigidBody(BodyId body, int32_t fragment) const;

 private:
  struct Entry;
  // Rolling and spinning resistance of a dynamic body from the contact reaction it was given.
  static void resistRolling(btRigidBody& body, glm::dvec3 reaction);
  struct Policy {
    BodyId body;
    HandoffPolicy policy = HandoffPolicy::Never;
    double maxVolume = 0;
    int32_t seenFragments = 1;  // fragment count at the last scan
  };
  World& m_world;
  btDiscreteDynamicsWorld& m_dynamics;
  size_t m_worldColliders = 0;            // the world's own colliders, first in its list
  std::vector<btRigidBody*> m_colliders;  // registered with addCollider, in that order
  std::vector<Policy> m_policies;         // sorted by body index: deterministic hand-off order
  std::vector<std::unique_ptr<Entry>> m_entries;
  std::vector<RigidFragment> m_fragments;  // parallel to m_entries
  std::vector<int32_t> m_nodeCount;        // scratch: nodes per fragment of the body scanned
  std::vector<int32_t> m_candidates;       // scratch: its fragments not yet in Bullet
  bool m_dynamicFriction = false;
};

}  // namespace gf::bullet
