// Bullet bridge (issue 5 item 3): fragments that break off a graphfrac body become Bullet rigid
// bodies. After each World::step the bridge reads the fragment events, detaches the fragments
// each body's policy picks (World::detachFragment) and creates a btRigidBody for each: a convex
// hull of the fragment's nodes in its principal frame, the fragment's mass and principal
// inertia, and the linear and angular velocity that carry its momentum and angular momentum
// over. After each Bullet step it moves the fragments' nodes with their rigid bodies
// (World::setFragmentTransform), so their render surface keeps streaming.
//
// Not in this slice: contact between Bullet bodies and the deformable (FEM) bodies; a handed-
// off fragment collides only with Bullet objects, and a Bullet ball passes through FEM bodies.
// Concave fragments get the hull of their nodes (no convex decomposition yet).
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
  /// in its destructor.
  Bridge(World& world, btDiscreteDynamicsWorld& dynamics);
  ~Bridge();
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  /// The hand-off policy of a body (maxVolume [m^3] only for BelowVolume, > 0). Error for a
  /// stale id, a body without fracture or a bad volume.
  Result<void> setPolicy(BodyId body, HandoffPolicy policy, double maxVolume = 0);

  /// One frame: World::step(dt), handOffNewFragments(), a Bullet step of exactly dt
  /// (stepSimulation(dt, 0): no interpolation, the game's loop fixes dt), syncFromDynamics().
  StepStatus step(double dt);
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
  struct Policy {
    BodyId body;
    HandoffPolicy policy = HandoffPolicy::Never;
    double maxVolume = 0;
    int32_t seenFragments = 1;  // fragment count at the last scan
  };
  World& m_world;
  btDiscreteDynamicsWorld& m_dynamics;
  std::vector<Policy> m_policies;  // sorted by body index: deterministic hand-off order
  std::vector<std::unique_ptr<Entry>> m_entries;
  std::vector<RigidFragment> m_fragments;  // parallel to m_entries
};

}  // namespace gf::bullet
