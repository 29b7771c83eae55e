// Plays a scene's sculpting strokes (Scene::strokes, thesis ch. 7) into a World: the one
// helper both runners (`graphfrac run` and BulletScene, so graphfrac-demo) use.
//
// The tool is one sphere collider appended after the scene's colliders when the world is made,
// so that it keeps its index whatever else (the Bullet bridge) replaces the colliders behind
// it. Between strokes, and during wet / dry strokes, it is parked far from everything
// (kParkedTool) rather than removed, for the same reason. A push moves the collider with the
// velocity of its path, so a step of h carries it exactly along the path, and asks World::deform
// at its centre, so the clay gives way around the tool (eq 7.7). A pull moves the collider the
// same way, and at its first step the nodes within radius + grab of the tool's centre stick to
// the tool: every step World::pull ties each to the tool's centre at the step's end plus the
// offset it had when grabbed, and World::deform keeps the clay around the tool local. The
// scene puts the tool against the surface, so the stuck nodes lie in the shell around the
// sphere, which moving away from the body never pushes them. A cut parks the sphere and moves a
// CutBrush (a square along the path) instead, sampled once per step against the body's render
// surface with a deform brush holding the body still around it (the thesis freezes the body
// while marking); every step its force is at least the threshold it cuts what it overlaps.
#pragma once

#include <graphfrac/world.h>

#include <glm/vec3.hpp>
#include <optional>
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
  /// collider gave the bodies, divided by h, minus the force of its pull (World::pullForce),
  /// plus the cut brush's force; zero without strokes.
  glm::dvec3 toolForce(const World& world, double h) const;
  /// The cut brush's four corners where the last apply() sampled it (empty unless a cut stroke
  /// was active then): what a renderer draws.
  std::span<const glm::dvec3> brushPose() const { return m_brushPose; }
  /// The tool's index in World::colliders(), -1 without strokes.
  int toolCollider() const { return m_tool; }

 private:
  // A cut stroke's step k of `steps`, its brush's leading edge at `centre` at the step's start.
  Result<void> cutStroke(World& world, BodyId body, int active, glm::dvec3 centre, int k,
                         int steps);

  std::vector<SceneStroke> m_strokes;  // a copy: the scene need not outlive the player
  double m_dt = 0;
  int m_tool = -1;
  // The pull stroke that has grabbed nodes (-1: none), its body, the nodes and their offsets
  // from the tool's centre when grabbed.
  int m_grabbedBy = -1;
  BodyId m_pulled;
  std::vector<int32_t> m_grabbed;
  std::vector<glm::dvec3> m_offsets, m_targets;
  // The cut stroke whose brush this is (-1: none), and the brush's force in the last step.
  int m_brushStroke = -1;
  std::optional<CutBrush> m_brush;
  glm::dvec3 m_brushForce{0};
  std::vector<glm::dvec3> m_brushPose;
};

/// "push", "pull", "cut", "wet" or "dry".
const char* strokeTypeName(SceneStroke::Type type);

}  // namespace gf::scene
