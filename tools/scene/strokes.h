// Plays a scene's sculpting strokes (Scene::strokes, thesis ch. 7) into a World: the one
// helper both runners (`graphfrac run` and BulletScene, so graphfrac-demo) use.
//
// The tool is one sphere collider appended after the scene's colliders when the world is made,
// so that it keeps its index whatever else (the Bullet bridge) replaces the colliders behind
// it. Between strokes, and during wet / dry strokes, it is parked far from everything
// (kParkedTool) rather than removed, for the same reason. A push moves the collider with the
// velocity of its path, so a step of h carries it exactly along the path, and asks World::deform
// at its centre, so the clay gives way around the tool (eq 7.7).
#pragma once

#include <graphfrac/world.h>

#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "scene/scene.h"

namespace gf::scene {

class StrokePlayer {
 public:
  /// Where the idle tool waits [m]: far beyond any scene, inside Collider::check's bounds.
  static constexpr float kParkedTool = 1e6f;

  /// Appends the tool's collider to `def.colliders` when `scene` has strokes (call before the
  /// World is made from `def`); nothing otherwise.
  StrokePlayer(const Scene& scene, WorldDef& def);
  StrokePlayer() = default;

  /// Before the world steps substep `substep` (0-based) of `substeps` of frame `frame`
  /// (1-based): places the tool and gives the brushes of the stroke active in that frame. The
  /// error names the stroke ("strokes[2] (push of body \"clay\"): ..."); the runners stop
  /// then (the scene's checks make it unreachable for a loaded scene: a bad body id only).
  Result<void> apply(World& world, std::span<const BodyId> bodies, int frame, int substep = 0,
                     int substeps = 1);

  /// The stroke of Scene::strokes active in `frame` (-1 when none).
  int activeStroke(int frame) const;
  /// The force on the tool [N] over the last step of length `h`: minus the impulse its
  /// collider gave the bodies, divided by h (zero without strokes).
  glm::dvec3 toolForce(const World& world, double h) const;
  /// The tool's index in World::colliders(), -1 without strokes.
  int toolCollider() const { return m_tool; }

 private:
  std::vector<SceneStroke> m_strokes;  // a copy: the scene need not outlive the player
  double m_dt = 0;
  int m_tool = -1;
};

/// "push", "wet" or "dry".
const char* strokeTypeName(SceneStroke::Type type);

}  // namespace gf::scene
