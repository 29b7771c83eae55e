// What happened during a step, reported as arrays sorted for determinism (Box2D style). The
// spans World returns stay valid until the next step or body creation/destruction.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>

#include "ids.h"

namespace gf {

/// An edge of a body's mesh broke (by the stress criterion, a brittle crack plane, a cut, or
/// severed by other breaks),
/// or, for a body in CutMode::Xfem, a cut crossed a tet (one event per tet that carries the new
/// cut's enrichment: edge, nodeA and nodeB are -1, `tet` names it, position is the centroid of
/// the cut polygon in it).
struct FractureEvent {
  BodyId body;
  int32_t edge = -1;               ///< Edge index in the body's edge graph (-1: Is-XFEM).
  int32_t nodeA = -1, nodeB = -1;  ///< Its end nodes.
  glm::vec3 position{0, 0, 0};     ///< World-space midpoint of the edge when it broke.
  float stress = 0;                ///< Tensile normal stress that broke it [Pa]; 0: cut, severed.
  /// Where the render surface splits the edge, from nodeA (0) to nodeB (1): 0.5, or with
  /// FractureSettings::splitPoint = ForceRatio the point set when it broke (fig 4.10).
  float split = 0.5f;
  /// Severed: the edge carried nothing any more, every tet around it split by other breaks of
  /// the same step (degradation model; stress 0, split 0.5; docs/design.md "Severed edges").
  enum class Cause : uint8_t { Stress, BrittlePlane, Cut, Severed } cause = Cause::Stress;
  int32_t tet = -1;  ///< CutMode::Xfem: the tet the cut crosses; -1 for graph events.
};

/// A body's node graph split: a new fragment appeared (the old one keeps its id).
struct FragmentEvent {
  BodyId body;
  int32_t fragment = -1;  ///< New fragment id (0 is the piece holding node 0 at creation).
  int32_t parent = -1;    ///< Fragment it split from.
  int32_t nodeCount = 0;
  double volume = 0;  ///< [m^3]
  double mass = 0;    ///< [kg]
  glm::vec3 centreOfMass{0, 0, 0};
  glm::vec3 velocity{0, 0, 0};  ///< Momentum / mass [m/s].
};

/// A fragment left the FEM solve to be moved by rigid-body physics (World::detachFragment).
struct HandoffEvent {
  BodyId body;
  int32_t fragment = -1;
  int32_t nodeCount = 0;
  double mass = 0;  ///< [kg]
  glm::vec3 centreOfMass{0, 0, 0};
  glm::vec3 velocity{0, 0, 0};         ///< Linear velocity of the centre of mass [m/s].
  glm::vec3 angularVelocity{0, 0, 0};  ///< [rad/s], world axes.
};

}  // namespace gf
