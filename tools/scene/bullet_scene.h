// A loaded scene (scene.h) running with Bullet: the gf::World with the scene's bodies, a Bullet
// world (single precision, as integration/ builds it) with the scene's rigid bodies, and a
// gf::bullet::Bridge between them with each body's hand-off policy. Shared by graphfrac-demo and
// `graphfrac bench`; it owns everything and tears it down in the order Bullet needs.
//
// Sub-stepping: the scene's "substeps" are taken at the bridge, not inside World::step. One
// frame is `substeps` bridge steps of dt / substeps (each: mirror the rigid bodies as
// colliders, one World step, contact impulses back to Bullet, hand-off, one Bullet step of the
// same length). The coupling is staggered per bridge step, so a fast rigid body (a 20 m/s ball)
// only stays a kinematic obstacle for one small step instead of ploughing through the FEM body
// for a whole frame at its pre-impact velocity.
#pragma once

#include <graphfrac/jobs.h>
#include <graphfrac/world.h>

#include <glm/mat4x4.hpp>
#include <memory>
#include <span>
#include <vector>

#include "scene/scene.h"
#include "scene/strokes.h"

class btDiscreteDynamicsWorld;

namespace gf::bullet {
class Bridge;
}

namespace gf::scene {

/// What the last frame cost, wall clock [ms].
struct FrameTimings {
  StepTimings world;    ///< World::timings() summed over the frame's substeps (world.totalMs
                        ///< is the time spent inside World::step).
  double bulletMs = 0;  ///< The bridge's work outside World::step: colliders, impulses,
                        ///< hand-off, the Bullet steps, moving handed-off fragments.
  double totalMs = 0;   ///< The whole frame.
};

class BulletScene {
 public:
  /// Builds the world (a thread pool when the thread count is not 1; `threads` < 0 takes the
  /// scene's), its bodies, the Bullet world and rigid bodies and the bridge. Errors name the
  /// scene's source and the body.
  static Result<std::unique_ptr<BulletScene>> create(const Scene& scene, int threads = -1);
  ~BulletScene();
  BulletScene(const BulletScene&) = delete;
  BulletScene& operator=(const BulletScene&) = delete;

  World& world() { return *m_world; }
  const World& world() const { return *m_world; }
  /// The id of Scene::bodies[i].
  BodyId body(size_t i) const { return m_bodies[i]; }
  size_t bodyCount() const { return m_bodies.size(); }

  /// One scene frame: the cuts of the next frame, then the substeps (see above), each after
  /// the scene's strokes (StrokePlayer) are given for it. A cut or stroke the world rejects
  /// comes back as kStepInvalidInput with its message, and nothing more is stepped.
  StepStatus step();
  /// Frames stepped so far.
  int frame() const { return m_frame; }
  const FrameTimings& timings() const { return m_timings; }
  /// The World's events of every substep of the last frame, in step order (World's own spans
  /// only hold the last substep's).
  std::span<const FractureEvent> fractureEvents() const { return m_fractureEvents; }
  std::span<const FragmentEvent> fragmentEvents() const { return m_fragmentEvents; }
  std::span<const HandoffEvent> handoffEvents() const { return m_handoffEvents; }

  /// Body-to-world transform of Scene::rigidBodies[i] now (identity for a plane: its shape is
  /// already in world space).
  glm::mat4 rigidTransform(size_t i) const;
  size_t rigidBodyCount() const;
  /// The scene's sculpting strokes as played so far.
  const StrokePlayer& strokes() const { return m_strokes; }
  /// Fragments handed to Bullet so far.
  size_t handedOff() const;

  btDiscreteDynamicsWorld& dynamics();
  bullet::Bridge& bridge() { return *m_bridge; }

 private:
  BulletScene() = default;
  struct BulletObjects;

  double m_dt = 0;
  int m_substeps = 1;
  int m_frame = 0;
  size_t m_nextCut = 0;
  std::vector<SceneCut> m_cuts;
  StrokePlayer m_strokes;
  std::vector<BodyId> m_bodies;
  FrameTimings m_timings;
  std::vector<FractureEvent> m_fractureEvents;
  std::vector<FragmentEvent> m_fragmentEvents;
  std::vector<HandoffEvent> m_handoffEvents;
  // Destroyed bottom-up: the bridge before the world and Bullet, the world before its jobs.
  std::unique_ptr<JobSystem> m_jobs;
  std::unique_ptr<World> m_world;
  std::unique_ptr<BulletObjects> m_bullet;
  std::unique_ptr<bullet::Bridge> m_bridge;
};

}  // namespace gf::scene
